"""Screenshots of the live view in headless Chromium (docs/figures/view_record.png, ...).

Run: ``.venv/bin/python benchmarks/view_figures.py`` (about a minute on the simulator).

``record``: the embedded simulator's scripted hand teaches for ``--seconds`` while the view's
pose tap and scene feeder publish; the page is captured once the region fitted so far has been
drawn at least twice.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import threading
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # for tests.view.browser (headless Chromium, test helper)

from limbctl.session import demo_region_path, open_rig  # noqa: E402
from limbctl.teach.dataset import DatasetWriter  # noqa: E402
from limbctl.teach.record import record  # noqa: E402
from limbctl.view import Board, HardLimits, ViewServer  # noqa: E402
from limbctl.view.feed import PoseTap, SceneFeeder  # noqa: E402
from tests.view.browser import chromium, text_of, wait_for  # noqa: E402

FIGURES = ROOT / "docs" / "figures"


def limits_of(profile) -> HardLimits:
    return HardLimits(
        (profile.pan.min_deg, profile.pan.max_deg), (profile.tilt.min_deg, profile.tilt.max_deg)
    )


def record_figure(out: Path, seconds: float, seed: int) -> None:
    """Screenshot of the page during a record on the simulator."""
    board = Board()
    with (
        tempfile.TemporaryDirectory() as folder,
        ViewServer(board, port=0) as server,
        chromium() as browser,
        open_rig(hand=demo_region_path(), seed=seed) as session,
        DatasetWriter(Path(folder) / "teach.limb", rig=session.profile.name) as writer,
    ):
        tap = PoseTap(session.rig, board, "record", note="torque off: move the limb by hand")
        browser.get(server.url)
        stop = threading.Event()
        with SceneFeeder(board, tap.samples, limits_of(session.profile)) as feeder:
            recorder = threading.Thread(target=record, args=(tap, writer, 100.0, None, stop))
            recorder.start()
            try:
                with contextlib.suppress(Exception):
                    # wait for the chosen length of teaching, measured by samples at 100 Hz
                    wait_for(
                        browser,
                        lambda d: (
                            int(text_of(d, "sample-count")) >= 100 * seconds
                            and feeder.fits_done >= 2
                        ),
                        "",
                        timeout=seconds * 4 + 120,
                    )
                browser.save_screenshot(str(out))
            finally:
                stop.set()
                recorder.join()
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=25.0, help="teaching time before capture")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=FIGURES)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    record_figure(args.out / "view_record.png", args.seconds, args.seed)


if __name__ == "__main__":
    main()
