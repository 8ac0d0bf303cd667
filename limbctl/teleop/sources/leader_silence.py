"""A felt leader's silent servos: when each stopped answering, for how long, and when to ask."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from limbctl.servo.cycle import CycleRead
from limbctl.servo.health import Dropout

#: Two reads in a row: one lost reply is not a dropout.
MISSES_FOR_DROPOUT = 2
#: How often (s) a silent leader is probed: one failed read (6.3 ms) in ten cycles keeps the rate.
PROBE_INTERVAL_S = 0.05


@dataclass
class LeaderSilence:
    """The leader's silent servos: their dropouts, failed reads and the longest one (s)."""

    dropouts: list[Dropout] = field(default_factory=list)
    misses: int = 0
    longest_failed_read_s: float = 0.0
    _first_miss: dict[int, tuple[float, int]] = field(default_factory=dict)  # at, misses
    _probed_at: float = -math.inf

    @property
    def silent(self) -> tuple[int, ...]:
        """The servos missed by MISSES_FOR_DROPOUT reads in a row or more, now."""
        return tuple(i for i, (_, n) in self._first_miss.items() if n >= MISSES_FOR_DROPOUT)

    def missed(self, read: CycleRead, now_s: float) -> None:
        """A failed read at ``now_s``: each servo it names missed once more."""
        self.misses += 1
        self.longest_failed_read_s = max(self.longest_failed_read_s, read.duration_s)
        for servo_id in read.silent:
            at, count = self._first_miss.get(servo_id, (now_s - read.duration_s, 0))
            self._first_miss[servo_id] = (at, count + 1)

    def heard(self, now_s: float) -> list[str]:
        """A good read at ``now_s``: every silence ends; the notices of the dropouts it ends."""
        notes = []
        for servo_id, (at, count) in self._first_miss.items():
            if count >= MISSES_FOR_DROPOUT:
                dropout = Dropout(servo_id, at, now_s - at)
                self.dropouts.append(dropout)
                notes.append(f"leader {dropout.describe()}")
        self._first_miss.clear()
        return notes

    def read_now(self, now_s: float) -> bool:
        """Whether the cycle reads the leader now (while silent, once per PROBE_INTERVAL_S)."""
        if not self.silent or now_s - self._probed_at >= PROBE_INTERVAL_S:
            self._probed_at = now_s
            return True
        return False

    def lines(self, now_s: float) -> list[str]:
        """The summary's line on the leader's dropouts and failed reads."""
        ongoing = [
            Dropout(i, at, now_s - at, ongoing=True)
            for i, (at, n) in self._first_miss.items()
            if n >= MISSES_FOR_DROPOUT
        ]
        every = [*self.dropouts, *ongoing]
        if not every and not self.misses:
            return ["leader dropouts: none"]
        still = " so far (still silent)"
        said = "; ".join(
            f"servo {d.servo_id} {d.duration_s:.3f} s{still if d.ongoing else ''}" for d in every
        )
        return [
            f"leader dropouts: {said or 'none'} ({self.misses} failed reads, the longest "
            f"{1e3 * self.longest_failed_read_s:.1f} ms; each switched every leader servo's "
            f"push off at once)"
        ]
