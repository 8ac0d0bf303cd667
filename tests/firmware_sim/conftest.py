"""The firmware_sim tests' stepped-clock harness: simulators on a clock the test sets."""

from __future__ import annotations

from contextlib import ExitStack, closing

import pytest

from firmware_sim.simulator import Simulator
from tests.conftest import SteppedClock


@pytest.fixture
def stepped():
    """``stepped(**options)``: a :class:`Simulator` of ``options`` on a :class:`SteppedClock` of
    its own, and that clock; each simulator is closed when the test ends."""
    with ExitStack() as made:

        def start(**options):
            clock = SteppedClock()
            return made.enter_context(closing(Simulator(clock=clock, **options))), clock

        yield start
