"""LeRobot's own motor set-up and client against factory-fresh simulated servos.

A person sets up a LeRobot arm with ``lerobot-setup-motors``: for each motor, last first, it
asks "Connect the controller board to the '<motor>' motor only and press enter." and calls
``DynamixelMotorsBus.setup_motor(motor)`` (broadcast pings at the model's baud rates, 9600
first, until one answers; then torque off, ID, Baud Rate). This check does the same against
``firmware-sim --factory 2`` (two factory-fresh XL430-W250: ID 1, 57600 baud, Return Delay
Time 250), one servo plugged in per simulator run (``--connect``), each servo's EEPROM kept
in a file between runs (``--eeprom``), then both on one bus:

1. ``--factory 2 --connect 2``: LeRobot sets up ``tilt`` (ID 2 at its 1 Mbps default);
   limbctl's SDK then finds ID 2 at 1 Mbps and nothing at 57600.
2. ``--factory 2 --connect 1``: LeRobot sets up ``pan`` (ID 1 at 1 Mbps); the same check.
3. ``--factory 2``, both plugged in: LeRobot's client connects (its handshake pings each
   motor and checks the model), broadcast-pings, writes Return Delay Time 0
   (``configure_motors``), sync-reads Present_Position, writes Goal_Position with a write and
   a sync write and reads the servos there, and ``scan_port`` scans every baud rate it knows.

``--arm koch`` does the same for LeRobot's Koch follower (six servos: two XL430-W250, four
XL330-M288, as ``--factory 6 --model ...``) through its own ``KochFollower.setup_motors``, whose
``input()`` prompts the check answers as the person would.

The simulator restarts between steps, and its pty with it, so LeRobot's port is closed at each
prompt and reopened by ``setup_motor`` (a real adapter stays open while the servo is swapped;
the servo sees the same: a power-up with its EEPROM).

LeRobot and its torch are too heavy for limbctl's own environment, so two pythons take part:
this script runs under limbctl's (simulator, verification with the dynamixel-sdk) and starts
itself under ``--lerobot-python`` with ``--client`` for LeRobot's side, which imports nothing of
limbctl and talks over stdin/stdout (one JSON object a line). Peer: limbctl's own SDK reads of
the same servos in the same run.

    python benchmarks/lerobot_setup_check.py --lerobot-python /path/to/venv/bin/python \
        [--lerobot-python another/bin/python ...] [--arm gimbal|koch ...] [--append] \
        [--out docs/lerobot_check.md]

docs/lerobot_check.md came from two runs: the gimbal with LeRobot 0.6.1 and 0.4.4, then
``--arm koch --append`` with 0.6.1. A step that loses a reply is re-run once and reported
(RETRIES below).

Exit status 0 when every step passed, 1 otherwise. A LeRobot venv without its heavy
dependencies (what ``.ci/run`` does; lerobot 0.5 and later need Python 3.12 and import torch
too, for which PyPI has only the CUDA build, about 5.5 GB):

    python3.11 -m venv /tmp/lerobot-venv
    /tmp/lerobot-venv/bin/pip install torch==2.13.0 dynamixel-sdk pyserial deepdiff tqdm \
        draccus numpy accelerate datasets
    /tmp/lerobot-venv/bin/pip install --no-deps lerobot==0.4.4
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The arms set up: name -> motors as LeRobot sees them, name -> (ID, LeRobot model name), the
#: servo with ID n in the simulator's slot n. "gimbal" is limbctl's two joints; "koch" is
#: LeRobot's Koch follower, set up by its own ``KochFollower.setup_motors``.
ARMS = {
    "gimbal": {"pan": (1, "xl430-w250"), "tilt": (2, "xl430-w250")},
    "koch": {
        "shoulder_pan": (1, "xl430-w250"),
        "shoulder_lift": (2, "xl430-w250"),
        "elbow_flex": (3, "xl330-m288"),
        "wrist_flex": (4, "xl330-m288"),
        "wrist_roll": (5, "xl330-m288"),
        "gripper": (6, "xl330-m288"),
    },
}
#: Model numbers (X series e-Manual), for what limbctl's SDK expects to find.
MODEL_NUMBER = {"xl430-w250": 1060, "xl330-m288": 1200}
#: LeRobot's DynamixelMotorsBus.default_baudrate: what its setup writes.
LEROBOT_BAUD = 1_000_000
FACTORY_BAUD = 57_600
#: Control table addresses (X series e-Manual): ID, Baud Rate, Return Delay Time.
ID_ADDR, BAUD_ADDR, RDT_ADDR = 7, 8, 9
#: Baud Rate register value for 1 Mbps (X series e-Manual's baud table).
BAUD_VALUE_1M = 3
#: Ticks the goal moves from where the servo is: 100 of 4096 (8.8 deg), clear of noise.
GOAL_STEP_TICKS = 100
#: A servo is "there" within this many ticks of its goal (the simulated XL430's settling).
AT_GOAL_TICKS = 20
#: How long the client waits for the servos to reach the goal (s); 8.8 deg at the XL430's
#: profile-free speed takes well under a second.
GOAL_WAIT_S = 5.0
#: Times a person re-runs a LeRobot step that failed with "There is no status packet!" before
#: giving up. The SDK waits 34 ms for a reply (2 x its 16 ms latency timer + 2 ms); on this
#: 2-core machine at load 8-12 from other sessions, 11-29 of 1000 writes timed out, most with
#: the reply already in the pty when the SDK gave up (the SDK was descheduled between its read
#: and its clock check), with the simulator's and the client's niceness made no better (the
#: kernel's autogroups weigh sessions, not processes). A real set-up is re-run the same way, and
#: LeRobot's setup_motor rescans, so a re-run is harmless; each one is reported.
RETRIES = 1
#: Reply timeout of limbctl's verifying reads (ms): patient, as they only look.
PATIENT_MS = 500.0
#: How long a simulator run may take to create its pty link (s); it imports numpy and numba.
SIM_START_S = 60.0
#: How long one client step may take (s): a setup scans 9600 baud first, 4.5 s of broadcast.
STEP_TIMEOUT_S = 120.0


# ---------------------------------------------------------------- LeRobot's side (--client)
def client(port: str, arm: str) -> int:
    """LeRobot's setup_motors flow and client on ``port``; prints one JSON object a line."""
    from importlib.metadata import version

    from lerobot.motors import Motor, MotorNormMode
    from lerobot.motors.dynamixel import DynamixelMotorsBus

    def say(**fields) -> None:
        print(json.dumps(fields), flush=True)

    def prompt(text: str) -> None:
        say(prompt=text)
        sys.stdin.readline()

    def again(what: str, call, errors=(ConnectionError,), undo=None):
        """``call()``, re-run up to RETRIES times after one of ``errors`` (each reported)."""
        for attempt in range(RETRIES + 1):
            try:
                return call()
            except errors as error:
                if attempt == RETRIES:
                    raise
                say(retry=what, error=" ".join(str(error).split()))
                if undo is not None:
                    undo()

    say(
        lerobot=version("lerobot"),
        dynamixel_sdk=version("dynamixel-sdk"),
        python=platform.python_version(),
    )
    motors = {
        name: Motor(ident, model, MotorNormMode.RANGE_M100_100)
        for name, (ident, model) in ARMS[arm].items()
    }
    if arm == "koch":
        import builtins

        from lerobot.robots.koch_follower import KochFollower, KochFollowerConfig

        robot = KochFollower(KochFollowerConfig(port=port, id="limbctl_sim"))
        bus = robot.bus
        asked: list[str] = []

        def person(text: str = "") -> str:
            """The person at the prompt: swaps the servo (a new simulator run), presses enter."""
            if asked:
                say(step="setup_motor", motor=asked[-1], id=bus.motors[asked[-1]].id)
            if bus.is_connected:
                bus.port_handler.closePort()  # the simulator restarts for the next servo
            asked.append(text.split("'")[1])
            prompt(text)
            return ""

        builtins.input = person
        # LeRobot's own loop, verbatim; not re-run on a lost reply: it would start over at the
        # first motor while the bench has moved on
        robot.setup_motors()
        say(step="setup_motor", motor=asked[-1], id=bus.motors[asked[-1]].id)
    else:
        bus = DynamixelMotorsBus(port=port, motors=motors)
        # what LeRobot's robots' setup_motors() do: for motor in reversed(bus.motors):
        # input("Connect the controller board to the '...' motor only and press enter.");
        # bus.setup_motor(motor)
        for motor in reversed(bus.motors):
            if bus.is_connected:
                bus.port_handler.closePort()  # the simulator restarts for the next servo
            prompt(f"Connect the controller board to the '{motor}' motor only and press enter.")
            start = time.monotonic()
            again(f"setup_motor('{motor}')", lambda m=motor: bus.setup_motor(m))
            say(
                step="setup_motor",
                motor=motor,
                id=bus.motors[motor].id,
                baud=bus.get_baudrate(),
                seconds=round(time.monotonic() - start, 2),
            )
    bus.port_handler.closePort()
    prompt("Connect all motors and press enter.")
    # the handshake pings every motor and checks its model; a lost reply there is a RuntimeError
    # ("motor check failed") with the port left open
    again("connect", bus.connect, (ConnectionError, RuntimeError), bus.port_handler.closePort)
    say(step="connect", ok=True)
    found = again("broadcast_ping", lambda: bus.broadcast_ping(raise_on_error=True))
    say(step="broadcast_ping", found={str(k): v for k, v in found.items()})
    again("configure_motors", bus.configure_motors)  # Return Delay Time 0
    rdt = {m: again("read", lambda m=m: bus.read("Return_Delay_Time", m)) for m in motors}
    say(step="configure_motors", rdt=rdt)
    before = again("sync_read", lambda: bus.sync_read("Present_Position", normalize=False))
    say(step="sync_read", present=before)
    again("enable_torque", bus.enable_torque)
    goals = {m: before[m] + GOAL_STEP_TICKS for m in motors}
    first, *rest = motors
    again("write", lambda: bus.write("Goal_Position", first, goals[first], normalize=False))
    others = {m: goals[m] for m in rest}
    bus.sync_write("Goal_Position", others, normalize=False)  # no reply
    deadline = time.monotonic() + GOAL_WAIT_S
    while True:
        after = again("sync_read", lambda: bus.sync_read("Present_Position", normalize=False))
        if all(abs(after[m] - goals[m]) <= AT_GOAL_TICKS for m in motors):
            break
        if time.monotonic() > deadline:
            break
    say(step="goal", goal=goals, present=after)
    again("disconnect", bus.disconnect)  # torque off, port closed
    start = time.monotonic()
    found = DynamixelMotorsBus.scan_port(port)
    say(
        step="scan_port",
        found={str(k): v for k, v in found.items()},
        seconds=round(time.monotonic() - start, 2),
    )
    say(step="done")
    return 0


