"""Faults around the gate that the servos themselves show (issue 13): each on the real loop, the
real SDK and the simulator, injected while the loop runs.

- torque switched off under a running teleop (one broadcast Torque Enable = 0, what a brown-out
  reset leaves) and a servo that browns out and restarts: noticed, named, safe state, exit 3;
- a servo that drops out: named while it is away, the loop keeps cycling (the other servo read
  every cycle, the silent one probed with one try at most every ``probe_interval_s``), the
  dropout reported with its length when it answers, or with its length so far when the session
  ends first;
- a servo pushed beyond what its motor holds: its drive saturates and it is reported as blocked
  before the firmware's own overload shutdown; a push the motor holds only with an overload
  still ends in the firmware's alarm;
- an alarm message says each servo's torque once, as the safe state left it.

Detection times are measured by ``benchmarks/bench_faults.py`` (docs/bench_faults.md); the
bounds here are generous, for a loaded machine.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

import pytest
from dynamixel_sdk import BROADCAST_ID, PacketHandler, PortHandler

from firmware_sim import SimulatedBus
from firmware_sim.wire import RIG_BAUD
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import HardwareError, Register
from limbctl.servo.health import HealthLimits
from limbctl.servo.rig import Rig
from limbctl.teleop.loop import LoopConfig, SafeState
from tests.safety.support import PROFILE, assert_goals_safe, goal_log_poses, live_rig, wait_for
from tests.safety.test_faults import LIMITS, RATE, LoopThread, sweep_lines

#: Generous bound on noticing a fault in a test (the benchmark measures the real figure).
NOTICE_BOUND_S = 2.0
#: The latency timer ``open_rig`` uses on the simulator's pty (a reply is awaited ~6 ms).
SIM_LATENCY_TIMER_MS = 2.0


def broadcast_torque_off(port_name: str) -> None:
    """One broadcast Torque Enable = 0 from another handle on the bus (no reply, no lock)."""
    port = PortHandler(port_name)
    assert port.setBaudRate(RIG_BAUD)
    try:
        PacketHandler(2.0).write1ByteTxOnly(port, BROADCAST_ID, Register.TORQUE_ENABLE.address, 0)
    finally:
        port.closePort()


def fault_time(loop: LoopThread) -> float:
    """Seconds from the last logged cycle before the fault to the end (the loop's own clock)."""
    return loop.summary.elapsed_s - loop.cycles.rows[-1]["t"]


class ReadLog(Rig):
    """The real rig; it also remembers each cycle read it was asked for (an observer):
    (perf_counter s, ids, attempts)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.reads: list[tuple[float, tuple[int, ...], int]] = []

    def read_cycle(self, attempts=1, ids=None):
        self.reads.append((time.perf_counter(), tuple(ids or self.ids), attempts))
        return super().read_cycle(attempts, ids)


@contextmanager
def sim_rig(goal_log=None):
    """The simulated rig driven as ``open_rig`` drives it (latency timer 2 ms), logging its
    reads; set up beforehand at the SDK's patient 16 ms, so a loaded machine's late reply does
    not fail the set-up."""
    with SimulatedBus(ids=PROFILE.ids, goal_log=goal_log) as sim:
        with ServoBus.from_profile(PROFILE, port=sim.port) as setup:
            Rig(PROFILE, setup).configure()
            Rig(PROFILE, setup).set_torque(True)
        bus = ServoBus.from_profile(PROFILE, port=sim.port, latency_timer_ms=SIM_LATENCY_TIMER_MS)
        with bus:
            bus.note_pwm_limits(setup.pwm_limits)  # what set-up read, for this bus's reports
            yield sim, ReadLog(PROFILE, bus)


def dropouts_line(summary) -> str:
    """The summary's line listing the dropouts."""
    return next(line for line in summary.lines() if line.startswith("servo dropouts"))


def still_lines(n: int) -> list[str]:
    """A command that holds the limb still (inside the BEAN region), ``n`` lines long."""
    return ['{"pan": 5.0, "tilt": 0.0}'] * n


@pytest.mark.parametrize("safe_state", [SafeState.HOLD, SafeState.TORQUE_OFF])
def test_torque_switched_off_under_teleop_is_noticed(tmp_path, safe_state):
    log = tmp_path / "goals.jsonl"
    with live_rig(goal_log=log) as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0, safe_state=safe_state)
        with LoopThread(rig, config, sweep_lines(20000)) as loop:
            loop.cycles.wait_cycles(20)
            broadcast_torque_off(sim.port)
            loop.join(timeout_s=30.0)
        summary = loop.summary
        truth = sim.truth()
    assert summary.exit_code == 3 and summary.ended_by == "fault", summary.fault
    assert "reports torque off while it is being driven" in summary.fault
    assert "servo 1" in summary.fault or "servo 2" in summary.fault
    assert fault_time(loop) < NOTICE_BOUND_S
    assert not any(servo["torque_on"] for servo in truth["servos"].values())
    if safe_state is SafeState.HOLD:
        assert "pan and tilt torque off as the servo reports it" in summary.fault
    else:
        # the servos had already lost it: torque-off says so, not that it switched it off
        assert summary.fault.endswith(
            "— pan and tilt torque was already off (as the servos reported it); it stays off"
        )
    assert_goals_safe(
        goal_log_poses(log), loop.gate.envelope, LIMITS, loop.gate.produced_ticks(rig)
    )


