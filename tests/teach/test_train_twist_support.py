"""train lists the stretches of the twist band its teaching could not support."""

from limbctl.envelope import RigidMap
from limbctl.teach.train import summarize
from tests.region.test_twist_evidence import DIP_AT, dipped_teaching


def test_train_names_the_twist_stop_the_teaching_never_reached():
    _, q = dipped_teaching()
    summary = summarize(RigidMap(twist=True, seed=0).fit(q), q)
    assert summary.unsupported_twist, "the dip's stop was never taught, yet nothing is listed"
    text = "\n".join(summary.lines())
    assert "twist unsupported" in text
    first = next(w for w in summary.unsupported_twist if "upper (positive) twist stop" in w)
    pan = float(first.split("near pan ")[1].split(",")[0])
    tilt = float(first.split("tilt ")[1].split(" ")[0])
    assert abs(pan - DIP_AT[0]) < 16 and abs(tilt - DIP_AT[1]) < 16
    assert f"  {first}" in summary.lines()