# ---------------------------------------------------------------- limbctl's side
class Simulator:
    """One ``firmware-sim`` run: started with ``options``, stopped with SIGTERM."""

    def __init__(self, link: Path, options: list[str]) -> None:
        self.link = link
        self.command = [sys.executable, "-m", "firmware_sim", "--link", str(link), *options]
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        self.log = link.with_name("firmware-sim.log")
        with open(self.log, "ab") as log:
            self.process = subprocess.Popen(self.command, env=env, stdout=log, stderr=log)
        deadline = time.monotonic() + SIM_START_S
        while not link.exists():
            if self.process.poll() is not None:
                raise RuntimeError(f"firmware-sim exited: {self.log.read_text()[-2000:]}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"firmware-sim made no {link} in {SIM_START_S} s")
            time.sleep(0.05)

    def stop(self) -> None:
        self.process.send_signal(signal.SIGINT)
        self.process.wait(timeout=30)


def sdk_view(port: str) -> dict:
    """What limbctl's dynamixel-sdk sees: IDs at 57600 and at 1 Mbps, ID/baud/RDT registers."""
    from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

    class PatientPort(PortHandler):
        def setPacketTimeout(self, packet_length):  # noqa: N802 (SDK's name)
            self.setPacketTimeoutMillis(PATIENT_MS)

    packet = PacketHandler(2.0)
    handler = PatientPort(port)
    seen: dict = {}
    try:
        for baud in (FACTORY_BAUD, LEROBOT_BAUD):
            if not handler.setBaudRate(baud):
                raise RuntimeError(f"cannot open {port} at {baud}")
            found, _ = packet.broadcastPing(handler)
            seen[str(baud)] = {str(k): v[0] for k, v in sorted(found.items())}
        for ident in sorted(int(k) for k in seen[str(LEROBOT_BAUD)]):
            values = []
            for addr in (ID_ADDR, BAUD_ADDR, RDT_ADDR):
                value, result, error = packet.read1ByteTxRx(handler, ident, addr)
                values.append(value if result == COMM_SUCCESS and error == 0 else None)
            seen[f"id {ident}"] = dict(zip(("ID", "Baud_Rate", "Return_Delay_Time"), values))
    finally:
        handler.closePort()
    return seen


def expect(condition: bool, what: str, checks: list[tuple[bool, str]]) -> None:
    checks.append((bool(condition), what))


def run_check(lerobot_python: str, workdir: Path, arm: str = "gimbal") -> dict:
    """Drive LeRobot's client through one simulator run per motor, then one with all of them;
    every event and check."""
    motors = ARMS[arm]
    link = workdir / "tty"
    bench = ["--factory", str(len(motors)), "--eeprom", str(workdir / "eeprom")]
    models = [model for _, model in motors.values()]
    if len(set(models)) > 1:
        bench += ["--model", ",".join(models)]
    runs = [[*bench, "--connect", str(ident)] for ident, _ in reversed(motors.values())]
    runs.append(bench)
    events: list[dict] = []
    checks: list[tuple[bool, str]] = []
    sims: list[str] = []
    views: list[dict] = []
    errors = open(workdir / "lerobot.stderr", "w+", encoding="utf-8")  # noqa: SIM115
    lerobot = subprocess.Popen(
        [lerobot_python, str(Path(__file__).resolve()), "--client", str(link), "--arm", arm],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=errors,  # a file: tqdm's bars must not fill a pipe nobody reads
        text=True,
        cwd=workdir,
    )
    sim: Simulator | None = None
    try:
        for line in lerobot.stdout:
            if not line.startswith("{"):
                continue
            event = json.loads(line)
            events.append(event)
            if "prompt" in event:
                if sim is not None:
                    views.append(sdk_view(str(link)))
                    sim.stop()
                sim = Simulator(link, runs[len(sims)])
                shown = " ".join(["firmware-sim", *sim.command[3:]])
                sims.append(shown.replace(str(workdir), "$TMP"))
                lerobot.stdin.write("\n")
                lerobot.stdin.flush()
            if event.get("step") == "done":
                views.append(sdk_view(str(link)))
        code = lerobot.wait(timeout=STEP_TIMEOUT_S)
    finally:
        if lerobot.poll() is None:
            lerobot.kill()
        if sim is not None:
            sim.stop()
    errors.seek(0)
    stderr = errors.read()
    errors.close()
    steps = {(e.get("step"), e.get("motor")): e for e in events if "step" in e}
    expect(code == 0, f"LeRobot's client exited {code}", checks)
    for k, (motor, (ident, model)) in enumerate(reversed(motors.items())):
        done = steps.get(("setup_motor", motor), {})
        expect(done.get("id") == ident, f"setup_motor('{motor}') set ID {ident}", checks)
        view = views[k] if k < len(views) else {}
        expect(
            view.get(str(LEROBOT_BAUD)) == {str(ident): MODEL_NUMBER[model]}
            and view.get(str(FACTORY_BAUD)) == {},
            f"limbctl's SDK finds only ID {ident} at {LEROBOT_BAUD}, nothing at {FACTORY_BAUD}",
            checks,
        )
        registers = view.get(f"id {ident}", {})
        expect(
            registers.get("ID") == ident and registers.get("Baud_Rate") == BAUD_VALUE_1M,
            f"ID {ident}'s registers read back ID {ident}, Baud Rate {BAUD_VALUE_1M} (1 Mbps)",
            checks,
        )
    every = {str(i): MODEL_NUMBER[model] for i, model in motors.values()}
    ids = sorted(i for i, _ in motors.values())
    expect(steps.get(("connect", None), {}).get("ok"), "connect() with its handshake", checks)
    ping = steps.get(("broadcast_ping", None), {}).get("found")
    expect(ping == every, f"broadcast_ping() finds IDs {ids} with their models", checks)
    rdt = steps.get(("configure_motors", None), {}).get("rdt")
    expect(rdt == dict.fromkeys(motors, 0), "configure_motors() leaves RDT 0", checks)
    goal = steps.get(("goal", None), {})
    reached = all(
        abs(goal.get("present", {}).get(m, 1 << 20) - goal.get("goal", {}).get(m, 0))
        <= AT_GOAL_TICKS
        for m in motors
    )
    expect(reached, f"Goal_Position write + sync_write reached within {AT_GOAL_TICKS}", checks)
    scan = steps.get(("scan_port", None), {}).get("found")
    expect(scan == {str(LEROBOT_BAUD): ids}, f"scan_port() finds {ids} at 1 Mbps only", checks)
    final = views[-1] if len(views) > len(motors) else {}
    expect(
        final.get(str(LEROBOT_BAUD)) == every and final.get(str(FACTORY_BAUD)) == {},
        f"after all: limbctl's SDK finds IDs {ids} at 1 Mbps, nothing at 57600",
        checks,
    )
    return {
        "arm": arm,
        "events": events,
        "checks": checks,
        "sims": sims,
        "views": views,
        "stderr": stderr,
        "code": code,
    }


def section(result: dict) -> list[str]:
    """One LeRobot's part of docs/lerobot_check.md."""
    head = next((e for e in result["events"] if "lerobot" in e), {})
    passed = all(ok for ok, _ in result["checks"])
    lines = [
        f"## {result['arm']}: LeRobot {head.get('lerobot', '?')} (Python "
        f"{head.get('python', '?')}, dynamixel-sdk {head.get('dynamixel_sdk', '?')})",
        "",
        f"Outcome: **{'PASS' if passed else 'FAIL'}** "
        f"({sum(ok for ok, _ in result['checks'])} of {len(result['checks'])} checks).",
        "",
        f"Steps re-run after a lost reply (at most {RETRIES} each, as a person re-runs a "
        f"failed step): {sum('retry' in e for e in result['events'])}.",
        "",
        "Simulator runs, one per prompt, as a person plugs servos in:",
        "",
        *[f"{k + 1}. `{line}`" for k, line in enumerate(result["sims"])],
        "",
        "What LeRobot did and said:",
        "",
        "```",
        *[json.dumps(e) for e in result["events"]],
        "```",
        "",
        "Checks:",
        "",
        *[f"- {'ok  ' if ok else 'FAIL'} {what}" for ok, what in result["checks"]],
        "",
        "limbctl's SDK view after each run (the peer):",
        "",
        "```",
        *[json.dumps(v) for v in result["views"]],
        "```",
        "",
    ]
    if not passed and result["stderr"].strip():
        lines += ["LeRobot's stderr:", "", "```", result["stderr"].strip()[-4000:], "```", ""]
    return lines


def report(results: list[dict], command: str, title: bool = True) -> str:
    """docs/lerobot_check.md's text (without its title: to append to it)."""
    lines = ["# LeRobot's own motor set-up against the simulator", ""] if title else []
    lines += [
        f"Command: `{command}`",
        "",
        "What it does: benchmarks/lerobot_setup_check.py's docstring. limbctl's side on Python "
        f"{platform.python_version()} ({platform.machine()}, {os.cpu_count()} cores, load "
        f"average {', '.join(f'{x:.1f}' for x in os.getloadavg())} at the end).",
        "",
    ]
    for result in results:
        lines += section(result)
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--lerobot-python",
        action="append",
        help="a python with lerobot (repeat for several LeRobots; default: this python)",
    )
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "lerobot_check.md")
    parser.add_argument(
        "--arm",
        action="append",
        choices=sorted(ARMS),
        help="what to set up (repeatable; default: gimbal): limbctl's two joints, or LeRobot's "
        "Koch follower (6 servos, XL430 and XL330) through its own setup_motors",
    )
    parser.add_argument(
        "--append", action="store_true", help="add this run's sections to --out, keep the rest"
    )
    parser.add_argument("--client", metavar="PORT", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    arms = args.arm or ["gimbal"]
    if args.client:
        return client(args.client, arms[0])
    results = []
    for python in args.lerobot_python or [sys.executable]:
        for arm in arms:
            with tempfile.TemporaryDirectory() as tmp:
                results.append(run_check(python, Path(tmp), arm))
    pythons = args.lerobot_python or [sys.executable]
    command = "python benchmarks/lerobot_setup_check.py" + "".join(
        f" --lerobot-python LEROBOT{k + 1}/bin/python"
        if len(pythons) > 1
        else " --lerobot-python LEROBOT_VENV/bin/python"
        for k in range(len(pythons))
    )
    command += "".join(f" --arm {arm}" for arm in args.arm or [])
    if args.append and args.out.exists():
        command += " --append"
        text = args.out.read_text(encoding="utf-8") + report(results, command, title=False)
    else:
        text = report(results, command)
    args.out.write_text(text, encoding="utf-8")
    print(text)
    return 0 if all(ok for r in results for ok, _ in r["checks"]) else 1


if __name__ == "__main__":
    sys.exit(main())
