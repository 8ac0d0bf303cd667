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
    # a 2000-sample teaching: coarser than the benchmark's 7500, still far nearer than the clamp
    assert row["learned_mean_deg"] < 1.5 and row["clamp_mean_deg"] > 4 * row["learned_mean_deg"]
    # an incomplete teaching: the evidence cap holds the band in and a deep command may move
    # (docs/bench_region_families.md)
    assert row["deep_unchanged"] >= 0.97 and row["within_1deg"] >= 0.97
    # a rerun resumes from the written table
    assert run_twist(tmp_path, "smoke") == headline