def test_a_servo_that_browns_out_and_restarts_is_noticed(tmp_path):
    with live_rig() as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0)
        with LoopThread(rig, config, sweep_lines(20000)) as loop:
            loop.cycles.wait_cycles(20)
            sim.restart(2, 0.05)  # 50 ms off the bus, back with RAM at its defaults
            loop.join(timeout_s=30.0)
        summary = loop.summary
    assert summary.exit_code == 3 and summary.ended_by == "fault"
    assert "servo 2 reports torque off" in summary.fault and "brown-out" in summary.fault
    assert "tilt torque off" in summary.fault and "pan holding the last safe pose" in summary.fault


def test_a_dropout_keeps_the_loop_cycling_probes_the_servo_and_reports_its_length(tmp_path):
    log = tmp_path / "goals.jsonl"
    seen: list[tuple[float, str]] = []
    # loop time -> perf_counter, from each cycle's value as it is handed on (its end)
    clock: list[float] = []

    def observe(cycle) -> None:
        clock.append(time.perf_counter() - cycle.t)
        seen.extend((cycle.t, n) for n in cycle.notices)

    vanish_s = 0.3
    with sim_rig(goal_log=log) as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0, on_cycle=observe)
        with LoopThread(rig, config, sweep_lines(20000)) as loop:
            loop.cycles.wait_cycles(200)
            injected = loop.cycles.rows[-1]["t"]
            sim.vanish(2, vanish_s)
            wait_for(
                lambda: any(t > injected and n.startswith("servo 2 answered") for t, n in seen),
                30.0,
                "servo 2 to be reported back",
            )
            loop.cycles.wait_cycles(len(loop.cycles.rows) + 20)
        summary = loop.summary
        reads = list(rig.reads)
    assert summary.exit_code == 0 and summary.ended_by == "stopped", summary.fault
    # (on a loaded machine a late reply may name a servo for a moment too: this is the dropout
    # that began after the injection)
    dropout = next(d for d in summary.dropouts if d.servo_id == 2 and d.started_s > injected)
    assert not dropout.ongoing
    start, end = dropout.started_s, dropout.started_s + dropout.duration_s
    named = [t for t, n in seen if n == "servo 2 stopped answering; holding its last goal"]
    assert any(start <= t < start + NOTICE_BOUND_S for t in named)
    assert any(abs(t - end) < 1e-6 and n == dropout.describe() for t, n in seen)
    # timed from the first missed read to the probe that found it back: the 0.3 s, known to
    # within a probe interval (0.05 s) and a cycle; generous for a loaded machine
    assert vanish_s - 0.05 <= dropout.duration_s < vanish_s + NOTICE_BOUND_S
    assert f"servo 2 {dropout.duration_s:.3f} s" in dropouts_line(summary)
    assert "still silent" not in dropouts_line(summary)
    # the loop kept cycling: the cycles completed during the dropout are a large share of what
    # it ran before it (waiting for the silent servo in each cycle gave about a fifth)
    times = [row["t"] for row in loop.cycles.rows]
    before = [t for t in times if t < start][-100:]
    healthy_hz = (len(before) - 1) / (before[-1] - before[0])
    during = sum(start <= t < end for t in times)
    assert during >= 0.4 * healthy_hz * dropout.duration_s, (during, healthy_hz)
    # while it was away, servo 2 was only probed: alone, one try each, at most one per 0.05 s
    # (inside the dropout: after the read that missed it, before the probe that found it)
    offset = min(clock)  # perf_counter at loop time 0, to within a cycle's end
    inside = [(at, ids, n) for at, ids, n in reads if 2 in ids and start + 0.02 < at - offset]
    inside = [(at, ids, n) for at, ids, n in inside if at - offset < end - 0.005]
    assert inside and all(ids == (2,) and n == 1 for _, ids, n in inside), inside
    probes = [at for at, _, _ in inside]
    gaps = [b - a for a, b in zip(probes, probes[1:], strict=False)]
    # (the loop keeps 0.05 s between probe cycles; the answering servo's read before each probe
    # takes longer when one of its replies is late)
    assert min(gaps, default=1.0) >= 0.03, gaps
    assert len(probes) <= dropout.duration_s / 0.05 + 2
    assert_goals_safe(
        goal_log_poses(log), loop.gate.envelope, LIMITS, loop.gate.produced_ticks(rig)
    )


