"""Setting up servos out of the box, as a person does it, and every refusal's message."""

import io
from importlib import resources
from pathlib import Path

import pytest

from calib import default_sim_profile
from firmware_sim import SimulatedBus
from limbctl.cli import main
from limbctl.errors import ConfigError
from limbctl.servo.bus import ServoBus
from limbctl.servo.control_table import Register
from limbctl.servo.motors import JointTarget, check_target, setup_joint
from limbctl.servo.scan import SCAN_BAUDS
from limbctl.servo.setup import configure_servos
from limbctl.session import demo_region_path

PROFILE = default_sim_profile()
PAN = JointTarget("pan", PROFILE.pan.id, PROFILE.model, PROFILE.baud)
TILT = JointTarget("tilt", PROFILE.tilt.id, PROFILE.model, PROFILE.baud)
#: The bauds scanned in these tests: the factory's and the profile's (a full scan is 6 s).
BAUDS = (57_600, PROFILE.baud)


def setup(sim, target):
    return setup_joint(sim.port, target, latency_timer_ms=2.0, scan_bauds=BAUDS)


def test_two_factory_servos_set_up_one_then_the_other_then_both(tmp_path):
    eeprom, link = tmp_path / "eeprom", tmp_path / "tty"
    with SimulatedBus(factory=2, connect=(1,), eeprom_dir=eeprom, link=link) as sim:
        pan = setup(sim, PAN)
        assert pan.ok, pan.message
        assert pan.written == (f"baud 57600 -> {PROFILE.baud}", "Return Delay Time 0")
        again = setup(sim, PAN)
        assert again.ok and again.written == ()  # harmless the second time
    with SimulatedBus(factory=2, connect=(2,), eeprom_dir=eeprom, link=link) as sim:
        tilt = setup(sim, TILT)
        assert tilt.ok, tilt.message
        assert tilt.written[0] == "ID 1 -> 2"
    with SimulatedBus(factory=2, eeprom_dir=eeprom, link=link) as sim:
        with ServoBus(sim.port, PROFILE.baud, PROFILE.ids, PROFILE.model) as bus:
            for servo_id in PROFILE.ids:
                assert bus.read(Register.ID, servo_id) == servo_id
                assert bus.read(Register.RETURN_DELAY_TIME, servo_id) == 0
        run_the_flow_on(sim, tmp_path)
        refused = setup(sim, PAN)
    assert not refused.ok
    assert refused.message == (
        f"more than one servo answers (ID 1 at {PROFILE.baud} baud, ID 2 at {PROFILE.baud} "
        f"baud): connect only the pan servo and run again"
    )


def run_the_flow_on(sim, tmp_path):
    """calibrate, record, train and teleop, unchanged, on the servos set-up left."""
    port = sim.port
    data = resources.files("limbctl").joinpath("data")
    sim.set_hand(Path(str(data.joinpath("calibration_hand.yaml"))))
    assert main(["calibrate", "--port", port, "--out", str(tmp_path / "rig.yaml")]) == 0
    sim.set_hand(demo_region_path())
    recording, model = tmp_path / "teach.limb", tmp_path / "model.npz"
    assert main(["record", "--port", port, "--out", str(recording), "--duration", "3"]) == 0
    assert main(["train", str(recording), "--out", str(model), "--kind", "cone"]) == 0
    commands = tmp_path / "commands.jsonl"
    commands.write_text("".join(f'{{"pan": {i * 0.1}, "tilt": 0.0}}\n' for i in range(50)))
    teleop = ["teleop", "--port", port, "--model", str(model), "--source", f"replay:{commands}"]
    assert main([*teleop, "--quiet", "--approach", "20"]) == 0


