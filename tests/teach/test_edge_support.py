"""No READY TO TRAIN while the learned edge would bridge what the samples surround (issue 35,
finding 1), checked in a worker process on a hand's teaching of a notched ellipse."""

import os
from functools import partial

import numpy as np
import pytest

from limbctl.region import RegionParams, TaughtRegion
from limbctl.region import taught as taught_module
from limbctl.region.evidence import SETTLED_DEG, Stretch
from limbctl.teach import edge_support
from limbctl.teach.edge_support import EdgeSupport, unsupported_stretches
from limbctl.teach.guide import Guide
from limbctl.teach.record import RecordSummary
from tests.region.test_evidence import RATE_HZ, hand_teaching, notched_ellipse

#: The notched ellipse of tests/region/test_evidence.py (its first case) and where its notch is.
A, B, CENTRE, AT = 27.2, 23.4, (-5.7, 7.2), 273.0
NOTCH = (CENTRE[0] + A * np.cos(np.radians(AT)), CENTRE[1] + B * np.sin(np.radians(AT)))


def bridging_stretches(d: np.ndarray) -> tuple[Stretch, ...]:
    """The check with a region that bridges the notch (a coarse alpha shape, nothing carved):
    run in the worker, which imports it from this module."""
    taught_module.CARVE_ROUNDS = 0
    region = TaughtRegion(RegionParams(edge="supported", alpha_factor=4.0)).fit(d, lookup=False)
    return tuple(
        Stretch(s.pan_deg, s.tilt_deg, s.distance_deg, s.length_deg)
        for s in region.unsupported_edge
    )


@pytest.fixture(scope="module")
def taught():
    outline, _ = notched_ellipse(A, B, CENTRE, AT, width=9.0, depth=8.0)
    return hand_teaching(outline, seed=1)


def guide_of(d: np.ndarray, support: EdgeSupport | None) -> Guide:
    guide = Guide(support=support)
    pan, tilt = np.arctan2(d[:, 1], d[:, 0]), np.arcsin(np.clip(d[:, 2], -1.0, 1.0))
    for k, (p, t) in enumerate(zip(pan, tilt, strict=True)):
        guide.add(k / RATE_HZ, float(p), float(t))
    return guide


@pytest.fixture
def cached(monkeypatch):
    """As after the warm-up: the training's kernels in the cache, so the check may run."""
    monkeypatch.setattr(EdgeSupport, "possible", property(lambda self: True))


def test_a_bridged_notch_withholds_ready_named_and_while_recording_until_the_first_answer(
    taught, cached
):
    with EdgeSupport(bridging_stretches) as support:
        guide = guide_of(taught, support)
        first = guide.assess()  # the check has only been started
        assert not first.ready and first.checking, "ready before the check answered"
        assert "checking that the samples support the edge" in first.line()
        support._pending.result(timeout=120)  # the worker's answer
        later = guide.assess()
        assert not later.ready and later.unsupported and not later.checking
        guidance = guide_of(taught, support).assess(final=True)
    assert not guidance.ready and guidance.unsupported
    first = guidance.unsupported[0]
    assert abs(first.pan_deg - NOTCH[0]) < 8.0 and abs(first.tilt_deg - NOTCH[1]) < 10.0
    assert f"trace the edge near pan {first.pan_deg:+.0f}, tilt {first.tilt_deg:+.0f}" in (
        guidance.line()
    )
    summary = RecordSummary(guidance=guidance, edge_checked=True)
    assert any(line.startswith("edge unsupported") for line in summary.lines())


def test_the_default_fit_supports_its_edge_and_ready_stands(taught, cached):
    assert guide_of(taught, None).assess().ready, "not ready by coverage alone"
    d = np.array([[1.0, 0.0, 0.0]] * (edge_support.MIN_SAMPLES - 1))
    assert unsupported_stretches(d) == (), "too few samples were judged"
    assert unsupported_stretches(taught) == ()
    with EdgeSupport() as support:
        guidance = guide_of(taught, support).assess(final=True)
    assert guidance.ready and guidance.unsupported == () and support.stretches == ()


def test_without_cached_kernels_or_with_a_dying_worker_the_edge_is_left_unchecked(
    taught, monkeypatch
):
    monkeypatch.setattr(EdgeSupport, "possible", property(lambda self: False))
    with EdgeSupport(bridging_stretches) as support:
        guidance = guide_of(taught, support).assess(final=True)
        assert support._pool is None  # no worker was started
    assert guidance.ready and support.stretches is None
    summary = RecordSummary(guidance=guidance, edge_checked=False)
    assert any("not checked" in line for line in summary.lines())
    monkeypatch.setattr(EdgeSupport, "possible", property(lambda self: True))
    with EdgeSupport(dies) as support:  # as a worker that cannot start does
        guidance = guide_of(taught, support).assess(final=True)
    assert guidance.ready and support.stretches is None, "a dying worker spoilt the recording"


def dies(d: np.ndarray) -> tuple[Stretch, ...]:
    """A check whose worker dies."""
    os._exit(3)


#: A held stretch as deep as the guided teachings' last requests (docs/bench_guided_teaching.md:
#: 1.26-2.07 deg after the hand traced the stop again), and one of a bridged notch, deeper.
SHALLOW = Stretch(-12.0, 20.0, 1.8, 3.0, held=True)
DEEP = Stretch(-5.0, -15.0, SETTLED_DEG + 0.5, 6.0, held=True)


def found(stretches: tuple[Stretch, ...], d: np.ndarray) -> tuple[Stretch, ...]:
    """A check that finds ``stretches`` whatever the samples (bound with functools.partial)."""
    return stretches


def test_a_held_stretch_the_samples_stand_near_is_settled_and_ready_stands_saying_so(
    taught, cached
):
    assert SHALLOW.settled and not DEEP.settled
    assert not Stretch(0.0, 0.0, 1.8, 3.0).settled, "an unheld stretch was settled"
    with EdgeSupport(partial(found, (SHALLOW,))) as support:
        guidance = guide_of(taught, support).assess(final=True)
    assert guidance.ready and guidance.unsupported == () and guidance.settled == (SHALLOW,)
    assert "READY TO TRAIN (edge held at the samples in 1 places)" in guidance.line()
    lines = RecordSummary(guidance=guidance, edge_checked=True).lines()
    assert any(line.startswith("edge held") and "pan -12, tilt 20" in line for line in lines)
    assert not any(line.startswith("edge unsupported") for line in lines)
    with EdgeSupport(partial(found, (SHALLOW, DEEP))) as support:
        guidance = guide_of(taught, support).assess(final=True)
    assert not guidance.ready and guidance.unsupported == (DEEP,)
    assert "trace the edge near pan -5, tilt -15" in guidance.line()
