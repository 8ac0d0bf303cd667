"""Screenshots of the live view in headless Chromium (docs/figures/view_record.png, ...).

Run: ``.venv/bin/python benchmarks/view_figures.py`` (about a minute on the simulator).

``record``: the embedded simulator's scripted hand teaches for ``--seconds`` while the view's
pose tap and scene feeder publish; the page is captured once the region has been fitted on at least
three quarters of that teaching.

``teleop``: a Rigid Map trained on that recording gates ``limbctl teleop --source page``; the
page, opened with the session's key, is dragged from inside the region out through its top edge
and held there; it is captured once the gate says which way is blocked, then the job is ended as
Ctrl-C would.

``keyboard``: ``limbctl teleop --source keyboard`` in a 160 x 40 tmux pane with the same model:
the key guide, a smaller step, a few presses, a held key up to the edge, a hold and a release;
the guide and the status line after each step are kept (docs/figures/keyboard_session.txt).
``--keyboard-only MODEL`` makes only this capture, with a model already trained.
"""

from __future__ import annotations

import argparse
import os
import signal
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
from tests.teleop.tmux import tmux_pane  # noqa: E402
from tests.view.browser import chromium, drag_on_plane, text_of, wait_for  # noqa: E402

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
    """Screenshot of the page steering ``limbctl teleop --source page`` out through the edge."""
    # nobody is there to move the limb in by hand if it rests outside the region after the
    # teaching: the servos drive it in slowly, as in the demo
    options = TeleopOptions(
        model=model, source="page", quiet=True, duration=300.0, approach=DEMO_APPROACH_DEG_S
    )
    with open_view(ViewOptions(enabled=True, port=0), print) as live, chromium() as browser:

        def capture() -> None:
            try:
                browser.get(live.control_url)
                wait_for(browser, lambda d: "you steer" in text_of(d, "control"), "no control")
                wait_for(browser, lambda d: text_of(d, "cycles") not in ("", "-"), "no teleop")
                # from the region's middle up through its top edge, then along it to the right
                wait_for(browser, lambda d: text_of(d, "pose") != "-", "no pose read")
                written = [float(v) for v in text_of(browser, "pose").split(",")]
                top = max(
                    p[1]
                    for p in browser.execute_script(
                        "return window.limbview.state.scene.loops[0].points;"
                    )
                )
                path = [written, (written[0], top - 5.0), (written[0] + 10.0, top + 15.0)]
                path.append((written[0] + 35.0, top + 20.0))
                drag_on_plane(browser, path, pause_s=0.4)
                wait_for(
                    browser,
                    lambda d: (
                        "blocked, sliding" in text_of(d, "words")
                        or "blocked, holding" in text_of(d, "words")
                    ),
                    "the gate never said what blocks the limb",
                    timeout=120,
                )
                browser.save_screenshot(str(out))
            finally:
                os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C ends the job

        watcher = threading.Thread(target=capture)
        watcher.start()
        run_teleop(options, view=live)
        watcher.join()
    print(f"wrote {out}")


def keyboard_capture(out: Path, model: Path) -> None:
    """The text of a keyboard session in a 160 x 40 terminal: the guide, then the status line
    as it stood after each thing the person did, then the summary after q."""
    command = (
        f"{sys.executable} -m limbctl teleop --model {model} --source keyboard --no-view "
        f"--approach {DEMO_APPROACH_DEG_S}"
    )
    shots: list[str] = []
    with tmux_pane(command, env={"PYTHONPATH": str(ROOT)}) as pane:
        pane.wait_for(lambda t: "written pan" in pane.status(), "no status line", timeout=120)
        guide = pane.text().split("\n    ")[0].rstrip()

        def shot(did: str, shows: str) -> None:
            pane.wait_for(lambda t: shows in pane.status(), f"after {did}: no {shows!r}")
            shots.append(f"[{did}]\n{pane.status().strip()}")

        pane.keys("c")
        shot("c: back to the region's centre", "inside: following")
        pane.keys("-")
        shot("-: a smaller step", "step 1 deg")
        for _ in range(3):
            pane.keys("Left")
            time.sleep(0.3)  # three separate presses, as a person makes them
        time.sleep(0.6)  # one status refresh later
        shot("left, left, left: 1 deg each", "inside: following")
        pane.keys("+", "+")
        started = time.monotonic()
        pane.keys("Up")
        time.sleep(0.5)  # the terminal's repeat delay, then its repeats at 30 Hz
        while time.monotonic() - started < 3.0:
            pane.keys("Up")
            time.sleep(1 / 30)
        shot("+, +, then up held for 3 s: 50 deg/s", "blocked")
        pane.keys("Space")
        shot("space: hold", "holding the last safe pose")
        pane.keys("Space", "Down", "Down")
        time.sleep(0.6)
        shot("space: release, then down, down", "inside")
        pane.keys("q")
        pane.wait_for(lambda t: "EXIT" in t, "the session did not end")
        summary = pane.text(history=True).rstrip().split("\n")
        ended = next(i for i, line in enumerate(summary) if line.startswith(("parked", "ended")))
    text = "\n\n".join([guide, *shots, "[q: quit]\n" + "\n".join(summary[ended:])]) + "\n"
    out.write_text("$ limbctl teleop --model model.npz --source keyboard\n" + text)
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=25.0, help="teaching time before capture")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=FIGURES)
    parser.add_argument("--keyboard-only", type=Path, metavar="MODEL", help="only the capture")
    args = parser.parse_args()
    if args.keyboard_only:
        keyboard_capture(args.out / "keyboard_session.txt", args.keyboard_only)
        return
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as folder:
        data, model = Path(folder) / "teach.limb", Path(folder) / "model.npz"
        record_figure(args.out / "view_record.png", data, args.seconds, args.seed)
        sim = default_sim_profile()
        metadata = {"rig": sim.name, "calibration": sim.calibration.to_dict()}
        RigidMap().fit(load_dataset(data).quaternions).save(model, metadata=metadata)
        teleop_figure(args.out / "view_teleop.png", model)
        keyboard_capture(args.out / "keyboard_session.txt", model)


if __name__ == "__main__":
    main()
