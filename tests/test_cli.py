"""The command line: complete --help, clear errors, exit codes."""

import os

import pytest

from limbctl.cli import build_parser, main
from limbctl.teleop.commands import _ALLOWED_KEYS, _TWIST_KEYS
from tests.safety.support import wait_for

COMMANDS = "demo calibrate record train teleop reboot motors plot eval info prepare".split()


def _help(argv: list[str], capsys) -> str:
    with pytest.raises(SystemExit) as exit_info:
        main([*argv, "--help"])
    assert exit_info.value.code == 0
    return " ".join(capsys.readouterr().out.split())  # argparse wraps lines anywhere


#: What a help says beyond its options: both rigs, and every key a teleop command line may hold.
SAYS = {
    "": ["two servos (pan, tilt) or three (and roll)"],
    "record": ["pan, tilt; and roll on three servos"],
    "teleop": [
        *(f"'{key}'" for key in sorted((_ALLOWED_KEYS | _TWIST_KEYS) - {"t"})),
        "leader:ID,ID,ID",
        "[ ] roll",
    ],
}


@pytest.mark.parametrize("command", ["", *COMMANDS])
def test_every_command_has_help_with_its_options_and_speaks_of_both_rigs(command, capsys):
    out = _help([command] if command else [], capsys)
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command").choices.get(command, parser)
    for action in sub._actions:
        for flag in action.option_strings:
            assert flag in out
    assert command or all(name in out for name in COMMANDS)  # the top level lists every command
    assert all(words in out for words in SAYS.get(command, [])), command
    assert "both joints" not in out


def test_errors_and_bad_option_values_are_one_bounded_line_and_exit_2(tmp_path, capsys):
    missing = tmp_path / "nope.npz"
    assert main(["info", str(missing)]) == 2
    err = capsys.readouterr().err
    assert "limbctl info: error:" in err and "no such model file" in err

    assert main(["train", str(tmp_path / "none.limb"), "--out", str(tmp_path / "m.npz")]) == 2
    assert "limbctl train: error:" in capsys.readouterr().err

    (tmp_path / "bad.yaml").write_text("name: x\nport: sim\n")
    code = main(["teleop", "--rig", str(tmp_path / "bad.yaml"), "--model", str(missing)])
    assert code == 2
    assert "bad.yaml" in capsys.readouterr().err
    # bad option values are quoted boundedly
    huge = "9" * 100_000
    out = str(tmp_path / "rig.yaml")
    for option in ("--pan-stops", "--tilt-limits", "--ids"):
        assert main(["calibrate", "--out", out, f"{option}={huge},"]) == 2
        err = capsys.readouterr().err
        assert f"limbctl calibrate: error: {option}" in err and len(err) < 300, err[:300]
    with pytest.raises(SystemExit):
        main(["record", "--out", "x.limb", "--rate", huge + "x"])
    assert len(capsys.readouterr().err) < 1000
    # bad numbers are refused by the parser
    with pytest.raises(SystemExit) as exit_info:
        main(["record", "--out", "x.limb", "--rate", "nan"])
    assert exit_info.value.code == 2
    assert "positive number" in capsys.readouterr().err


def _wait_for_alarm(sim, servo_id):
    alarm = lambda: sim.truth()["servos"][servo_id]["hardware_error_status"]  # noqa: E731
    wait_for(alarm, 10.0, "the simulated servo to raise its alarm")


def test_reboot_and_info_on_servos_in_alarm_and_on_a_port_another_controller_holds(sim, capsys):
    from limbctl.servo.bus import ServoBus

    sim.set_temperature(2, 95.0)  # over the limit: overheating, torque off
    _wait_for_alarm(sim, 2)
    # info lists the servo in alarm and the way out
    assert main(["info", "--port", sim.port]) == 3
    out, err = capsys.readouterr()
    assert "servo 1: " in out and "hardware errors: none" in out
    assert "servo 2: " in out and "hardware errors: overheating" in out and "pose: pan" in out
    assert "servo 2 in alarm: fix the cause, then `limbctl reboot`" in err
    # reboot reboots the servo in alarm and says what it was
    sim.set_temperature(2, 30.0)  # the cause is fixed
    assert main(["reboot", "--port", sim.port]) == 0
    err = capsys.readouterr().err
    assert "servo 2 was in alarm (overheating): rebooted, torque off" in err
    assert "servo 1" not in err
    assert sim.truth()["servos"][2]["hardware_error_status"] == 0
    assert main(["reboot", "--port", sim.port]) == 0
    assert "no servo is in alarm" in capsys.readouterr().err
    # reboot says when the alarm comes straight back
    sim.set_voltage(1, 5.0)  # under the input voltage limit, and it stays there
    _wait_for_alarm(sim, 1)
    assert main(["reboot", "--port", sim.port]) == 3
    err = capsys.readouterr().err
    assert "servo 1 was in alarm (input voltage): rebooted, torque off" in err
    assert "servo 1 is in alarm again right after its reboot (input voltage)" in err
    sim.set_voltage(1, 12.0)  # the cause is fixed
    assert main(["reboot", "--port", sim.port]) == 0
    assert "in alarm again" not in capsys.readouterr().err
    # a command on a port another controller holds is refused, naming it
    with ServoBus(sim.port, 4_000_000, (1, 2)) as holder:
        assert main(["reboot", "--port", sim.port]) == 2
        err = capsys.readouterr().err
        assert f"in use by this process, pid {os.getpid()}" in err
        assert "cable" not in err and "thread" not in err
        assert holder.read_positions().keys() == {1, 2}  # the holder runs on


def test_motors_scan_finds_the_simulated_rig(capsys):
    assert main(["motors", "scan", "--scan-baud", "57600", "--scan-baud", "4000000"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines() == [
        "ID   1  XL430-W250 (1060)        firmware  46  at 4000000 baud",
        "ID   2  XL430-W250 (1060)        firmware  46  at 4000000 baud",
    ]
    assert "scanning [##] 2/2: 4000000 baud" in captured.err


def test_motors_setup_needs_a_port_and_a_known_joint(capsys):
    assert main(["motors", "setup", "--yes"]) == 2
    assert capsys.readouterr().err == (
        "limbctl motors: error: motors setup needs --port: the serial device of the servos (or "
        "a `firmware-sim --factory 2 --link PATH` to try it)\n"
    )
    assert main(["motors", "setup", "--yes", "--joint", "elbow", "--port", "/dev/null"]) == 2
    assert "unknown joint 'elbow': the profile has pan, tilt" in capsys.readouterr().err
    assert main(["motors", "setup", "--yes", "--baud", "4500000", "--port", "/dev/null"]) == 2
    assert capsys.readouterr().err == (
        "limbctl motors: error: baud 4500000 is one the servos know, but the serial driver "
        "(dynamixel-sdk) cannot open it; choose one of 9600, 57600, 115200, 1000000, 2000000, "
        "3000000, 4000000\n"
    )


def test_teleop_at_57600_baud_says_the_wire_cannot_carry_200_hz(tmp_path, capsys, cone_file):
    model = cone_file(180.0)
    commands = tmp_path / "commands.jsonl"
    commands.write_text("".join(f'{{"pan": {i * 0.2}, "tilt": 0.0}}\n' for i in range(20)))
    teleop = ["teleop", "--model", str(model), "--source", f"replay:{commands}", "--quiet"]
    assert main([*teleop, "--baud", "57600", "--latency-timer", "16"]) == 0
    assert "warning: at 57600 baud one cycle's 80 bytes take 13.9 ms" in capsys.readouterr().err
