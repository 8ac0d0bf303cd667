"""The one small exception tree of limbctl.

::

    LimbctlError
    ├── ConfigError            a rig profile, option or CLI argument is wrong (names the field)
    ├── FileFormatError        a model, dataset or rig file is corrupt, truncated or foreign
    ├── InvalidInputError      a command or quaternion is non-finite, non-unit or malformed
    │                          (also a ValueError, so numeric callers can catch that)
    ├── BusError               anything on the servo bus
    │   ├── PortError          the port cannot be opened or vanished
    │   │   └── PortInUse      another process holds the port (the message names it)
    │   ├── BusTimeout         a servo did not answer in time
    │   ├── CorruptReply       a reply failed its CRC or framing
    │   └── ServoAlarm         a servo reported a hardware error (carries the decoded bits)
    └── SafetyError            the gate refused to produce a goal (never silently bypassed)

Every message says what went wrong and, where it can, what to do about it.
"""

from __future__ import annotations


class LimbctlError(Exception):
    """Base of every error raised on purpose by limbctl."""


class ConfigError(LimbctlError):
    """A rig profile, option or argument is invalid."""


class FileFormatError(LimbctlError):
    """A file on disk is corrupt, truncated, of the wrong version or of another kind."""

    def __init__(self, path: object, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{self.path}: {problem}")


class InvalidInputError(LimbctlError, ValueError):
    """A command or quaternion cannot be used (NaN, inf, not unit length, malformed)."""


class BusError(LimbctlError):
    """Something went wrong on the servo bus."""

    def __init__(self, message: str, servo_id: int | None = None) -> None:
        self.servo_id = servo_id
        super().__init__(message)


class PortError(BusError):
    """The serial port cannot be opened, or it disappeared."""


class PortInUse(PortError):
    """Another controller holds the serial port; the message names its pid and command."""


class BusTimeout(BusError):
    """A servo did not answer within the retry budget."""


class CorruptReply(BusError):
    """A reply arrived but failed its CRC, framing or length check."""


class ServoAlarm(BusError):
    """A servo reported a hardware error; ``bits`` holds the decoded error names."""

    def __init__(
        self, message: str, servo_id: int | None = None, bits: tuple[str, ...] = ()
    ) -> None:
        self.bits = tuple(bits)
        super().__init__(message, servo_id)


class SafetyError(LimbctlError):
    """The gate refused to produce a goal position."""