def test_a_dropout_still_going_on_at_a_clean_end_is_reported_with_its_length_so_far():
    seen: list[str] = []
    with sim_rig() as (sim, rig):
        # lost only after 30 s: this session ends cleanly while servo 2 is still away
        config = LoopConfig(
            rate_hz=RATE,
            duration_s=60.0,
            health=HealthLimits(lost_after_s=30.0),
            on_cycle=lambda cycle: seen.extend(cycle.notices),
        )
        with LoopThread(rig, config, sweep_lines(20000)) as loop:
            loop.cycles.wait_cycles(20)
            sim.vanish(2, 60.0)
            wait_for(lambda: "servo 2 stopped answering; holding its last goal" in seen, 30.0, "")
            loop.cycles.wait_cycles(len(loop.cycles.rows) + 40)
        summary = loop.summary
    assert summary.exit_code == 0 and summary.ended_by == "stopped", summary.fault
    (dropout,) = [d for d in summary.dropouts if d.ongoing and d.servo_id == 2]
    assert dropout.servo_id == 2 and dropout.duration_s > 0.1
    said = [n for n in summary.notices if "servo 2 still silent when the session ended" in n]
    assert len(said) == 1 and f"{dropout.duration_s:.3f} s so far" in said[0]
    assert f"servo 2 {dropout.duration_s:.3f} s so far (still silent)" in dropouts_line(summary)


