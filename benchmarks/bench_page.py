"""The teleop loop's rate while the steering page floods its socket (docs/bench_page.md).

Run: ``.venv/bin/python benchmarks/bench_page.py --seconds 15 --repeats 2 --out docs/bench_page.md``

``limbctl teleop --source page`` runs at 200 Hz on the embedded simulator, a Rigid Map trained on
the tests' 20 s recording as its gate. A client in its own process holds control with the
session's key and the page's Origin, and sends ``{"pan": .., "tilt": ..}`` lines on a small
circle inside the region:

- ``page``: at 20 Hz, as the page does;
- ``flood``: at ``--flood`` messages per second (10,000 by default), in bursts every 10 ms.

The modes run in turn, ``--repeats`` times. Reported: the loop's cycles per second and cycle
time (p50, p99) from its telemetry, the messages the client sent per second, and the flood's
rate as a share of the page's in the same run.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: Seconds between the client's bursts: 100 bursts a second, so 10,000 msg/s is 100 a burst.
BURST_PERIOD_S = 0.01
#: The page's own resend rate (control.js SEND_MS = 50 ms).
PAGE_HZ = 20.0


def client(url: str, rate: float, seconds: float) -> None:
    """Hold control and send ``rate`` messages a second for ``seconds``; print what was sent.

    The frames are built (masked, as a browser's) once, and each burst is one write: the flood
    costs the sender little, so what is measured is what it costs the session.
    """
    import websocket

    origin = url.split("/?")[0]
    ws_url = origin.replace("http://", "ws://") + "/ws?" + url.split("?", 1)[1]
    socket = websocket.create_connection(ws_url, origin=origin, timeout=10)
    per_burst = max(1, round(rate * BURST_PERIOD_S))
    period = per_burst / rate
    # a 10 deg circle around (-18, -4) deg, well inside the region, in 400 points
    frames = []
    for i in range(400):
        phase = 2.0 * math.pi * i / 400.0
        line = {"pan": -18.0 + 10.0 * math.cos(phase), "tilt": -4.0 + 10.0 * math.sin(phase)}
        frames.append(websocket.ABNF.create_frame(json.dumps(line), websocket.ABNF.OPCODE_TEXT))
    wire = [frame.format() for frame in frames]
    sent, started = 0, time.perf_counter()
    next_burst = started
    while time.perf_counter() - started < seconds:
        socket.sock.sendall(b"".join(wire[(sent + k) % len(wire)] for k in range(per_burst)))
        sent += per_burst
        next_burst += period
        delay = next_burst - time.perf_counter()
        if delay > 0:
            time.sleep(delay)
    elapsed = time.perf_counter() - started
    socket.close()
    print(json.dumps({"sent": sent, "seconds": elapsed}))


def model_file(folder: Path) -> Path:
    from calib.profile import default_sim_profile
    from limbctl.envelope import RigidMap
    from limbctl.teach.dataset import load_dataset

    path = folder / "model.npz"
    sim = default_sim_profile()
    metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
    data = load_dataset(ROOT / "tests" / "data" / "hand_irregular_seed0_20s.limb")
    RigidMap().fit(data.quaternions).save(path, metadata=metadata)
    return path


def run(model: Path, rate: float, seconds: float, folder: Path) -> dict[str, float]:
    """One teleop session steered by a client sending ``rate`` msg/s; the loop's figures."""
    from limbctl.jobs import TeleopOptions, run_teleop
    from limbctl.live import ViewOptions, open_view

    telemetry = folder / f"telemetry-{rate:g}.jsonl"
    # the client starts once the loop runs and stops before the session's end
    options = TeleopOptions(
        model=model, source="page", telemetry=telemetry, quiet=True, duration=seconds + 4.0
    )
    result: dict[str, object] = {}
    with open_view(ViewOptions(enabled=True, port=0), lambda _: None) as live:

        def drive() -> None:
            while not telemetry.exists() or telemetry.stat().st_size == 0:
                time.sleep(0.05)  # the loop has not run its first cycle yet
            out = subprocess.run(
                [sys.executable, __file__, "--client", live.control_url, str(rate), str(seconds)],
                capture_output=True,
                text=True,
                check=True,
            )
            result.update(json.loads(out.stdout))

        driver = threading.Thread(target=drive)
        driver.start()
        run_teleop(options, view=live)
        driver.join()
    rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
    # the cycles while the client sent: from its first command to 1 s before the session's end
    t0 = next(row["t"] for row in rows if row["cmd"] is not None)
    window = [row for row in rows if t0 <= row["t"] <= t0 + seconds - 1.0]
    span = window[-1]["t"] - window[0]["t"]
    cycle_ms = np.array([row["cycle_ms"] for row in window])
    return {
        "cycles": len(window),
        "rate_hz": (len(window) - 1) / span,
        "p50_ms": float(np.percentile(cycle_ms, 50)),
        "p99_ms": float(np.percentile(cycle_ms, 99)),
        "sent_per_s": result["sent"] / result["seconds"],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--flood", type=float, default=10_000.0, help="flood rate, msg/s")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--client", nargs=3, metavar=("URL", "RATE", "SECONDS"))
    args = parser.parse_args()
    if args.client:
        client(args.client[0], float(args.client[1]), float(args.client[2]))
        return
    lines = [
        "| run | client | sent (msg/s) | cycles | loop rate (Hz) | cycle p50 (ms) | cycle p99 (ms) "
        "| flood / page rate |",
        "| --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    ratios = []
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        model = model_file(folder)
        for repeat in range(1, args.repeats + 1):
            page = run(model, PAGE_HZ, args.seconds, folder)
            flood = run(model, args.flood, args.seconds, folder)
            ratios.append(flood["rate_hz"] / page["rate_hz"])
            for label, figures, ratio in (("page", page, ""), ("flood", flood, ratios[-1])):
                lines.append(
                    f"| {repeat} | {label} | {figures['sent_per_s']:.0f} | {figures['cycles']} | "
                    f"{figures['rate_hz']:.1f} | {figures['p50_ms']:.2f} | {figures['p99_ms']:.2f} "
                    f"| {'' if ratio == '' else f'{ratio:.3f}'} |"
                )
            print("\n".join(lines[-2:]), flush=True)
    table = "\n".join(lines)
    print(table)
    print(f"lowest flood / page ratio: {min(ratios):.3f}")
    if args.out:
        args.out.write_text(
            "# Steering page: the loop's rate under a message flood\n\n"
            f"`python benchmarks/bench_page.py --seconds {args.seconds:g} --repeats "
            f"{args.repeats} --out {args.out}` (2-core machine shared with other work).\n\n"
            f"`limbctl teleop --source page` at 200 Hz on the simulator; a client process holds "
            f"control and sends at the page's {PAGE_HZ:g} Hz, then floods at {args.flood:g} "
            f"msg/s, {args.seconds:g} s each, in turn.\n\n"
            f"{table}\n\nLowest flood / page loop rate: {min(ratios):.3f}.\n"
        )


if __name__ == "__main__":
    main()
