"""The page source: the view's controller text goes through the same parser and refusals."""

from __future__ import annotations

import pytest

from limbctl.errors import ConfigError
from limbctl.geometry.gimbal import quat_to_pan_tilt
from limbctl.teleop.commands import Command
from limbctl.teleop.sources import PageSource, SourceContext, parse_source
from limbctl.view.control import ControlDesk


def test_the_controllers_lines_are_parsed_and_refused_like_any_others():
    desk = ControlDesk()
    page = object()
    desk.claim(page, "the page at 127.0.0.1:5000, since 12:00:00")
    with PageSource(desk.attach) as source:
        assert source.latest_only and source.explains
        # the reader thread attaches the source to the controller slot
        got: list[Command] = []
        while not got:
            desk.forward(page, '{"pan": 10.0, "tilt": 5.0}')
            got = source.poll(timeout=0.1)
        pan, tilt = quat_to_pan_tilt(got[-1].q)
        assert (float(pan), float(tilt)) == pytest.approx((0.174533, 0.0872665), abs=1e-6)
        desk.forward(page, "not json")
        desk.forward(page, '{"pan": "left"}')
        assert source.stats.rejected == 2 and source.poll() == []
        assert "127.0.0.1:5000" in source.describe()
    # closed: the slot no longer leads anywhere
    assert desk.forward(page, '{"pan": 1.0, "tilt": 1.0}') is False


def test_the_page_source_needs_the_view():
    spec = parse_source("page")
    with pytest.raises(ConfigError, match="--no-view"):
        spec.open(SourceContext())
    with pytest.raises(ConfigError, match="takes no argument"):
        parse_source("page:x").open(SourceContext(page=ControlDesk().attach))
