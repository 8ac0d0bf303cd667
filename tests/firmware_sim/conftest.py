"""The firmware_sim tests' stepped-clock harness: simulators on a clock the test sets."""

from __future__ import annotations

from contextlib import ExitStack, closing

import pytest

from firmware_sim.simulator import Simulator


class Clock:
    """A clock the test sets and steps: ``t`` seconds."""

    t = 0.0

    def __call__(self) -> float:
        return self.t


@pytest.fixture
def stepped():
    """``stepped(**options)``: a :class:`Simulator` of ``options`` on a :class:`Clock` of its own,
    and that clock; each simulator is closed when the test ends."""
    with ExitStack() as made:

        def start(**options):
            clock = Clock()
            return made.enter_context(closing(Simulator(clock=clock, **options))), clock

        yield start
