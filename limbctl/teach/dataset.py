"""Recorded-orientation files: append-only, crash-safe, every line checksummed.

UTF-8 text, a JSON header line then one line per record (the :data:`COLUMNS` written with
``repr``), each ``payload|crc`` with a *chained* CRC-32: an edited, deleted or reordered line
breaks the chain there. The loader drops a torn last line and refuses anything else wrong.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import threading
import zlib
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from calib.profile import Calibration, ProfileError, calibration_from_dict
from limbctl.errors import ConfigError, FileFormatError, InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_to_quat
from limbctl.geometry.quat import UNIT_TOLERANCE, as_quaternions

FORMAT_NAME = "limbctl-orientations"
FORMAT_VERSION = 1
COLUMNS = ("t_s", "pan_deg", "tilt_deg", "w", "x", "y", "z")
#: Longest time a written record may wait for fsync.
SYNC_INTERVAL_S = 0.25
#: Free space required before a recording starts (an hour at 100 Hz is about 30 MB).
MIN_FREE_BYTES = 64 * 1024 * 1024
_SEPARATOR = "|"
#: How every dataset file begins (the header's first key, written first).
MAGIC = ('{"format": "' + FORMAT_NAME + '"').encode()


@dataclass(frozen=True)
class DatasetHeader:
    """The first line of a dataset file (``calibration`` None in files from before it)."""

    rig: str
    created: str
    columns: tuple[str, ...] = COLUMNS
    version: int = FORMAT_VERSION
    meta: dict[str, Any] = field(default_factory=dict)
    calibration: Calibration | None = None


@dataclass(frozen=True)
class Dataset:
    """A loaded recording from ``path``, with its ``header`` (the first line): sample times ``t``
    (N,) in seconds from the start of the recording, joint angles ``pan_deg``, ``tilt_deg`` (N,)
    in degrees, unit ``quaternions`` (N, 4) (w, x, y, z), w >= 0, and ``dropped_tail``, why a torn
    last line was dropped, or None."""

    header: DatasetHeader
    t: np.ndarray
    pan_deg: np.ndarray
    tilt_deg: np.ndarray
    quaternions: np.ndarray
    dropped_tail: str | None
    path: str

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def pan(self) -> np.ndarray:
        """Pan angles in radians, shape (N,)."""
        return np.radians(self.pan_deg)

    @property
    def tilt(self) -> np.ndarray:
        """Tilt angles in radians, shape (N,)."""
        return np.radians(self.tilt_deg)


def _seal(payload: str, previous_crc: int) -> tuple[bytes, int]:
    """The line ``payload|crc\\n`` and its chained CRC."""
    if "\n" in payload or _SEPARATOR in payload:
        raise ValueError(f"payload may not contain newline or {_SEPARATOR!r}: {payload!r}")
    # crc_i = crc32(payload_i, crc_{i-1})
    crc = zlib.crc32(payload.encode("utf-8"), previous_crc)
    return f"{payload}{_SEPARATOR}{crc:08x}\n".encode(), crc


def check_writable(path: str | os.PathLike[str], min_free_bytes: int = MIN_FREE_BYTES) -> Path:
    """Refuse, before recording starts, an output path that cannot be written or lacks room
    (ConfigError if the file exists, its directory is missing or not writable, or lacks the free
    space)."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.exists():
        raise ConfigError(
            f"{path}: already exists; recordings are never overwritten, choose another --out"
        )
    if not directory.is_dir():
        raise ConfigError(
            f"{path}: directory {directory} does not exist (or is not a directory); create it first"
        )
    if not os.access(directory, os.W_OK | os.X_OK):
        raise ConfigError(f"{path}: directory {directory} is not writable; check permissions")
    free = shutil.disk_usage(directory).free
    if free < min_free_bytes:
        raise ConfigError(
            f"{path}: only {free / 1e6:.1f} MB free on that disk, need at least "
            f"{min_free_bytes / 1e6:.1f} MB; free some space or record elsewhere"
        )
    return path


