"""Seeded fault injection on the simulator's replies (same seed and traffic, same faults), and
*vanished* servos that neither execute nor answer for a while, then come back intact."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np


def _probability(name: str, value: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise ValueError(f"{name} must be a probability between 0 and 1, got {value!r}")
    return value


@dataclass
class FaultPlan:
    """The fault options, probabilities and a delay (ms); validated on construction."""

    drop: float = 0.0
    corrupt: float = 0.0
    latency_ms: float = 0.0
    latency_p: float = 1.0
    seed: int = 0

    def __post_init__(self) -> None:
        self.drop = _probability("drop", self.drop)
        self.corrupt = _probability("corrupt", self.corrupt)
        self.latency_p = _probability("latency_p", self.latency_p)
        self.latency_ms = float(self.latency_ms)
        if not (math.isfinite(self.latency_ms) and self.latency_ms >= 0.0):
            raise ValueError(f"latency_ms must be a finite number >= 0, got {self.latency_ms!r}")


@dataclass
class FaultInjector:
    """Applies a :class:`FaultPlan` to outgoing packets; tracks vanished servos."""

    plan: FaultPlan = field(default_factory=FaultPlan)
    vanished_until: dict[int, float] = field(default_factory=dict)
    dropped: int = 0
    corrupted: int = 0
    delayed: int = 0

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.plan.seed)

    def replan(self, plan: FaultPlan) -> None:
        """Switch to new fault options (the generator restarts from the new plan's seed)."""
        self.plan = plan
        self._rng = np.random.default_rng(plan.seed)

    def vanish(self, servo_id: int, now: float, duration_s: float) -> None:
        """Make ``servo_id`` unreachable from ``now`` for ``duration_s`` seconds."""
        if not (math.isfinite(duration_s) and duration_s >= 0.0):
            raise ValueError(f"vanish duration must be a finite number >= 0 s, got {duration_s!r}")
        self.vanished_until[servo_id] = now + duration_s

    def present(self, servo_id: int, now: float) -> bool:
        """Whether ``servo_id`` is on the bus at time ``now``."""
        until = self.vanished_until.get(servo_id)
        if until is None:
            return True
        if now >= until:
            del self.vanished_until[servo_id]
            return True
        return False

    def outgoing(self, packet: bytes) -> tuple[bytes | None, float]:
        """The packet as it will leave (None if dropped) and the extra delay in seconds."""
        plan = self.plan
        if plan.drop and self._rng.random() < plan.drop:
            self.dropped += 1
            return None, 0.0
        if plan.corrupt and self._rng.random() < plan.corrupt:
            self.corrupted += 1
            damaged = bytearray(packet)
            index = int(self._rng.integers(len(damaged)))
            # flip 1..255 so the byte surely changes
            damaged[index] ^= int(self._rng.integers(1, 256))
            packet = bytes(damaged)
        extra = 0.0
        if plan.latency_ms and self._rng.random() < plan.latency_p:
            self.delayed += 1
            extra = plan.latency_ms / 1000.0
        return packet, extra

    def counters(self) -> dict[str, int]:
        return {"dropped": self.dropped, "corrupted": self.corrupted, "delayed": self.delayed}
