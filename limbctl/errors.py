"""The one small exception tree of limbctl (drawn in docs/architecture.md)."""

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