class DatasetWriter:
    """Append orientation samples to a new dataset file at ``path``; a context manager. The header
    names the ``rig``, JSON ``meta`` and ``calibration``; a record waits ``sync_interval_s`` (s)
    at most for fsync."""

    def __init__(
        self,
        path: str | os.PathLike[str],
        rig: str,
        meta: dict[str, Any] | None = None,
        sync_interval_s: float = SYNC_INTERVAL_S,
        min_free_bytes: int = MIN_FREE_BYTES,
        calibration: Calibration | None = None,
    ) -> None:
        self.path = check_writable(path, min_free_bytes)
        self.header = DatasetHeader(
            rig=rig,
            created=datetime.now(timezone.utc).isoformat(timespec="seconds"),
            meta=dict(meta or {}),
            calibration=calibration,
        )
        self.sync_interval_s = float(sync_interval_s)
        self.count = 0
        self._fd: int | None = None
        self._crc = 0
        self._dirty = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._syncer: threading.Thread | None = None
        self._sync_error: OSError | None = None

    def open(self) -> DatasetWriter:
        """Create the file, write and fsync the header, start the background syncer."""
        if self._fd is not None:
            return self
        header = {
            "format": FORMAT_NAME,
            "version": self.header.version,
            "rig": self.header.rig,
            "created": self.header.created,
            "columns": list(self.header.columns),
            "meta": self.header.meta,
        }
        if self.header.calibration is not None:
            header["calibration"] = self.header.calibration.to_dict()
        line, self._crc = _seal(json.dumps(header, separators=(", ", ": ")), 0)
        try:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_APPEND, 0o644)
        except FileExistsError:
            raise ConfigError(f"{self.path}: already exists; choose another --out") from None
        self._write(line)
        os.fsync(self._fd)
        self._syncer = threading.Thread(target=self._sync_loop, name="dataset-fsync", daemon=True)
        self._syncer.start()
        return self

    def close(self) -> None:
        """Stop the syncer, fsync and close. Safe to call twice."""
        if self._fd is None:
            return
        self._stop.set()
        if self._syncer is not None:
            self._syncer.join()
        with self._lock:
            fd, self._fd = self._fd, None
            try:
                os.fsync(fd)
            finally:
                os.close(fd)

    def __enter__(self) -> DatasetWriter:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def append(self, t_s: float, pan: float, tilt: float, q: np.ndarray | None = None) -> None:
        """Append one sample: ``t_s`` seconds since the start, joint angles ``pan``, ``tilt`` (rad,
        stored in degrees) and the pose's quaternion ``q`` (4,) (default: from pan and tilt).
        InvalidInputError for non-finite values or a non-unit ``q``."""
        if self._fd is None:
            raise RuntimeError("DatasetWriter is not open; use it as a context manager")
        if self._sync_error is not None:
            raise self._write_failed(self._sync_error) from self._sync_error
        values = [float(t_s), math.degrees(float(pan)), math.degrees(float(tilt))]
        if not all(math.isfinite(v) for v in values):
            raise InvalidInputError(f"sample {self.count}: non-finite t/pan/tilt {values}")
        quat = pan_tilt_to_quat(float(pan), float(tilt)) if q is None else q
        quat, _ = as_quaternions(quat, name=f"sample {self.count} quaternion")
        payload = ",".join(repr(v) for v in values + [float(c) for c in quat[0]])
        with self._lock:
            line, self._crc = _seal(payload, self._crc)
            try:
                self._write(line)
            except OSError as exc:  # disk full, file too large, device gone
                raise self._write_failed(exc) from exc
            self._dirty = True
            self.count += 1

    def _write_failed(self, exc: OSError) -> FileFormatError:
        return FileFormatError(
            self.path,
            f"cannot write sample {self.count} ({exc.strerror or exc}); the disk may be full. "
            f"The {self.count} samples before it are kept and load as they are",
        )

    def _write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            written = os.write(self._fd, view)  # type: ignore[arg-type]
            view = view[written:]

    def _sync_loop(self) -> None:
        while not self._stop.wait(self.sync_interval_s):
            with self._lock:
                if not self._dirty or self._fd is None:
                    continue
                self._dirty = False
                fd = self._fd
                try:
                    os.fsync(fd)
                except OSError as exc:  # surfaced on the next append
                    self._sync_error = exc
                    return


