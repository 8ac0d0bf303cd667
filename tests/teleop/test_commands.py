import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from limbctl.errors import InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction
from limbctl.teleop.commands import MAX_LINE_BYTES, command_from_pan_tilt, parse_command


def test_pan_tilt_line():
    c = parse_command('{"pan": 30, "tilt": -10}\n')
    expected = pan_tilt_to_direction(math.radians(30), math.radians(-10))
    np.testing.assert_allclose(c.direction, expected, atol=1e-12)
    np.testing.assert_allclose(limb_direction(c.q), expected, atol=1e-12)
    assert c.q[1] == 0.0 and c.q[0] >= 0


def test_dir_and_q_lines_and_time():
    c = parse_command(b'{"dir": [0, 2, 0], "t": 1.5}')
    np.testing.assert_allclose(c.direction, [0, 1, 0], atol=1e-15)
    assert c.t == 1.5
    # 90 deg about +z points the limb along +y
    s = math.sqrt(0.5)
    c2 = parse_command(f'{{"q": [{s}, 0, 0, {s}]}}')
    np.testing.assert_allclose(c2.direction, [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize(
    "line, reason",
    [
        ('{"pan": NaN, "tilt": 0}', "NaN"),
        ('{"pan": Infinity, "tilt": 0}', "Infinity"),
        ('{"pan": 1e400, "tilt": 0}', "finite"),
        ('{"pan": 10}', "together"),
        ('{"pan": 200, "tilt": 0}', "outside"),
        ('{"pan": 0, "tilt": -91}', "outside"),
        ('{"pan": "10", "tilt": 0}', "number"),
        ('{"pan": true, "tilt": 0}', "number"),
        ('{"dir": [0, 0, 0]}', "length"),
        ('{"dir": [1, 0]}', "list of 3"),
        ('{"q": [1, 1, 0, 0]}', "norm"),
        ('{"q": [1, 0, 0, 0], "pan": 0, "tilt": 0}', "exactly one"),
        ('{"pna": 0, "tilt": 0}', "unknown key"),
        ("[1, 2, 3]", "JSON object"),
        ('{"pan": 0, "tilt": ', "malformed"),
        (b"\xff\xfe", "UTF-8"),
        ("{}", "exactly one"),
        ('{"dir": [1e300, 0, 0]}', "out of range"),
    ],
)
def test_bad_lines_are_refused_with_a_reason(line, reason):
    with pytest.raises(InvalidInputError, match=reason):
        parse_command(line)


def test_oversize_line_refused():
    line = '{"pan": 0, "tilt": 0' + " " * MAX_LINE_BYTES + "}"
    with pytest.raises(InvalidInputError, match="longer"):
        parse_command(line)


@given(st.text(max_size=200))
def test_arbitrary_text_never_escapes_as_a_non_finite_command(text):
    try:
        c = parse_command(text)
    except InvalidInputError:
        return
    assert np.isfinite(c.q).all() and abs(np.linalg.norm(c.q) - 1) < 1e-9


@given(st.floats(-180.0, 180.0, allow_nan=False), st.floats(-90.0, 90.0, allow_nan=False))
def test_commands_built_from_numbers_equal_the_parsed_line(pan, tilt):
    built = command_from_pan_tilt(pan, tilt)
    parsed = parse_command(f'{{"pan": {pan!r}, "tilt": {tilt!r}}}')
    np.testing.assert_array_equal(built.q, parsed.q)
    np.testing.assert_array_equal(built.direction, parsed.direction)


@pytest.mark.parametrize(
    ("pan", "tilt", "reason"),
    [(float("nan"), 0.0, "finite"), (181.0, 0.0, "outside"), (0.0, -90.5, "outside")],
)
def test_commands_built_from_numbers_are_checked_like_lines(pan, tilt, reason):
    with pytest.raises(InvalidInputError, match=reason):
        command_from_pan_tilt(pan, tilt)
