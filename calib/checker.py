"""Validation of rig profile data: one-line errors naming file and field, and the checks."""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

from calib.yaml_guard import shown


class ProfileError(ValueError):
    """A rig profile is missing or invalid; the message names the file and the field."""


class ProfileFileError(ProfileError):
    """A rig profile file (``path``, a :class:`~pathlib.Path`) cannot be read or is not YAML."""

    def __init__(self, path: str | os.PathLike[str], problem: str) -> None:
        self.path = Path(path)
        super().__init__(f"{self.path}: {problem}")


#: Longest port or model string (a device path is well under this).
MAX_TEXT_CHARS = 256
#: Unknown keys named in one message; the rest are counted (a message stays one short line).
MAX_LISTED_KEYS = 5


def _key_name(key: Any) -> str:
    """A key bare if a short printable string, else bounded."""
    if isinstance(key, str) and key.isprintable() and len(key) <= 40:
        return key
    return shown(key)


class Checker:
    """Collects the file name so every error names file and field."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, field: str, problem: str) -> ProfileError:
        return ProfileError(f"{self.source}: {field} {problem}")

    def mapping(
        self, value: Any, field: str, keys: tuple[str, ...], optional: tuple[str, ...] = ()
    ) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(
                field, f"must be a mapping with keys {', '.join(keys)}, got {shown(value)}"
            )
        missing = [k for k in keys if k not in value]
        if missing:
            raise self.fail(field, f"is missing {', '.join(missing)} (expected {', '.join(keys)})")
        allowed = keys + optional
        unknown = sorted(_key_name(k) for k in value if k not in allowed)
        if unknown:
            listed = ", ".join(unknown[:MAX_LISTED_KEYS])
            if len(unknown) > MAX_LISTED_KEYS:
                listed += f" and {len(unknown) - MAX_LISTED_KEYS} more"
            raise self.fail(
                field,
                f"has unknown keys {listed} (allowed: {', '.join(allowed)}); check the spelling",
            )
        return value

    def integer(self, value: Any, field: str, lo: int, hi: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(field, f"must be an integer in {lo}..{hi}, got {shown(value)}")
        if not lo <= value <= hi:
            raise self.fail(field, f"must be in {lo}..{hi}, got {shown(value)}")
        return value

    def number(self, value: Any, field: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(field, f"must be a number, got {shown(value)}")
        try:
            number = float(value)
        except OverflowError:  # an integer beyond any float
            number = math.inf
        if not math.isfinite(number):
            raise self.fail(field, f"must be finite, got {shown(value)}")
        return number

    def text(self, value: Any, field: str, max_chars: int = MAX_TEXT_CHARS) -> str:
        if not isinstance(value, str) or not value.strip():
            raise self.fail(field, f"must be a non-empty string, got {shown(value)}")
        if len(value) > max_chars:
            raise self.fail(
                field, f"must be at most {max_chars} characters, got {len(value)} characters"
            )
        if not value.isprintable():
            raise self.fail(
                field, f"must be printable text (no newlines or control codes), got {shown(value)}"
            )
        return value

    def direction(self, value: Any, field: str) -> int:
        if isinstance(value, bool) or value not in (1, -1):
            raise self.fail(field, f"must be +1 or -1, got {shown(value)}")
        return int(value)

    def direction3(self, value: Any, field: str) -> tuple[float, float, float]:
        if not isinstance(value, (list, tuple)) or len(value) != 3:
            raise self.fail(field, f"must be a list of 3 numbers [x, y, z], got {shown(value)}")
        xyz = [self.number(v, f"{field}[{i}]") for i, v in enumerate(value)]
        norm = math.sqrt(sum(v * v for v in xyz))
        if norm == 0.0:
            raise self.fail(field, "must not be the zero vector")
        return (xyz[0] / norm, xyz[1] / norm, xyz[2] / norm)