@pytest.mark.parametrize(
    ("servos", "message"),
    [
        (
            {"factory": 2},
            "two or more servos answer as ID 1 at 57600 baud: connect only the pan servo and run "
            "again",
        ),
        (
            {"factory": 2, "connect": ()},
            f"no servo answers for the pan joint; baud rates scanned (--scan-baud): 57600, "
            f"{PROFILE.baud}:",
        ),
        (
            {"factory": 2, "connect": (), "bauds": SCAN_BAUDS},
            "no servo answers for the pan joint: no servo answered at any baud rate",
        ),
    ],
    ids=["collision", "nothing-connected", "nothing-at-any-rate"],
)
def test_a_bus_set_up_cannot_serve_is_refused_saying_why(tmp_path, servos, message):
    servos = dict(servos)
    bauds = servos.pop("bauds", BAUDS)
    with SimulatedBus(**servos, link=tmp_path / "tty") as sim:
        outcome = setup_joint(sim.port, PAN, latency_timer_ms=2.0, scan_bauds=bauds)
    assert not outcome.ok and outcome.message.startswith(message)


def test_another_model_a_5_v_servo_on_12_v_and_targets_its_family_cannot_take_are_refused(
    tmp_path,
):
    target = JointTarget("pan", 1, "xl330-m288", PROFILE.baud)
    with SimulatedBus(factory=1, model="xl330-m288", link=tmp_path / "tty") as sim:
        assert setup(sim, PAN).message.startswith(
            "the connected servo is XL330-M288 (1200) but the profile's pan is XL430-W250 (1060): "
            "connect the pan servo, or fix `model:` in the profile"
        ), "a servo of another model was set up as pan"
        sim.set_voltage(1, 12.0)
        outcome = setup(sim, target)
        assert outcome.message == (
            "pan: XL330-M288 measures 12.0 V, outside its 3.5..7.0 V limits: it expects "
            "3.7..6 V (5 V recommended); fix the supply before torque goes on"
        )
    with SimulatedBus(ids=(1,), model="xl330-m288", link=tmp_path / "tty") as sim:
        sim.set_voltage(1, 12.0)
        with ServoBus(sim.port, PROFILE.baud, (1,), "xl330-m288") as bus:
            with pytest.raises(ConfigError, match=r"^servo 1: XL330-M288 measures 12.0 V"):
                configure_servos(bus, {1: (0, 4095)})
            assert bus.read(Register.TORQUE_ENABLE, 1, check_alert=False) == 0
    with pytest.raises(ConfigError, match="XL330-M288 servos do not run at 4500000 baud"):
        check_target(JointTarget("pan", 1, "xl330-m288", 4_500_000))
    with pytest.raises(ConfigError, match="servo IDs are 0..252, got 300 for tilt"):
        check_target(JointTarget("tilt", 300, "xl430-w250", 57_600))


RIGS = Path(__file__).parents[2] / "calib" / "rigs"
#: The two rigs set-up serves: the finding's pan 7 / tilt 9 (no ID a factory servo has), and the
#: three-servo sim3 as shipped (pan 1: the factory ID, so only its set-up state tells it apart).
RIG_IDS = {"sim": {"pan": 7, "tilt": 9}, "sim3": {"pan": 1, "tilt": 2, "roll": 3}}


def rig_profile(tmp_path, rig):
    """A copy of ``calib/rigs/RIG.yaml`` whose joints have the IDs of :data:`RIG_IDS`."""
    text = (RIGS / f"{rig}.yaml").read_text()
    if rig == "sim":
        text = text.replace("  id: 1\n", "  id: 7\n").replace("  id: 2\n", "  id: 9\n")
    path = tmp_path / f"{rig}.yaml"
    path.write_text(text)
    return path


def answering_id(sim):
    """The ID the simulator's one servo (slot 1) answers as now (its ground truth)."""
    return sim.truth()["servos"][1]["id"]


def asked(answers_as, previous, joint):
    """What set-up asks when the servo of ``previous``, set up a moment ago, is still on."""
    return (
        f"The connected servo answers as ID {answers_as}, the {previous} joint's (set up a moment "
        f"ago): connect only the {joint} servo and press Enter to look again, or type skip to "
        f"leave {joint} for now: "
    )


