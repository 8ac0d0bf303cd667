"""Promise 5, reduced: the soak of benchmarks/soak.py at CI size (full run: docs/soak.md)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

from tests.safety.support import bean_model

SOAK_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "soak.py"


@pytest.fixture(scope="module")
def soak():
    spec = importlib.util.spec_from_file_location("soak", SOAK_PATH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def test_the_compressed_and_the_live_soak_keep_every_promise(soak):
    result = soak.compressed_soak(30_000, seed=3, model=bean_model())
    assert result.cycles == 30_000
    # every segment kind came up, so each promise was exercised
    assert result.segments >= len(soak.SEGMENTS)
    assert result.commands > 0 and result.refused > 0 and result.fault_cycles > 0
    assert result.goals_checked > 1000 and result.hold_checks > 1000
    assert result.unsafe_goals == 0 and result.limit_violations == 0
    assert result.worst_excursion_deg <= result.tolerance_deg
    assert result.held_drift_ticks == 0
    # no growth in memory once warm (allocator noise is far below a megabyte per 30k cycles)
    assert result.rss_growth_mb < 4.0
    # the live soak on the simulator, with faults
    result = soak.live_soak(4.0, seed=5, model=bean_model())
    assert result.ended_by == "end of input"
    assert result.goals_logged > 200 and result.faults_injected > 0
    assert result.limit_violations == 0
    assert result.worst_excursion_deg <= soak.ROUNDING_DEG + 0.01
    assert result.held_error_ticks <= 3
