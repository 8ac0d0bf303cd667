"""Open a rig for a job: ``--port`` given, that device; else a profile's device; else (``port:
sim``) :class:`firmware_sim.SimulatedBus` in its own process, through the real dynamixel-sdk."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from calib.profile import RigProfile
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import MAX_TICK
from limbctl.servo.profiles import check_models, load_rig_profile
from limbctl.servo.rig import Rig
from limbctl.servo.setup import configure_servos


@dataclass
class Session:
    """An open rig and, when simulated, the simulator behind it."""

    rig: Rig
    profile: RigProfile
    simulator: Any | None  # firmware_sim.SimulatedBus when simulated

    @property
    def simulated(self) -> bool:
        return self.simulator is not None


def demo_region_path() -> Path:
    """The packaged REGION.yaml the demo's scripted hand teaches."""
    return Path(str(resources.files("limbctl").joinpath("data", "demo_region.yaml")))


@contextmanager
def open_rig(
    port: str | None = None,
    rig_path: Path | None = None,
    baud: int | None = None,
    hand: Path | Mapping | None = None,
    goal_log: Path | None = None,
    seed: int = 0,
    sim_options: Mapping[str, Any] | None = None,
    extra_ids: tuple[int, ...] = (),
    latency_timer_ms: float | None = None,
    profile: RigProfile | None = None,
) -> Iterator[Session]:
    """Connect to the servos of the rig (``profile``, or the YAML at ``rig_path``, default the
    simulated rig), starting the simulator (given ``hand``, ``goal_log``, ``seed``,
    ``sim_options``) when no ``port`` is known, with ``extra_ids`` on the same bus and the USB
    adapter's ``latency_timer_ms`` (default 16, 2 on the simulator's pty); close on exit."""
    profile = profile if profile is not None else load_rig_profile(rig_path)
    device = port if port is not None else (None if profile.is_sim else profile.port)
    with ExitStack() as stack:
        simulator = None
        if device is None:
            from firmware_sim import SimulatedBus

            simulator = stack.enter_context(
                SimulatedBus(
                    ids=profile.ids + tuple(extra_ids),
                    model=profile.model,
                    hand=hand,
                    goal_log=goal_log,
                    seed=seed,
                    **({"roll_id": profile.ids[-1]} if profile.twists else {}),
                    **{"baud": baud or profile.baud, **dict(sim_options or {})},
                )
            )
            device = simulator.port
        if latency_timer_ms is None:  # a pty has no USB latency: 2 ms covers scheduling
            latency_timer_ms = 2.0 if simulator is not None else 16.0
        # a leader on the same bus may be another model: only the rig's servos are checked
        bus = ServoBus(
            device,
            baud or profile.baud,
            profile.ids + tuple(extra_ids),
            None if extra_ids else profile.model,
            latency_timer_ms=latency_timer_ms,
        )
        stack.enter_context(bus)
        if extra_ids:
            check_models(bus, profile.ids, profile.model)
        yield Session(rig=Rig(profile, bus), profile=profile, simulator=simulator)


def configure(rig: Rig, extra_ids: tuple[int, ...] = ()) -> None:
    """Set up the rig's servos with its hard limits, and ``extra_ids`` (a leader) full range."""
    configure_servos(rig.bus, {**rig.tick_limits(), **dict.fromkeys(extra_ids, (0, MAX_TICK))})


@contextmanager
def stop_on_signals() -> Iterator[threading.Event]:
    """An event set by SIGINT or SIGTERM while the block runs (handlers restored after)."""
    stop = threading.Event()

    def handler(signum: int, frame: object) -> None:
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