def motors_setup(profile, port, *options, bauds=BAUDS):
    """``limbctl motors setup`` scanning only ``bauds`` (None: every rate, as by default)."""
    scan = [f"--scan-baud={baud}" for baud in bauds or ()]
    return main(["motors", "setup", "--rig", str(profile), "--port", port, *scan, *options])


@pytest.mark.parametrize("rig", sorted(RIG_IDS))
def test_a_one_servo_bench_sets_up_pan_only_with_yes_renumbers_on_purpose_and_skip_is_said(
    tmp_path, capsys, monkeypatch, rig
):
    ids = RIG_IDS[rig]
    others = [joint for joint in ids if joint != "pan"]
    profile = rig_profile(tmp_path, rig)
    with SimulatedBus(factory=1, link=tmp_path / "tty") as sim:
        # the default scan of every rate (6 s a joint) on one rig: the rig does not matter to it
        status = motors_setup(profile, sim.port, "--yes", bauds=None if rig == "sim" else BAUDS)
        answers_as = answering_id(sim)
        lines = capsys.readouterr().err.splitlines()
        # --renumber makes another joint's servo this one on purpose, named by --joint
        assert motors_setup(profile, sim.port, "--yes", "--joint", "tilt") == 1
        assert answering_id(sim) == ids["pan"]
        assert motors_setup(profile, sim.port, "--yes", "--joint", "tilt", "--renumber") == 0
        assert answering_id(sim) == ids["tilt"], "--renumber did not make the servo tilt's"
    renumbered = capsys.readouterr().err.splitlines()
    assert (
        f"tilt: XL430-W250 (1060) now ID {ids['tilt']} at 4000000 baud, Return Delay Time 0, "
        f"Status Return Level 2 (RAM: set again at every start) (found as ID {ids['pan']} at "
        "4000000 baud, the pan joint's ID: renumbered on purpose (--renumber), so no servo "
        f"answers as pan until one is set up as it; wrote ID {ids['pan']} -> {ids['tilt']})"
    ) in renumbered
    assert renumbered[-1] == "set up: tilt; failed: none"
    assert motors_setup(profile, "/dev/null", "--renumber") == 2
    refused = capsys.readouterr().err.strip()
    assert refused.endswith(
        "--renumber makes the connected servo one joint's on purpose: name that joint with "
        "--joint (e.g. --joint tilt)"
    )
    assert answers_as == ids["pan"], "the pan servo was renumbered as another joint's"
    for joint in others:
        assert (
            f"{joint}: FAILED: the connected servo answers as ID {ids['pan']}, the pan joint's, "
            f"and is the pan servo set up a moment ago: connect only the {joint} servo and run "
            f"`limbctl motors setup --joint {joint}` again (or, to make this servo the {joint} "
            f"servo on purpose, add --renumber)"
        ) in lines
    assert lines[-1] == f"set up: pan; failed: {', '.join(others)}"
    assert status == 1
    # asked: Enter for pan; then for each other joint: Enter (pan's servo still alone), then skip
    monkeypatch.setattr("sys.stdin", io.StringIO("\n" + "\nskip\n" * len(others)))
    with SimulatedBus(factory=1, link=tmp_path / "tty") as sim:
        status = motors_setup(profile, sim.port)
        answers_as = answering_id(sim)
    err = capsys.readouterr()
    assert answers_as == ids["pan"]
    for joint in others:
        assert asked(ids["pan"], "pan", joint) in err.out
    assert err.err.splitlines()[-1] == f"set up: pan; skipped: {', '.join(others)}; failed: none"
    assert status == 1


