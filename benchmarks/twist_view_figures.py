"""Screenshots of the live view of a three-servo rig in headless Chromium (docs/figures/...).

Run: ``PYTHONPATH=. .venv/bin/python benchmarks/twist_view_figures.py`` (about two minutes on
the simulator).

``view_twist_record.png``: ``limbctl record --rig sim3`` on the embedded simulator, whose scripted
hand teaches ``limbctl/data/demo_region3.yaml`` (a swing outline with a twist band over it) for
``--seconds``; the page, captured at its end, shows the twist taught so far by place under the swing
plane and the twist gauge of the present pose.

``view_twist_teleop.png``: a ``RigidMap(twist=True)`` trained on that recording gates
``limbctl teleop --rig sim3`` replaying the demo's sweep far outside in swing and twist
(:func:`limbctl.eval.twist_demo.write_twist_stream`); the page is captured ``--teleop-seconds``
into the sweep: the learned band over the swing plane and the gauge of the present twist against
the band at the present direction, with the twist last written.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.view.browser (headless Chromium, test helper)

from calib.profile import default_sim_profile  # noqa: E402
from limbctl.envelope import RigidMap  # noqa: E402
from limbctl.eval.twist_demo import write_twist_stream  # noqa: E402
from limbctl.jobs import Connection, RecordOptions, TeleopOptions, run_record, run_teleop  # noqa: E402
from limbctl.live import ViewOptions, open_view  # noqa: E402
from limbctl.teach.dataset import load_dataset  # noqa: E402
from tests.view.browser import chromium, text_of, wait_for  # noqa: E402

FIGURES = ROOT / "docs" / "figures"
#: The page's size (px): tall enough for the swing plane and the twist panel under it.
WINDOW = (1300, 1040)


def page_size(browser) -> None:
    """Make the captured page :data:`WINDOW` (a headless window's screenshot is its viewport)."""
    width, height = WINDOW
    metrics = {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}
    browser.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", metrics)


def record_figure(out: Path, data: Path, seconds: float, seed: int) -> None:
    """Screenshot of the page at the end of a ``seconds`` record on the three-servo simulator
    (the view stays up, showing the recording's last state, until the job's view is closed)."""
    with open_view(ViewOptions(enabled=True, port=0), print) as live, chromium() as browser:
        page_size(browser)
        browser.get(live.url)
        options = RecordOptions(
            out=data, duration=seconds, connection=Connection(seed=seed, rig=Path("sim3"))
        )
        run_record(options, view=live)
        count = str(len(load_dataset(data)))
        wait_for(browser, lambda d: text_of(d, "sample-count") == count, "not the last state")
        wait_for(browser, lambda d: "fitted on" in text_of(d, "region-note"), "no region")
        wait_for(browser, lambda d: "deg" in text_of(d, "twist-now"), "no twist gauge")
        browser.save_screenshot(str(out))
    print(f"wrote {out}")


def teleop_figure(out: Path, model: Path, folder: Path, seconds: float) -> None:
    """Screenshot of the page ``seconds`` into the demo's twist sweep through the gate."""
    commands = folder / "commands.jsonl"
    write_twist_stream(commands)
    options = TeleopOptions(
        model=model,
        source=f"replay:{commands}",
        quiet=True,
        connection=Connection(rig=Path("sim3")),
    )
    with open_view(ViewOptions(enabled=True, port=0), print) as live, chromium() as browser:
        page_size(browser)
        browser.get(live.url)

        def capture() -> None:
            try:
                wait_for(browser, lambda d: text_of(d, "cycles") not in ("", "-"), "no teleop")
                cycles = 200 * seconds  # the loop's 200 Hz
                wait_for(
                    browser,
                    lambda d: int(text_of(d, "cycles")) >= cycles,
                    "the sweep did not get that far",
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=40.0, help="teaching time")
    parser.add_argument("--teleop-seconds", type=float, default=3.4, help="into the sweep")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=FIGURES)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        data, model = folder / "teach.limb", folder / "model.npz"
        record_figure(args.out / "view_twist_record.png", data, args.seconds, args.seed)
        sim3 = default_sim_profile("sim3")
        metadata = {"rig": sim3.name, "calibration": sim3.calibration.to_dict()}
        RigidMap(twist=True).fit(load_dataset(data).quaternions).save(model, metadata=metadata)
        teleop_figure(args.out / "view_twist_teleop.png", model, folder, args.teleop_seconds)


if __name__ == "__main__":
    main()
