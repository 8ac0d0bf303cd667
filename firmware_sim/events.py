"""Faults scheduled from the command line: ``firmware-sim --event T:KIND:ID:VALUE``
(docs/simulator.md)."""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

from firmware_sim.simulator import Simulator

#: What an event can do, with the unit of its value.
KINDS = {"vanish": "s", "voltage": "V", "temperature": "deg C", "restart": "s", "push": "%"}
#: Kinds whose value may be negative (a cold motor, a push the other way).
SIGNED_KINDS = ("temperature", "push")


@dataclass(frozen=True)
class ScheduledEvent:
    """One fault: ``kind`` on servo ``servo_id`` with ``value``, ``at_s`` seconds after start."""

    at_s: float
    kind: str
    servo_id: int
    value: float

    def apply(self, sim: Simulator, slot: int) -> None:
        """Apply the fault to the servo in ``slot`` of ``sim`` now."""
        if self.kind in ("voltage", "temperature"):
            sim.set_environment(slot, **{self.kind: self.value})
        else:
            getattr(sim, self.kind)(slot, self.value)

    def unmatched(self, sim: Simulator) -> str | None:
        """Why no single servo of ``sim`` answers as this event's ID now, or None."""
        slots = sim.slots_answering(self.servo_id)
        if not slots:
            ids = ", ".join(map(str, sim.answering_ids()))
            return f"no servo answers as ID {self.servo_id}; the servos answer as {ids}"
        if len(slots) > 1:
            return (
                f"servos in slots {', '.join(map(str, slots))} all answer as ID "
                f"{self.servo_id}: an event names one servo; plug in one (--connect) or give "
                f"each its own ID (limbctl motors setup)"
            )
        return None


def parse_event(text: str) -> ScheduledEvent:
    """A :class:`ScheduledEvent` from ``T:KIND:ID:VALUE``; ValueError saying what is wrong."""
    parts = text.split(":")
    if len(parts) != 4:
        raise ValueError(f"event {text!r}: expected T:KIND:ID:VALUE, e.g. 2.5:vanish:1:0.5")
    at_text, kind, id_text, value_text = (part.strip() for part in parts)
    if kind not in KINDS:
        raise ValueError(f"event {text!r}: kind must be one of {', '.join(KINDS)}")
    try:
        at_s, value, servo_id = float(at_text), float(value_text), int(id_text)
    except ValueError:
        raise ValueError(f"event {text!r}: T and VALUE must be numbers, ID an integer") from None
    if not (math.isfinite(at_s) and at_s >= 0.0):
        raise ValueError(f"event {text!r}: T must be a finite number of seconds >= 0")
    if not 0 <= servo_id <= 252:
        raise ValueError(f"event {text!r}: ID must be 0..252")
    if not math.isfinite(value) or (kind not in SIGNED_KINDS and value < 0.0):
        unit = KINDS[kind]
        bound = "" if kind in SIGNED_KINDS else " >= 0"
        raise ValueError(f"event {text!r}: VALUE must be a finite number of {unit}{bound}")
    return ScheduledEvent(at_s, kind, servo_id, value)


@dataclass
class EventSchedule:
    """Events waiting for their time, applied once each by :meth:`apply_due`."""

    events: list[ScheduledEvent] = field(default_factory=list)
    #: Why each event that found no single servo when its time came was not applied.
    skipped: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.events = sorted(self.events, key=lambda event: event.at_s)

    def check(self, sim: Simulator) -> None:
        """ValueError naming the event if no single servo of ``sim`` answers as its ID."""
        for event in self.events:
            problem = event.unmatched(sim)
            if problem:
                raise ValueError(f"event at {event.at_s:g} s: {problem}")

    def apply_due(self, sim: Simulator) -> int:
        """Apply every due event to the servo answering as its ID then; how many were applied
        (one that finds no single servo goes to stderr and :attr:`skipped`)."""
        now = sim.now()
        due = [event for event in self.events if event.at_s <= now]
        applied = 0
        for event in due:
            slots = sim.slots_answering(event.servo_id)
            if len(slots) == 1:
                event.apply(sim, slots[0])
                applied += 1
                continue
            ids = ", ".join(map(str, sim.answering_ids()))
            what = f"{event.kind}:{event.servo_id}:{event.value:g}"
            why = (
                f"no servo answers as ID {event.servo_id} now (the servos answer as {ids})"
                if not slots
                else f"servos in slots {', '.join(map(str, slots))} all answer as ID "
                f"{event.servo_id} now"
            )
            self.skipped.append(f"event at {event.at_s:g} s ({what}): {why}: not applied")
            print(f"firmware-sim: {self.skipped[-1]}", file=sys.stderr, flush=True)
        self.events = self.events[len(due) :]
        return applied
