"""Where a recorder's hole comes from: the recorder and the simulator timed side by side, loaded.

Run: ``.venv/bin/python benchmarks/bench_record_gaps.py --seconds 20 --runs 3 --burners 0,4``
(writes docs/bench_record_gaps.md).

Each run records ``--seconds`` of the simulator's scripted hand on the three-servo rig
(``calib/rigs/sim3.yaml``, the demo's teaching, 125 Hz) through :func:`limbctl.teach.record.record`
and the real dynamixel-sdk, exactly as ``limbctl record --rig sim3`` does, but with the simulator
started here (``firmware_sim.bus.serve`` on a pty, in its own process, as
:class:`firmware_sim.SimulatedBus` starts it) so that its own timeline is kept: the monotonic time
of each pass of its serve loop (the loop wakes at least every ``TICK_S``, 5 ms, when it runs at
all) and of each batch of bytes it received. The recorder's side keeps the monotonic time and
outcome of every read. Both processes read the same system-wide monotonic clock.

Runs with 0 and with N CPU burners (``python -c "while 1: pass"``, started and ended here) are
interleaved. For each run: the 1-minute load average at its end, the largest gap between two
samples of the teaching, the recorder's failed reads, and at the largest sample gap the longest
pause of the simulator's serve loop inside it (a pause as long as the sample gap: the simulator's
process did not run; short pauses but failed reads: the replies went astray on the way).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from limbctl.errors import BusError

ROOT = Path(__file__).resolve().parents[1]
RIG = ROOT / "calib" / "rigs" / "sim3.yaml"
HAND = ROOT / "limbctl" / "data" / "demo_region3.yaml"
#: Recorder rate (Hz): ``limbctl record``'s default.
RATE_HZ = 125.0


def serve_traced(link: str, trace: str, config_json: str) -> None:
    """The simulator process: serve on a pty at ``link``; on SIGTERM write its timeline."""
    import resource
    import select as select_module
    import types

    import firmware_sim.bus as sim_bus
    from firmware_sim.bus import PtyEndpoint, build_simulator, serve

    # the serve loop's blocking calls, each one taking 20 ms or more kept with its length
    slow: list[tuple[str, float, float, float]] = []

    def timed(name, call):
        def wrapper(*args):
            start = time.monotonic()
            try:
                return call(*args)
            finally:
                took = time.monotonic() - start
                if took >= 0.02:
                    timeout = args[-1] if args and isinstance(args[-1], float) else -1.0
                    slow.append((name, start, took, timeout))

        return wrapper

    sim_bus.time = types.SimpleNamespace(
        monotonic=time.monotonic, sleep=timed("sleep", time.sleep), perf_counter=time.perf_counter
    )
    sim_bus.select = types.SimpleNamespace(select=timed("select", select_module.select))

    sim = build_simulator(json.loads(config_json))
    passes: list[float] = []
    batches: list[tuple[float, int, int]] = []
    advance, receive = sim.advance, sim.receive

    schedstat = os.open("/proc/self/schedstat", os.O_RDONLY)

    def traced_advance(until_s=None):
        # /proc/self/schedstat: ns on a CPU, ns waiting runnable on a run queue, timeslices
        run_delay_s = 1e-9 * int(os.pread(schedstat, 100, 0).split()[1])
        faults = resource.getrusage(resource.RUSAGE_SELF).ru_majflt
        passes.append((time.monotonic(), time.process_time(), run_delay_s, faults))
        return advance(until_s)

    def traced_receive(data, arrived_s=None, baud=None):
        replies = receive(data, arrived_s, baud)
        batches.append((time.monotonic(), len(data), len(replies)))
        return replies

    sim.advance, sim.receive = traced_advance, traced_receive
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    with PtyEndpoint(link) as endpoint:
        serve(sim, endpoint, lambda: bool(stop))
    np.savez(
        trace,
        passes=np.array(passes).reshape(-1, 4),
        batches=np.array(batches).reshape(-1, 3),
        slow=json.dumps(slow),
    )


def record_once(seconds: float, seed: int, workdir: Path, latency_ms: float = 2.0) -> dict:
    """One traced recording; its figures."""
    from limbctl.servo.bus import ServoBus
    from limbctl.servo.profiles import load_rig_profile
    from limbctl.servo.rig import Rig
    from limbctl.teach.dataset import DatasetWriter, load_dataset
    from limbctl.teach.record import record

    profile = load_rig_profile(RIG)
    workdir.mkdir(parents=True)
    link, trace = workdir / f"pty{seed}", workdir / f"sim{seed}.npz"
    config = {"ids": list(profile.ids), "hand": str(HAND), "seed": seed, "baud": profile.baud}
    config["roll_id"] = profile.roll.id
    sim = subprocess.Popen(
        [sys.executable, __file__, "--serve", str(link), str(trace), json.dumps(config)]
    )
    deadline = time.monotonic() + 30.0
    while not link.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    reads: list[tuple[float, float, int, float, float]] = []
    try:
        with ServoBus(
            str(link), profile.baud, profile.ids, profile.model, latency_timer_ms=latency_ms
        ) as bus:
            rig = Rig(profile, bus)
            port = bus._port  # the SDK's port handler: its calls kept for the slowest read
            events: list[tuple] = []
            slowest: list = [0.0, []]

            def logged(name, call):
                def wrapper(*args):
                    value = call(*args)
                    if name != "readPort" or value:
                        events.append((name, time.monotonic(), time.time(), repr(value)[:40]))
                    return value

                return wrapper

            for name in ("writePort", "readPort", "clearPort"):
                setattr(port, name, logged(name, getattr(port, name)))

            class Timed:
                """The rig, each read's start, end and outcome kept (1 read, 0 failed)."""

                def read_pose(self):
                    start, cpu = time.monotonic(), time.thread_time()
                    events.clear()
                    try:
                        pose = rig.read_pose()
                    except Exception:
                        reads.append((start, time.monotonic(), 0, cpu, time.thread_time()))
                        raise
                    reads.append((start, time.monotonic(), 1, cpu, time.thread_time()))
                    if reads[-1][1] - start > slowest[0]:
                        slowest[:] = [
                            reads[-1][1] - start,
                            [
                                (
                                    e[0],
                                    round(e[1] - start, 4),
                                    round(e[2] - events[0][2] if events else 0, 4),
                                    e[3],
                                )
                                for e in events
                            ],
                        ]
                    return pose

                def set_torque(self, enabled):
                    rig.set_torque(enabled)

            out = workdir / f"teach{seed}.limb"
            with DatasetWriter(out, rig=profile.name) as writer:
                summary = record(Timed(), writer, RATE_HZ, duration_s=seconds)
    finally:
        sim.send_signal(signal.SIGTERM)
        sim.wait(30)
    t = load_dataset(out).t
    (workdir / "slowest_read.json").write_text(json.dumps(slowest, indent=0))
    np.save(workdir / "reads.npy", np.array(reads))
    gaps = np.diff(t)
    k = int(np.argmax(gaps))
    r = np.array(reads)
    timeline = np.load(trace)
    passes, sim_cpu, sim_wait, sim_faults = timeline["passes"].T
    slow = [c for c in json.loads(str(timeline["slow"])) if c[2] >= 0.1]
    # the sample gap on the monotonic clock: a sample's time is taken as its read starts (a read
    # retried within the bus's budget then succeeding is one read), so the gap runs from the
    # start of sample k's read to the start of sample k + 1's
    ok = np.flatnonzero(r[:, 2] == 1)
    a, b = ok[k], ok[k + 1]
    lo, hi = r[a, 0], r[b, 0]
    within = (passes >= lo) & (passes <= hi)
    edges = np.r_[lo, passes[within], hi]
    pause = int(np.argmax(np.diff(edges)))
    # the simulator's CPU time and time runnable on a run queue over its longest pause in the
    # gap (its passes around it)
    before = np.flatnonzero(passes <= edges[pause])
    after = np.flatnonzero(passes >= edges[pause + 1])
    sim_cpu_ms = sim_wait_ms = -1.0
    if len(before) and len(after):
        sim_cpu_ms = 1e3 * float(sim_cpu[after[0]] - sim_cpu[before[-1]])
        sim_wait_ms = 1e3 * float(sim_wait[after[0]] - sim_wait[before[-1]])
    # the recorder's time in reads (sample k's, then the failed ones) and the longest time
    # between two reads, over the gap
    span = r[a:b]
    in_reads = float((span[:, 1] - span[:, 0]).sum())
    between = float((r[a + 1 : b + 1, 0] - r[a:b, 1]).max())
    return {
        "samples": len(t),
        "gap_ms": 1e3 * float(gaps[k]),
        "gap_at_s": float(t[k]),
        "failed": summary.failed_reads,
        "dropouts": summary.dropouts,
        "sim_pause_ms": 1e3 * float(np.diff(edges).max()),
        "sim_cpu_in_pause_ms": sim_cpu_ms,
        "sim_runnable_waiting_in_pause_ms": sim_wait_ms,
        "rec_in_reads_ms": 1e3 * in_reads,
        "rec_between_reads_max_ms": 1e3 * between,
        "rec_longest_read_ms": 1e3 * float((span[:, 1] - span[:, 0]).max()),
        "rec_cpu_in_gap_ms": 1e3 * float(r[b, 3] - r[a, 3]),
        "sim_major_faults": int(sim_faults[-1] - sim_faults[0]),
        "sim_calls_over_100ms": [[c[0], round(c[2], 3), c[3]] for c in slow][:6],
        "sim_pause_all_ms": 1e3 * float(np.diff(passes).max()),
        "failed_in_gap": int(b - a - 1),
        "batches_in_gap": int(
            ((timeline["batches"][:, 0] >= lo) & (timeline["batches"][:, 0] <= hi)).sum()
        ),
        "load": os.getloadavg()[0],
    }


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--serve":
        serve_traced(*sys.argv[2:5])
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--runs", type=int, default=3, help="runs of each burner count")
    parser.add_argument(
        "--burners",
        default="0,4,4s",
        help="burner counts, interleaved; a count ending in s starts its burners in a session "
        "of their own (another autogroup of the scheduler), else in the recorder's",
    )
    parser.add_argument(
        "--latency-ms",
        default="2",
        help="latency timers (ms) the recorder's bus assumes, interleaved: each sets how long a "
        "reply is awaited (2 * timer + 2 ms + bytes); 2 is what `limbctl record` uses on the pty",
    )
    parser.add_argument("--keep", type=Path, help="keep each run's files in a folder made here")
    parser.add_argument("--label", default="", help="a name for this set of runs")
    parser.add_argument("--json", type=Path, help="append each run's figures here")
    args = parser.parse_args()
    counts = [(int(c.rstrip("s")), c.endswith("s")) for c in args.burners.split(",")]
    with contextlib.ExitStack() as stack:
        tmp = tempfile.mkdtemp(dir=args.keep) if args.keep else None
        tmp = tmp or stack.enter_context(tempfile.TemporaryDirectory())
        for run in range(args.runs):
            for (count, own_session), latency in (
                (c, lat) for c in counts for lat in map(float, args.latency_ms.split(","))
            ):
                burners = [
                    subprocess.Popen(
                        [sys.executable, "-c", "while 1: pass"], start_new_session=own_session
                    )
                    for _ in range(count)
                ]
                where = Path(tmp) / f"{run}_{count}{'s' * own_session}_{latency:g}"
                try:
                    result = record_once(args.seconds, run, where, latency)
                except BusError as exc:  # the bus did not open: the simulator starved then too
                    result = {"open_failed": str(exc)}
                finally:
                    for b in burners:
                        b.kill()
                        b.wait()
                result.update(
                    burners=count,
                    run=run,
                    label=args.label,
                    own_session=own_session,
                    latency_ms=latency,
                )
                print(json.dumps(result), flush=True)
                if args.json is not None:
                    with args.json.open("a") as f:
                        f.write(json.dumps(result) + "\n")


if __name__ == "__main__":
    main()
