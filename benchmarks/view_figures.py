"""Screenshots of the live view in headless Chromium (docs/figures/view_record.png, ...).

Run: ``.venv/bin/python benchmarks/view_figures.py`` (about a minute on the simulator).

``record``: the embedded simulator's scripted hand teaches for ``--seconds`` while the view's
pose tap and scene feeder publish; the page is captured once the region has been fitted on at least
three quarters of that teaching.

``teleop``: a Rigid Map trained on that recording gates a sweep sent over UDP that leaves the
region; the page is captured while the gate corrects the command onto the region's edge, then
the job is ended as Ctrl-C would.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.view.browser (headless Chromium, test helper)

from calib.profile import default_sim_profile  # noqa: E402
from limbctl.demo import DEMO_APPROACH_DEG_S  # noqa: E402
from limbctl.envelope import RigidMap  # noqa: E402
from limbctl.jobs import TeleopOptions, run_teleop  # noqa: E402
from limbctl.live import LiveView, ViewOptions, open_view  # noqa: E402
from limbctl.session import demo_region_path, open_rig  # noqa: E402
from limbctl.teach.dataset import DatasetWriter, load_dataset  # noqa: E402
from limbctl.teach.record import record  # noqa: E402
from limbctl.view import Board, ViewServer  # noqa: E402
from tests.view.browser import chromium, text_of, wait_for  # noqa: E402

FIGURES = ROOT / "docs" / "figures"


def record_figure(out: Path, data: Path, seconds: float, seed: int) -> None:
    """Screenshot of the page during a record on the simulator (the samples go to ``data``)."""
    board = Board()
    with (
        ViewServer(board, port=0) as server,
        chromium() as browser,
        open_rig(hand=demo_region_path(), seed=seed) as session,
        DatasetWriter(data, rig=session.profile.name) as writer,
    ):
        browser.get(server.url)
        stop = threading.Event()
        with LiveView(board, server.url).teaching(session.rig, session.profile) as taught:
            tap, feeder = taught.limb, taught.feeder
            recorder = threading.Thread(
                target=record,
                args=(tap, writer, 100.0, None, stop),
                kwargs={"on_guidance": taught.on_guidance},
            )
            recorder.start()
            try:
                # the chosen length of teaching (samples at 100 Hz), and a region fitted on at
                # least 3/4 of it (a fit takes seconds: the region lags the samples)
                wait_for(
                    browser,
                    lambda d: tap.count >= 100 * seconds and feeder.latest.samples >= 75 * seconds,
                    "the region did not catch up with the teaching",
                    timeout=600,
                )
                wait_for(browser, lambda d: "fitted on" in text_of(d, "region-note"), "no region")
                browser.save_screenshot(str(out))
            finally:
                stop.set()
                recorder.join()
    print(f"wrote {out}")


def teleop_figure(out: Path, model: Path) -> None:
    """Screenshot of the page while ``limbctl teleop`` gates a sweep that leaves the region."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    # nobody is there to move the limb in by hand if it rests outside the region after the
    # teaching: the servos drive it in slowly, as in the demo
    options = TeleopOptions(
        model=model,
        source=f"udp://127.0.0.1:{port}",
        quiet=True,
        duration=300.0,
        approach=DEMO_APPROACH_DEG_S,
    )
    with (
        open_view(ViewOptions(enabled=True, port=0), print) as live,
        chromium() as browser,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender,
    ):
        browser.get(live.url)
        started = time.monotonic()

        def sweep(driver) -> bool:
            # a circle of 45 deg around (20, 20) deg, once every 8 s: it leaves the region
            phase = 2.0 * math.pi * (time.monotonic() - started) / 8.0
            command = {"pan": 20.0 + 45.0 * math.cos(phase), "tilt": 20.0 + 45.0 * math.sin(phase)}
            sender.sendto(json.dumps(command).encode(), ("127.0.0.1", port))
            return (
                time.monotonic() - started > 5.0
                and text_of(driver, "outcome").startswith("corrected")
                and float(text_of(driver, "rate").split()[0]) > 0.0
            )

        def capture() -> None:
            try:
                wait_for(browser, sweep, "the gate never corrected the sweep", timeout=120)
                browser.save_screenshot(str(out))
            finally:
                if text_of(browser, "cycles") not in ("", "-"):
                    os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C ends the job

        watcher = threading.Thread(target=capture)
        watcher.start()
        run_teleop(options, view=live)
        watcher.join()
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=25.0, help="teaching time before capture")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=FIGURES)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        data, model = Path(folder) / "teach.limb", Path(folder) / "model.npz"
        record_figure(args.out / "view_record.png", data, args.seconds, args.seed)
        sim = default_sim_profile()
        metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
        RigidMap().fit(load_dataset(data).quaternions).save(model, metadata=metadata)
        teleop_figure(args.out / "view_teleop.png", model)


if __name__ == "__main__":
    main()
