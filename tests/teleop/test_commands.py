import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from limbctl.errors import InvalidInputError
from limbctl.geometry.gimbal import pan_tilt_roll_to_quat, pan_tilt_to_direction
from limbctl.geometry.quat import limb_direction
from limbctl.geometry.twist import decompose
from limbctl.teleop.commands import MAX_LINE_BYTES, command_from_pan_tilt, parse_command


def test_pan_tilt_dir_and_q_lines_and_time():
    c = parse_command('{"pan": 30, "tilt": -10}\n')
    expected = pan_tilt_to_direction(math.radians(30), math.radians(-10))
    np.testing.assert_allclose(c.direction, expected, atol=1e-12)
    np.testing.assert_allclose(limb_direction(c.q), expected, atol=1e-12)
    assert c.q[1] == 0.0 and c.q[0] >= 0
    c = parse_command(b'{"dir": [0, 2, 0], "t": 1.5}')
    np.testing.assert_allclose(c.direction, [0, 1, 0], atol=1e-15)
    assert c.t == 1.5
    # 90 deg about +z points the limb along +y
    s = math.sqrt(0.5)
    c2 = parse_command(f'{{"q": [{s}, 0, 0, {s}]}}')
    np.testing.assert_allclose(c2.direction, [0, 1, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("line", "reason", "twist"),
    [
        ('{"pan": NaN, "tilt": 0}', "NaN", False),
        ('{"pan": Infinity, "tilt": 0}', "Infinity", False),
        ('{"pan": 1e400, "tilt": 0}', "finite", False),
        ('{"pan": 10}', "together", False),
        ('{"pan": 200, "tilt": 0}', "outside", False),
        ('{"pan": 0, "tilt": -91}', "outside", False),
        ('{"pan": "10", "tilt": 0}', "number", False),
        ('{"pan": true, "tilt": 0}', "number", False),
        ('{"dir": [0, 0, 0]}', "length", False),
        ('{"dir": [1, 0]}', "list of 3", False),
        ('{"q": [1, 1, 0, 0]}', "norm", False),
        ('{"q": [1, 0, 0, 0], "pan": 0, "tilt": 0}', "exactly one", False),
        ('{"pna": 0, "tilt": 0}', "unknown key", False),
        ("[1, 2, 3]", "JSON object", False),
        ('{"pan": 0, "tilt": ', "malformed", False),
        (b"\xff\xfe", "UTF-8", False),
        ("{}", "exactly one", False),
        ('{"dir": [1e300, 0, 0]}', "out of range", False),
        ('{"pan": 0, "tilt": 0' + " " * MAX_LINE_BYTES + "}", "longer", False),
        # lines that carry twist, on a two-servo rig
        ('{"pan": 10, "tilt": 5, "roll": 20}', "two servos \\(no roll joint\\)", False),
        ('{"dir": [1, 0, 0], "twist": 30}', "two servos \\(no roll joint\\)", False),
        # three-servo rigs: lines that carry twist
        ('{"pan": 10, "tilt": 5, "roll": 200}', "roll 200.0 deg is outside", True),
        ('{"dir": [1, 0, 0], "twist": NaN}', "not a valid number", True),
        ('{"q": [1, 0, 0, 0], "twist": 10}', "twist goes with dir", True),
        ('{"dir": [1, 0, 0], "roll": 10}', "roll goes with pan and tilt", True),
        ('{"pan": 1, "tilt": 2, "spin": 3}', "unknown key", True),
    ],
)
def test_bad_lines_are_refused_with_a_reason(line, reason, twist):
    with pytest.raises(InvalidInputError, match=reason):
        parse_command(line, twist=twist)


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


def test_three_servo_forms_keep_their_twist():
    c = parse_command('{"pan": 30, "tilt": 30, "roll": 20}', twist=True)
    np.testing.assert_allclose(
        c.q, pan_tilt_roll_to_quat(math.radians(30), math.radians(30), math.radians(20)), atol=1e-15
    )
    # the twist is roll + 2 atan(tan(pan/2) tan(tilt/2)) = 20 + 8.2 deg
    assert math.degrees(float(decompose(c.q)[1])) == pytest.approx(28.2, abs=0.05)
    c = parse_command('{"dir": [1, 1, 0], "twist": -40}', twist=True)
    d, tau = decompose(c.q)
    np.testing.assert_allclose(d, [2**-0.5, 2**-0.5, 0], atol=1e-12)
    assert math.degrees(float(tau)) == pytest.approx(-40.0)
    q = pan_tilt_roll_to_quat(0.3, -0.2, 2.5)
    c = parse_command(json.dumps({"q": (-q).tolist()}), twist=True)
    np.testing.assert_allclose(c.q, q, atol=1e-15)
    # without roll/twist: the twist-free orientation, as on two servos
    c = parse_command('{"pan": 20, "tilt": 10}', twist=True)
    assert float(decompose(c.q)[1]) == pytest.approx(0.0, abs=1e-12)
