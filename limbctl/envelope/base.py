"""The Envelope interface every constraint model (RigidMap, SOM, Cone) speaks, and its ``.npz``
file: a JSON header (kind, version, parameters, a SHA-256 over all) and the model's arrays."""

from __future__ import annotations

import hashlib
import json
from abc import ABC, abstractmethod
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from limbctl.errors import ConfigError, FileFormatError
from limbctl.geometry.quat import as_quaternions

#: Bumped whenever the saved layout changes; older files are refused with a clear message.
FORMAT_VERSION = 1
_MAGIC = "limbctl-envelope"
#: How every .npz file (a zip archive) begins: a local file header's signature.
_ZIP_MAGIC = b"PK\x03\x04"


class Envelope(ABC):
    """A region of valid orientations on S^3 behind one interface. Subclasses set ``kind`` and
    implement ``fit``, ``respond``, ``_inside`` and ``_to_boundary`` (or ``contains`` and
    ``correct``), ``_params``, ``_arrays`` and ``_restore``. Every method takes one quaternion (4,)
    or a batch (N, 4) and returns the same leading shape."""

    kind: ClassVar[str] = ""
    #: Constructor keywords a user may set by name (``limbctl train --nodes``, ...).
    settable: ClassVar[tuple[str, ...]] = ()
    _registry: ClassVar[dict[str, type[Envelope]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        hooks = all(hasattr(cls, name) for name in ("_inside", "_to_boundary"))
        own = cls.contains is not Envelope.contains and cls.correct is not Envelope.correct
        if cls.kind and not (hooks or own):
            raise TypeError(
                f"{cls.__name__}: define _inside and _to_boundary, or contains and correct"
            )
        if cls.kind:
            Envelope._registry[cls.kind] = cls

    @abstractmethod
    def fit(self, q_train: np.ndarray) -> Envelope:
        """Learn the region from valid orientations ``q_train`` (N, 4). Returns self."""

    @abstractmethod
    def respond(self, q: np.ndarray, interpolation: str = "none", k: int = 8) -> np.ndarray:
        """The network's answer as in the papers, shape like ``q``."""

    def contains(self, q: np.ndarray) -> np.ndarray | bool:
        """Whether each orientation is inside the learned region: (N,) bool, or bool for (4,)."""
        arr, single = as_quaternions(q)
        inside = self._inside(arr)
        return bool(inside[0]) if single else inside

    def correct(self, q: np.ndarray) -> np.ndarray:
        """``q`` itself (canonical) inside the region, the boundary orientation outside."""
        arr, single = as_quaternions(q)
        out = arr.copy()
        outside = ~self._inside(arr)
        if outside.any():
            out[outside] = self._to_boundary(arr[outside])
        return out[0] if single else out

    @property
    @abstractmethod
    def weights(self) -> np.ndarray:
        """Trained node weights (nodes, 4); empty (0, 4) for analytic models."""

    @abstractmethod
    def _params(self) -> dict[str, Any]:
        """JSON-serialisable constructor parameters and scalar state."""

    @abstractmethod
    def _arrays(self) -> dict[str, np.ndarray]:
        """Named arrays that, with ``_params``, rebuild the trained model."""

    @classmethod
    @abstractmethod
    def _restore(cls, params: dict[str, Any], arrays: dict[str, np.ndarray]) -> Envelope:
        """Rebuild a trained model from what ``_params`` and ``_arrays`` returned."""

    def save(self, path: str | Path, metadata: dict[str, Any] | None = None) -> Path:
        """Write the model and JSON ``metadata`` to ``path`` (one .npz file) atomically."""
        path = Path(path)
        arrays = {name: np.ascontiguousarray(a) for name, a in self._arrays().items()}
        header = {
            "magic": _MAGIC,
            "format_version": FORMAT_VERSION,
            "kind": self.kind,
            "params": self._params(),
            "metadata": metadata or {},
        }
        header["sha256"] = _digest(header, arrays)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as fh:
            np.savez(
                fh, __header__=np.frombuffer(json.dumps(header).encode(), dtype=np.uint8), **arrays
            )
        tmp.replace(path)
        return path

    @classmethod
    def load(cls, path: str | Path) -> Envelope:
        """Read a model saved by :meth:`save`, checking magic, version, kind and checksum
        (FileFormatError naming the file and the problem: missing, corrupt, version or kind)."""
        header, arrays = _read(Path(path))
        kind = header.get("kind")
        target = Envelope._registry.get(kind)
        if target is None:
            raise FileFormatError(path, f"unknown model kind {kind!r}")
        if cls is not Envelope and not issubclass(target, cls):
            raise FileFormatError(path, f"holds a {kind} model, not a {cls.kind or cls.__name__}")
        try:
            return target._restore(header["params"], arrays)
        except (KeyError, ValueError, TypeError) as exc:
            raise FileFormatError(path, f"model parameters do not fit a {kind}: {exc}") from exc


def model_kinds() -> tuple[str, ...]:
    """The name of every model kind, in the order their classes were defined."""
    return tuple(Envelope._registry)


def model_class(kind: str) -> type[Envelope]:
    """The class of a model kind (ConfigError for an unknown kind, listing the choices)."""
    target = Envelope._registry.get(kind)
    if target is None:
        raise ConfigError(f"unknown model kind {kind!r}; choose one of {', '.join(model_kinds())}")
    return target


def build_model(kind: str, **options: Any) -> Envelope:
    """An unfitted model of ``kind`` built with constructor keywords ``options`` (ConfigError for
    an unknown kind, listing the choices, or options its constructor does not take)."""
    target = model_class(kind)
    try:
        return target(**options)
    except TypeError as exc:
        raise ConfigError(f"bad options for {kind}: {exc}") from exc


def load_model(path: str | Path) -> Envelope:
    """Load any envelope model file, whatever its kind."""
    return Envelope.load(path)


def load_header(path: str | Path) -> dict[str, Any]:
    """Read and verify a model file, returning its header (kind, params, metadata)."""
    header, _ = _read(Path(path))
    return header


def is_model_file(path: str | Path) -> bool:
    """Whether the file at ``path`` begins as a model file (a zip archive) does."""
    try:
        with open(path, "rb") as handle:
            return handle.read(len(_ZIP_MAGIC)) == _ZIP_MAGIC
    except OSError:
        return False


def _digest(header: dict[str, Any], arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the header (less its checksum) and each array's name, dtype, shape, bytes."""
    h = hashlib.sha256()
    body = {k: v for k, v in header.items() if k != "sha256"}
    h.update(json.dumps(body, sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _read(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    if not path.exists():
        raise FileFormatError(path, "no such model file (train one with `limbctl train`)")
    if not is_model_file(path):
        # np.load would take any other bytes for a pickle and advise allow_pickle=True
        raise FileFormatError(
            path,
            "not a readable model file (truncated or corrupt: it does not begin as an .npz "
            "archive does)",
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            raw = {name: data[name] for name in data.files}
    except Exception as exc:  # damaged zip bytes raise many types: all mean unreadable
        raise FileFormatError(
            path, f"not a readable model file (truncated or corrupt): {exc}"
        ) from exc
    if "__header__" not in raw:
        raise FileFormatError(path, "not a limbctl model file (no header)")
    try:
        header = json.loads(raw.pop("__header__").tobytes().decode())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise FileFormatError(path, f"model header is corrupt: {exc}") from exc
    if not isinstance(header, dict) or header.get("magic") != _MAGIC:
        raise FileFormatError(path, "not a limbctl model file (bad magic)")
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        raise FileFormatError(
            path,
            f"model format version {version} is not supported (this limbctl reads "
            f"{FORMAT_VERSION}); retrain with `limbctl train`",
        )
    if header.get("sha256") != _digest(header, raw):
        raise FileFormatError(path, "checksum mismatch: the file was modified or corrupted")
    return header, raw
