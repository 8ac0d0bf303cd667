"""The view's values: thinning, validation, JSON, and the board's versions."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from limbctl.view import Board, EdgeLoop, Live, PanTilt, Scene, TeleopStatus, thin_samples


def test_thinning_keeps_one_sample_per_cell_in_order_and_caps_the_count():
    rng = np.random.default_rng(0)
    # 10 000 samples in a 10 x 10 deg square: at most 20 x 20 cells of 0.5 deg
    samples = rng.uniform(0.0, 10.0, size=(10_000, 2))
    thinned = thin_samples(samples)
    assert 380 <= len(thinned) <= 400
    cells = {tuple(c) for c in np.floor(thinned / 0.5).astype(int)}
    assert len(cells) == len(thinned)
    order = [int(np.flatnonzero((samples == row).all(axis=1))[0]) for row in thinned]
    assert order == sorted(order)
    capped = thin_samples(rng.uniform(-90, 90, size=(50_000, 2)), limit=1000)
    assert 500 < len(capped) <= 1000
    assert thin_samples(np.zeros((0, 2))).shape == (0, 2)


def test_board_versions_count_publishes_and_snapshot_reads_both_parts_together():
    board = Board()
    assert board.snapshot().live is None and board.live is None and board.scene is None

    def publish(k: int) -> None:
        for i in range(1000):
            board.publish_live(Live(mode="record", pose=PanTilt(k, i)))

    threads = [threading.Thread(target=publish, args=(k,)) for k in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    board.publish_scene(Scene())
    snap = board.snapshot()
    assert snap.live_version == 4000 and snap.scene_version == 1
    assert snap.live.pose.tilt_deg == 999


def test_edge_loops_scenes_and_teleop_states_as_json():
    with pytest.raises(ValueError, match="3 vertices but 2 traced flags"):
        EdgeLoop([[0, 0], [1, 0], [0, 1]], [True, False])
    loop = EdgeLoop([[0, 0], [1, 0], [0, 1]], [1, 0, 1])
    assert loop.to_json() == {"points": [[0, 0], [1, 0], [0, 1]], "traced": [1, 0, 1]}
    scene = Scene(samples_deg=[[1.234, -5.678]], loops=(EdgeLoop([[0, 0], [1, 1]], [0, 1]),))
    as_json = scene.to_json()
    assert as_json["kind"] == "scene"
    assert as_json["samples"] == [[1.23, -5.68]]
    assert as_json["loops"][0]["traced"] == [0, 1]
    assert as_json["limits"] is None and as_json["guide"] == []
    # a teleop state carries the gate's words and the blocked sides
    words = "at the edge: up is blocked, holding there"
    command, written = PanTilt(0.0, 60.0), PanTilt(0.0, 30.0)
    status = TeleopStatus(command, written, "corrected", 199.96, 12, words, ("+tilt",))
    assert Live("teleop", teleop=status).to_json()["teleop"] == {
        "commanded": [0.0, 60.0],
        "written": [0.0, 30.0],
        "outcome": "corrected",
        "rate_hz": 200.0,
        "cycles": 12,
        "words": words,
        "blocked": ["+tilt"],
    }