def test_at_the_factory_id_and_baud_only_a_factory_fresh_servo_is_nobodys(tmp_path, capsys):
    """At pan's ID 1 and 57600 baud only the Return Delay Time (0, not 250) tells pan apart."""
    eeprom, link, rig = tmp_path / "eeprom", tmp_path / "tty", "sim3"  # --joint: any rig
    setup = ["motors", "setup", "--rig", rig, "--baud", "57600", "--scan-baud", "57600", "--yes"]
    setup.append("--joint")
    with SimulatedBus(factory=2, connect=(1,), eeprom_dir=eeprom, link=link) as sim:
        # a factory servo (57600 baud) is not found where --scan-baud looks elsewhere, and so said
        assert motors_setup(rig, sim.port, "--yes", "--joint", "pan", bauds=(12_345,)) == 2
        assert "--scan-baud 12345: no X-series servo runs at it" in capsys.readouterr().err
        assert motors_setup(rig, sim.port, "--yes", "--joint", "pan", bauds=(1_000_000,)) == 1
        assert (
            "pan: FAILED: no servo answers for the pan joint; baud rates scanned (--scan-baud): "
            "1000000: connect its servo, or scan every rate (leave --scan-baud out)"
        ) in capsys.readouterr().err.splitlines()
        assert main([*setup, "pan", "--port", sim.port]) == 0
    with SimulatedBus(factory=2, connect=(1,), eeprom_dir=eeprom, link=link) as sim:
        assert main([*setup, "tilt", "--port", sim.port]) == 1
        assert answering_id(sim) == 1
    assert (
        "tilt: FAILED: the connected servo answers as ID 1, the pan joint's, and is the pan "
        "servo set up before (a factory-fresh servo answers as ID 1 at 57600 baud with Return "
        "Delay Time 250): connect only the tilt servo and run `limbctl motors setup --joint "
        "tilt` again (or, to make this servo the tilt servo on purpose, add --renumber)"
    ) in capsys.readouterr().err.splitlines()
    with SimulatedBus(factory=2, connect=(2,), eeprom_dir=eeprom, link=link) as sim:
        assert main([*setup, "tilt", "--port", sim.port]) == 0
        assert sim.truth()["servos"][2]["id"] == 2
    assert "(found as ID 1 at 57600 baud; wrote ID 1 -> 2" in capsys.readouterr().err


class Bench:
    """The person at the bench, as ``sys.stdin``: at each prompt a step, either a line typed or
    a swap of the one connected servo (the simulator's slots) followed by Enter."""

    def __init__(self, sim, steps):
        self.sim, self.steps = sim, list(steps)

    def readline(self):
        step = self.steps.pop(0)
        if isinstance(step, str):
            return step
        unplug, plug = step
        self.sim.vanish(unplug, 3600.0)  # off the bus for the rest of the test
        self.sim.vanish(plug, 0.0)  # back at once
        return "\n"


def test_asked_again_the_person_connects_the_right_servo_and_every_joint_is_set_up(
    tmp_path, capsys, monkeypatch
):
    rig = "sim3"  # its swaps follow a factory-ID joint (pan 1) and a renumbered one (tilt 2)
    ids = RIG_IDS[rig]
    joints = list(ids)
    with SimulatedBus(factory=len(joints), link=tmp_path / "tty") as sim:
        for slot in range(2, len(joints) + 1):
            sim.vanish(slot, 3600.0)  # only slot 1 (the pan servo) is connected
        # Enter for pan; at each later joint Enter (the last servo still on), then the swap
        steps = ["\n"] + [s for k in range(1, len(joints)) for s in ("\n", (k, k + 1))]
        monkeypatch.setattr("sys.stdin", Bench(sim, steps))
        status = motors_setup(rig_profile(tmp_path, rig), sim.port)
        servos = sim.truth()["servos"]
    out, err = capsys.readouterr()
    for previous, joint in zip(joints, joints[1:]):
        assert asked(ids[previous], previous, joint) in out
    assert {joint: servos[k + 1]["id"] for k, joint in enumerate(joints)} == ids
    assert err.splitlines()[-1] == f"set up: {', '.join(joints)}; failed: none"
    assert status == 0
