"""The recorder's sample rate with the live view off and on (docs/bench_view.md).

Run: ``.venv/bin/python benchmarks/bench_view.py --seconds 30,60 --out docs/bench_view.md``

Each run records from the embedded simulator's scripted hand at 100 Hz for each length of
``--seconds``:

- ``off``: the recorder reads the rig directly;
- ``on``: the recorder reads through the view's pose tap, the scene feeder refits the region in
  its own process (fits back to back), the server runs, and a headless Chromium watches.

Reported: samples per second, and the gaps between consecutive samples (median, p99, max), from
the recorded file's own timestamps; the fits drawn, the intervals between the region's redraws
once the first region is drawn (median, max), and each fit's own time in the fit process (median,
max; on idle CPU only, so waits for the CPU count).

Then ``limbctl teleop`` at 200 Hz on a replayed sweep (``--teleop-seconds``), view off and on
(watched by Chromium): cycles per second and cycle time (p50, p99) from its telemetry.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.view.browser (headless Chromium, test helper)

from calib.profile import default_sim_profile  # noqa: E402
from limbctl.envelope import RigidMap  # noqa: E402
from limbctl.jobs import TeleopOptions, run_teleop  # noqa: E402
from limbctl.live import ViewOptions, open_view, rig_limits  # noqa: E402
from limbctl.session import demo_region_path, open_rig  # noqa: E402
from limbctl.teach.dataset import DatasetWriter, load_dataset  # noqa: E402
from limbctl.teach.record import record  # noqa: E402
from limbctl.view import Board, ViewServer  # noqa: E402
from limbctl.view.feed import PoseTap, SceneFeeder  # noqa: E402
from tests.view.browser import chromium, text_of, wait_for  # noqa: E402

#: The teleop runs, in turn: (name, (view served, Chromium watching)).
TELEOP_MODES = (("off", (False, False)), ("on", (True, False)), ("on, watched", (True, True)))
#: The runs: name -> (view served and watched, region refitted).
MODES = {"off": (False, False), "on, no refit": (True, False), "on": (True, True)}


def run(view: bool, refit: bool, seconds: float, seed: int) -> dict[str, float]:
    """Record ``seconds`` with the view on or off; the rate and sample gaps measured."""
    with tempfile.TemporaryDirectory() as folder, contextlib.ExitStack() as stack:
        out = Path(folder) / "teach.limb"
        if view:
            # the browser first, as a person opens the page before teaching
            board = Board()
            server = stack.enter_context(ViewServer(board, port=0))
            browser = stack.enter_context(chromium())
            browser.get(server.url)
        session = stack.enter_context(open_rig(hand=demo_region_path(), seed=seed))
        writer = stack.enter_context(DatasetWriter(out, rig=session.profile.name))
        limb = session.rig
        fits = 0
        redraws_s: list[float] = []
        fit_s: list[float] = []
        if view:
            limb = PoseTap(session.rig, board, "record")
            limits = rig_limits(session.profile)
            feeder = stack.enter_context(SceneFeeder(board, limb.samples, limits, fit=refit))
        summary = record(limb, writer, 100.0, seconds, threading.Event())
        if view:
            wait_for(browser, lambda d: text_of(d, "sample-count") == str(summary.samples), "")
            fits = feeder.fits_done
            redraws_s = list(feeder.fit_times)
            fit_s = list(feeder.fit_seconds)
        writer.close()
        data = load_dataset(out)
    gaps_ms = np.diff(data.t) * 1000.0
    return {
        "samples": len(data),
        "rate_hz": (len(data) - 1) / (data.t[-1] - data.t[0]),
        "gap_median_ms": float(np.median(gaps_ms)),
        "gap_p99_ms": float(np.percentile(gaps_ms, 99)),
        "gap_max_ms": float(gaps_ms.max()),
        "fits": fits,
        # the region's redraw intervals once the first region is drawn
        "redraw_median_s": float(np.median(np.diff(redraws_s))) if len(redraws_s) > 1 else math.nan,
        "redraw_max_s": float(np.max(np.diff(redraws_s))) if len(redraws_s) > 1 else math.nan,
        # each fit's own time in the fit process (waits for CPU included)
        "fit_median_s": float(np.median(fit_s)) if fit_s else math.nan,
        "fit_max_s": float(np.max(fit_s)) if fit_s else math.nan,
    }


def teleop_run(
    view: bool, browser: bool, model: Path, seconds: float, folder: Path
) -> dict[str, float]:
    """``run_teleop`` at 200 Hz on a replayed sweep, the view off or on (watched by Chromium or
    not); rates from telemetry."""
    commands = folder / "sweep.jsonl"
    with open(commands, "w", encoding="utf-8") as fh:
        for i in range(int(seconds * 50)):
            t = i / 50.0
            phase = 2.0 * math.pi * t / 8.0
            pan, tilt = 20.0 + 45.0 * math.cos(phase), 20.0 + 45.0 * math.sin(phase)
            fh.write(json.dumps({"t": t, "pan": pan, "tilt": tilt}) + "\n")
    telemetry = folder / f"telemetry_{view}.jsonl"
    options = TeleopOptions(
        model=model, source=f"replay:{commands}", telemetry=telemetry, quiet=True
    )
    with contextlib.ExitStack() as stack:
        live = stack.enter_context(open_view(ViewOptions(enabled=view, port=0), print))
        if browser:
            stack.enter_context(chromium()).get(live.url)
        run_teleop(options, view=live)
    rows = [json.loads(line) for line in telemetry.read_text().splitlines()]
    cycle_ms = np.array([row["cycle_ms"] for row in rows])
    return {
        "cycles": len(rows),
        "rate_hz": (len(rows) - 1) / (rows[-1]["t"] - rows[0]["t"]),
        "p50": float(np.median(cycle_ms)),
        "p99": float(np.percentile(cycle_ms, 99)),
    }


def teleop_table(seconds: float) -> str:
    rows = []
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        model = folder / "model.npz"
        data = load_dataset(ROOT / "tests" / "data" / "hand_irregular_seed0_20s.limb")
        sim = default_sim_profile()
        metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
        RigidMap().fit(data.quaternions).save(model, metadata=metadata)
        for mode, (view, browser) in TELEOP_MODES * 2:
            result = teleop_run(view, browser, model, seconds, folder)
            rows.append(
                f"| {mode} | {result['cycles']} | {result['rate_hz']:.1f} | "
                f"{result['p50']:.2f} | {result['p99']:.2f} |"
            )
            print(rows[-1], flush=True)
    return "\n".join(
        [
            f"Teleop at 200 Hz, a replayed sweep leaving the region, {seconds:g} s each, "
            "in turn (watched: a headless Chromium on the same machine shows the page):",
            "",
            "| view | cycles | rate (Hz) | cycle p50 (ms) | cycle p99 (ms) |",
            "| --- | --- | --- | --- | --- |",
            *rows,
        ]
    )


def recorder_table(lengths_s: list[float], seed: int) -> str:
    """The recorder's rows: each mode for each teaching length."""
    rows = []
    for seconds in lengths_s:
        for mode, (view, refit) in MODES.items():
            result = run(view, refit, seconds, seed)
            rows.append(
                f"| {seconds:g} s | {mode} | {result['samples']} | {result['rate_hz']:.2f} | "
                f"{result['gap_median_ms']:.2f} | {result['gap_p99_ms']:.2f} | "
                f"{result['gap_max_ms']:.2f} | {result['fits']} | "
                f"{result['redraw_median_s']:.2f} | {result['redraw_max_s']:.2f} | "
                f"{result['fit_median_s']:.2f} | {result['fit_max_s']:.2f} |"
            )
            print(rows[-1], flush=True)
    return "\n".join(
        [
            f"Recorder at 100 Hz on the simulator's scripted hand, seed {seed}.",
            "",
            "| teaching | view | samples | rate (Hz) | gap median (ms) | gap p99 (ms) "
            "| gap max (ms) | fits | region redraw median (s) | region redraw max (s) "
            "| fit median (s) | fit max (s) |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
            *rows,
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--seconds",
        default="30",
        help="teaching lengths to record, comma-separated (s; default 30)",
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--teleop-seconds", type=float, default=15.0, help="each teleop run (s); 0 skips them"
    )
    parser.add_argument("--out", type=Path, default=None, help="write the table here (markdown)")
    args = parser.parse_args()
    try:
        lengths = [float(x) for x in args.seconds.split(",")]
    except ValueError:
        parser.error(
            f"--seconds: need lengths in seconds separated by commas, got {args.seconds!r}"
        )
    table = recorder_table(lengths, args.seed)
    if args.teleop_seconds > 0:
        table += "\n\n" + teleop_table(args.teleop_seconds)
    if args.out is not None:
        command = " ".join(["python", "benchmarks/bench_view.py", *sys.argv[1:]])
        args.out.write_text(
            "# Live view: the recorder's rate\n\n"
            f"`{command}` (2-core machine shared with other work).\n\n" + table + "\n"
        )
    print(table)


if __name__ == "__main__":
    main()
