"""A felt leader servo dropping off the bus mid-push, over the real SDK and the simulator's pty.

Each run presses the two-servo leader into the wall (tests/teleop/test_felt_leader.py's session
and hand), waits until the wall holds it still, waits a further 0-4 ms (five phases of the 5 ms
cycle), then makes the tilt servo vanish for 0.3 s. From the simulator's 1 ms ground truth it
measures how long the pan motor still pushed after the vanish, against one period plus one
failed read (timed on the same bus afterwards), and prints the report's leader lines.

    python benchmarks/bench_leader_dropout.py [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.teleop.test_felt_leader (the felt session, a helper)

from tests.teleop.test_felt_leader import IDS, PRESS, Running, felt_session  # noqa: E402

PERIOD_S = 1.0 / 200.0


def one_run(tmp: Path, phase_s: float) -> tuple[float | None, float, float, list[str]]:
    """(push after the vanish s, from the clock read before the call, or None if the wall was
    not on; from the clock read after it; the bound s; report lines)."""
    with felt_session(tmp) as (session, source, log), source:
        session.rig.set_torque(True)
        with Running(session, source) as running:
            running.pressed_or_paced_out(PRESS)
            held_at = time.monotonic()
            running.until(
                lambda p: source.snap.armed is not None or time.monotonic() > held_at + 20.0
            )
            n = len(running.pushes)
            running.until(lambda p: len(p) > n)  # just after a cycle
            deadline = time.perf_counter() + phase_s
            while time.perf_counter() < deadline:
                pass  # the phase within the cycle (a busy wait: a sleep's grain is coarser)
            at = session.simulator.truth()["leader"]["t"]
            session.simulator.vanish(IDS[1], 0.3)
            # the vanish lands between the two reads of the simulator's clock
            landed = session.simulator.truth()["leader"]["t"]
            running.until(lambda p: session.simulator.truth()["leader"]["t"] > at + 0.5)
        lines = list(source.report_lines())
        session.simulator.vanish(IDS[1], 0.1)
        failed = session.rig.bus.read_cycle(ids=IDS, attempts=1)
    rows = [json.loads(line) for line in log.read_text().splitlines()]
    rows = [row for row in rows if row["t"] >= at]
    if not rows[0]["motor_nm"][0]:
        return None, 0.0, PERIOD_S + failed.duration_s, lines
    off = next((row["t"] for row in rows if row["motor_nm"][0] == 0.0), rows[-1]["t"])
    return off - at, off - landed, PERIOD_S + failed.duration_s, lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    print(f"load {os.getloadavg()[0]:.1f}")
    for k in range(args.runs):
        phase = (k % 5) * 0.001
        with tempfile.TemporaryDirectory() as tmp:
            pushed, after, bound, lines = one_run(Path(tmp), phase)
        said = "the wall was off"
        if pushed is not None:
            said = f"pushed {1e3 * after:.1f}-{1e3 * pushed:.1f} ms after the vanish"
        print(f"phase {1e3 * phase:.0f} ms: {said}, bound {1e3 * bound:.1f} ms")
        print("   " + " | ".join(line for line in lines if "dropout" in line or "leader:" in line))


if __name__ == "__main__":
    main()
