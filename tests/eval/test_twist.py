"""The eval's twist experiment: the learned exact correction beats the engines' clamp."""

import csv

from limbctl.eval.twist import FIELDS, run_twist


def test_learned_exact_correction_beats_the_engines_clamp_on_the_true_region(tmp_path):
    headline = run_twist(tmp_path, "smoke")
    assert "engines' clamp" in headline[0]
    assert "learned correct()" in (tmp_path / "twist.md").read_text()
    with open(tmp_path / "twist.csv", newline="") as fh:
        (row,) = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    assert tuple(row) == FIELDS and row["seed"] == 0
    assert row["outside"] > 100
    # a 2000-sample teaching: coarser than the benchmark's 7500 (0.3 deg there), still far
    # nearer than the engines' two steps on the exact region
    assert row["learned_mean_deg"] < 1.5 and row["clamp_mean_deg"] > 4 * row["learned_mean_deg"]
    # the smoke's 2000-sample teaching is not one the guide calls complete (its band lists ~95
    # places the evidence cannot support): there the evidence cap holds the band in, containment
    # before coverage, and a deep command may be moved (1 of 77 at 2d23222; 99 % and more on
    # complete teachings: docs/bench_region_families.md)
    assert row["deep_unchanged"] >= 0.97 and row["within_1deg"] >= 0.97
    # a rerun resumes from the written table
    assert run_twist(tmp_path, "smoke") == headline