@pytest.mark.parametrize("safe_state", [SafeState.HOLD, SafeState.TORQUE_OFF])
def test_a_servo_pushed_hard_is_reported_blocked_before_the_firmware_trips(tmp_path, safe_state):
    log = tmp_path / "goals.jsonl"
    with sim_rig(goal_log=log) as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0, safe_state=safe_state)
        with LoopThread(rig, config, still_lines(20000)) as loop:
            loop.cycles.wait_cycles(200)
            sim.push(1, 300.0)  # three times stall torque: the motor cannot hold it
            loop.join(timeout_s=30.0)
        summary = loop.summary
        truth = sim.truth()
        if safe_state is SafeState.HOLD:
            # torque stays on against the push: the firmware's own overload shutdown follows
            overload = int(HardwareError.OVERLOAD)
            wait_for(
                lambda: sim.truth()["servos"][1]["hardware_error_status"] & overload,
                NOTICE_BOUND_S,
                "the firmware's overload shutdown after the loop's fault",
            )
    assert summary.exit_code == 3 and summary.ended_by == "fault", summary.fault
    # the loop's own rule, not the firmware's alarm (which it would report as a hardware error)
    assert summary.fault.startswith("servo 1 does not follow (blocked): "), summary.fault
    assert "drive saturated (PWM" in summary.fault and "blocked or overloaded" in summary.fault
    assert "hardware error" not in summary.fault
    assert truth["servos"][1]["hardware_error_status"] == 0
    if safe_state is SafeState.HOLD:
        assert summary.fault.endswith("— holding the last safe pose (torque on)")
        assert all(servo["torque_on"] for servo in truth["servos"].values())
    else:
        assert summary.fault.endswith("— torque switched off")
        assert not any(servo["torque_on"] for servo in truth["servos"].values())
    assert_goals_safe(
        goal_log_poses(log), loop.gate.envelope, LIMITS, loop.gate.produced_ticks(rig)
    )


def test_a_push_the_motor_holds_only_overloaded_ends_in_the_firmwares_alarm():
    with sim_rig() as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0)
        with LoopThread(rig, config, still_lines(20000)) as loop:
            loop.cycles.wait_cycles(200)
            # 150 % of stall: held 3 deg off its goal (not blocked), overloaded: after 0.5 s
            # the firmware shuts the servo down
            sim.push(1, 150.0)
            loop.join(timeout_s=30.0)
        summary = loop.summary
        truth = sim.truth()
    assert summary.exit_code == 3, summary.fault
    assert "servo 1: hardware error reported (servo 1: overload)" in summary.fault
    assert "pan torque off as the servo reports it; tilt holding" in summary.fault
    assert not truth["servos"][1]["torque_on"] and truth["servos"][2]["torque_on"]


@pytest.mark.parametrize("safe_state", [SafeState.HOLD, SafeState.TORQUE_OFF])
@pytest.mark.parametrize("alarm", ["voltage", "overheating"])
def test_an_alarm_message_says_each_servos_torque_once(alarm, safe_state):
    with live_rig() as (sim, rig):
        config = LoopConfig(rate_hz=RATE, duration_s=60.0, safe_state=safe_state)
        with LoopThread(rig, config, sweep_lines(20000)) as loop:
            loop.cycles.wait_cycles(20)
            if alarm == "voltage":
                sim.set_voltage(1, 5.0)  # not in the Shutdown mask: torque stays on
            else:
                sim.set_temperature(2, 95.0)  # shuts servo 2 down: its torque goes off
            loop.join(timeout_s=30.0)
        summary = loop.summary
        truth = sim.truth()
    fault = summary.fault
    assert summary.exit_code == 3, fault
    assert ("servo 1: input voltage" if alarm == "voltage" else "servo 2: overheating") in fault
    assert "`limbctl reboot`" in fault and "ServoBus" not in fault
    alarm_part, state = fault.split(" — ")
    assert "torque" not in alarm_part, "the alarm part must leave torque to the safe state"
    expected = {
        ("voltage", SafeState.HOLD): "holding the last safe pose (torque on)",
        ("voltage", SafeState.TORQUE_OFF): "torque switched off",
        ("overheating", SafeState.HOLD): (
            "tilt torque off as the servo reports it; pan holding the last safe pose (torque on)"
        ),
        ("overheating", SafeState.TORQUE_OFF): (
            "torque switched off on pan; tilt torque was already off (as the servo reported it)"
        ),
    }
    assert state == expected[alarm, safe_state]
    torque = {sid: servo["torque_on"] for sid, servo in truth["servos"].items()}
    if safe_state is SafeState.TORQUE_OFF:
        assert torque == {1: False, 2: False}
    else:
        assert torque == {1: True, 2: alarm == "voltage"}