def _split(path: Path, number: int, raw: bytes, previous_crc: int) -> tuple[str, int]:
    """Payload of line ``number`` after checking its chained CRC."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise FileFormatError(path, f"line {number}: not UTF-8 text (binary corruption)") from None
    payload, sep, crc_text = text.rpartition(_SEPARATOR)
    if not sep or len(crc_text) != 8:
        raise FileFormatError(path, f"line {number}: no checksum field (corrupt or hand-edited)")
    expected = zlib.crc32(payload.encode("utf-8"), previous_crc)
    if crc_text != f"{expected:08x}":
        raise FileFormatError(
            path,
            f"line {number}: checksum mismatch (the line was edited, corrupted, or a line "
            f"before it was removed); the recording cannot be trusted past this point",
        )
    return payload, expected


def _parse_header(path: Path, raw: bytes) -> tuple[DatasetHeader, int]:
    try:
        text = raw.decode("utf-8")
        payload, _, _ = text.rpartition(_SEPARATOR)
        data = json.loads(payload)
        kind = data.get("format") if isinstance(data, dict) else None
    except (UnicodeDecodeError, json.JSONDecodeError, AttributeError):
        kind = None
    if kind != FORMAT_NAME:
        raise FileFormatError(path, f"line 1: not a limbctl orientation dataset ({FORMAT_NAME})")
    payload, crc = _split(path, 1, raw, 0)
    version = data.get("version")
    if version != FORMAT_VERSION:
        raise FileFormatError(
            path,
            f"line 1: dataset format version {version!r}, this limbctl reads version "
            f"{FORMAT_VERSION}; use a matching limbctl",
        )
    columns = tuple(data.get("columns", ()))
    if columns != COLUMNS:
        raise FileFormatError(path, f"line 1: columns {list(columns)}, expected {list(COLUMNS)}")
    calibration = None
    if data.get("calibration") is not None:
        try:
            calibration = calibration_from_dict(data["calibration"], "header")
        except ProfileError as exc:
            raise FileFormatError(path, f"line 1: {str(exc).removeprefix('header: ')}") from None
    meta = dict(data.get("meta") or {})
    rig, created = str(data.get("rig")), str(data.get("created"))
    return DatasetHeader(rig, created, columns, version, meta, calibration), crc


def is_dataset_file(path: str | os.PathLike[str]) -> bool:
    """Whether the file at ``path`` begins as a dataset does (False if missing or unreadable)."""
    try:
        with open(path, "rb") as handle:
            return handle.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def load_dataset(path: str | os.PathLike[str]) -> Dataset:
    """Read a dataset, verifying every line (a torn last line is dropped); FileFormatError,
    naming file and line, for a foreign file, a wrong version, or a bad line before the last."""
    path = Path(path)
    try:
        blob = path.read_bytes()
    except OSError as exc:
        raise FileFormatError(path, f"cannot read ({exc})") from exc
    lines = blob.split(b"\n")
    tail = lines.pop()
    dropped_tail = None
    if tail:
        dropped_tail = (
            f"line {len(lines) + 1} was torn ({len(tail)} bytes, no newline: the writer stopped "
            f"mid-line) and was dropped"
        )
    if not lines:
        raise FileFormatError(path, "line 1: no complete header (empty or torn file)")
    header, crc = _parse_header(path, lines[0])
    rows = np.empty((len(lines) - 1, len(COLUMNS)), dtype=np.float64)
    for index, raw in enumerate(lines[1:]):
        number = index + 2
        payload, crc = _split(path, number, raw, crc)
        fields = payload.split(",")
        if len(fields) != len(COLUMNS):
            raise FileFormatError(path, f"line {number}: {len(fields)} fields, expected 7")
        try:
            rows[index] = [float(f) for f in fields]
        except ValueError:
            raise FileFormatError(path, f"line {number}: a field is not a number") from None
        if not np.isfinite(rows[index]).all():
            raise FileFormatError(path, f"line {number}: non-finite value")
    q = rows[:, 3:7]
    norms = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(~(np.abs(norms - 1.0) <= UNIT_TOLERANCE))
    if bad.size:
        raise FileFormatError(path, f"line {bad[0] + 2}: quaternion is not unit length")
    return Dataset(
        header=header,
        t=rows[:, 0].copy(),
        pan_deg=rows[:, 1].copy(),
        tilt_deg=rows[:, 2].copy(),
        quaternions=np.ascontiguousarray(q),
        dropped_tail=dropped_tail,
        path=str(path),
    )
