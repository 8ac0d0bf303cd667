"""The simulated bus without its transport: servos, world, faults and goal log on one clock.
A servo's joint is fixed by its *slot* (its ID at start; ``factory=N``: slots 1..N), so it keeps
its joint when set-up changes its ID."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import IO, Any

from firmware_sim.control_table import Model, Register, get_model
from firmware_sim.dispatch import dispatch
from firmware_sim.eeprom import EepromFile
from firmware_sim.faults import FaultInjector, FaultPlan
from firmware_sim.hand import Hand
from firmware_sim.leader import LeaderWorld, Operator
from firmware_sim.protocol import MAX_SERVO_ID, PacketParser
from firmware_sim.servo import Environment, Servo
from firmware_sim.wire import BAUD_BY_VALUE, collide, value_for_baud
from firmware_sim.world import DEFAULT_JOINTS, MAX_SUBSTEP_S, ROLL_JOINT, World

# A free shaft (no joint in the world) starts at the middle of the turn.
FREE_SHAFT_START_TICK = 2048.0


def parse_ids(ids: Sequence[int] | str) -> tuple[int, ...]:
    """Servo IDs from a sequence or a ``"1,2"`` string; ValueError naming the bad one."""
    if isinstance(ids, str):
        try:
            values = [int(part) for part in ids.split(",") if part.strip()]
        except ValueError:
            raise ValueError(
                f"--ids must look like 1,2 (comma-separated integers), got {ids!r}"
            ) from None
    else:
        values = [int(v) for v in ids]
    if not values:
        raise ValueError("at least one servo ID is needed, e.g. --ids 1,2")
    for value in values:
        if not 0 <= value <= MAX_SERVO_ID:
            raise ValueError(f"servo ID {value} is outside 0..{MAX_SERVO_ID}")
    if len(set(values)) != len(values):
        raise ValueError(f"servo IDs must be distinct, got {values}")
    return tuple(values)


class Simulator:
    """Servos on one bus with their world; servos beyond the joints drive free shafts.

    The other options are ``firmware-sim``'s (``--eeprom`` is ``eeprom_dir``), with ``hand`` a
    :class:`Hand`, ``leader`` a :meth:`LeaderWorld.from_spec` spec whose ids join and ``roll_id``
    the servo in ``ids`` that turns the limb about its own axis (None: two joints); ``baud`` the
    servos' baud rate (bit/s; None: any until their Baud Rate is written); ``clock`` monotonic s.
    """

    def __init__(
        self,
        ids: Sequence[int] = (1, 2),
        model: str = "xl430-w250",
        hand: Hand | None = None,
        goal_log: str | Path | None = None,
        seed: int = 0,
        faults: FaultPlan | None = None,
        clock: Callable[[], float] = time.monotonic,
        baud: int | None = None,
        factory: int = 0,
        connect: Sequence[int] | None = None,
        eeprom_dir: str | Path | None = None,
        leader: Mapping[str, Any] | None = None,
        roll_id: int | None = None,
    ) -> None:
        self.leader = None if leader is None else LeaderWorld.from_spec(leader)
        leader_ids = () if self.leader is None else self.leader.ids
        ids = tuple(ids) + tuple(i for i in leader_ids if i not in tuple(ids))
        if factory > 0 and leader_ids:
            raise ValueError(
                "a leader gimbal is not served with --factory (factory-fresh servos all answer "
                "as ID 1): drop --factory or --leader"
            )
        slots = parse_ids(range(1, factory + 1) if factory > 0 else ids)
        self.ids = (parse_ids(connect) if connect else ()) if connect is not None else slots
        if not set(self.ids) <= set(slots):
            raise ValueError(f"--connect {list(self.ids)} names slots beyond {list(slots)}")
        # --model names the limb's and free shafts' models; a leader's come from its spec
        followers = [slot for slot in slots if slot not in leader_ids]
        given = dict(zip(followers, self._models(model, len(followers)), strict=True))
        models = [given.get(slot) for slot in slots]
        baud_value = None if baud is None else value_for_baud(int(baud))
        self.seed = seed
        joints = DEFAULT_JOINTS
        if roll_id is not None:
            if roll_id not in self.ids or roll_id in (j.servo_id for j in DEFAULT_JOINTS):
                raise ValueError(
                    f"the roll joint's servo {roll_id} must be one of the ids {list(self.ids)} "
                    f"other than pan and tilt ({', '.join(str(j.servo_id) for j in joints)})"
                )
            joints = (*DEFAULT_JOINTS, replace(ROLL_JOINT, servo_id=int(roll_id)))
        self.world = World(joints=joints, hand=hand, seed=seed)
        self._joint_ids = {joint.servo_id for joint in self.world.joints}
        if self._joint_ids & set(leader_ids):
            raise ValueError(
                f"leader ids {leader_ids} must not be the follower's {self._joint_ids}"
            )
        self._clock = clock
        self._start = clock()
        self.time_s = 0.0
        self._free_shafts: dict[int, list[float]] = {}
        self.servos: list[Servo] = []
        self._eeproms: dict[int, EepromFile] = {}
        for slot, slot_model in zip(slots, models, strict=True):
            if slot not in self.ids:
                continue
            on_goal = self._log_goal
            if slot in self._joint_ids:
                start = self.world.raw_tick(slot)
            elif slot in leader_ids:
                start = self.leader.raw_tick(slot)
                slot_model = get_model(self.leader.model)
                on_goal = None  # the goal log is the follower's: a leader's goals are not in it
            else:
                start = FREE_SHAFT_START_TICK
                self._free_shafts[slot] = [start, 0.0]
            servo = Servo(1 if factory > 0 else slot, slot_model, start, on_goal=on_goal)
            if factory <= 0 and baud_value is not None:
                servo.preset(Register.BAUD_RATE, baud_value)
            if eeprom_dir is not None:
                self._eeproms[slot] = EepromFile(eeprom_dir, slot)
                self._eeproms[slot].load(servo)
            self.servos.append(servo)
        # no baud given: each servo hears any host baud until its Baud Rate register is written
        self._any_baud = (
            {id(servo): servo.value(Register.BAUD_RATE) for servo in self.servos}
            if baud is None and factory <= 0
            else {}
        )
        self._home_ids = {id(servo): sid for servo, sid in zip(self.servos, self.ids, strict=True)}
        self.faults = FaultInjector(faults or FaultPlan(seed=seed))
        self.parser = PacketParser()
        self._goal_log: IO[str] | None = None
        if goal_log is not None:
            self._goal_log = open(goal_log, "a", encoding="utf-8", buffering=1)  # noqa: SIM115
        self.packets = 0

    @staticmethod
    def _models(model: str, count: int) -> list[Model]:
        """One model per slot from ``"key"`` (all alike) or ``"key,key,..."`` (one each)."""
        keys = [part.strip() for part in model.split(",") if part.strip()]
        if len(keys) == 1:
            keys *= count
        if len(keys) != count:
            raise ValueError(
                f"--model names {len(keys)} models for {count} servos; give 1 or {count}"
            )
        return [get_model(key) for key in keys]

    def hears(self, servo: Servo, baud: int | None) -> bool:
        """Whether ``servo`` decodes a host at ``baud`` bit/s (None: always)."""
        register = servo.value(Register.BAUD_RATE)
        if self._any_baud.get(id(servo)) == register:
            return True
        return baud is None or BAUD_BY_VALUE.get(register) == baud

    def now(self) -> float:
        """Seconds since the simulator started."""
        return self._clock() - self._start

    def advance(self, until_s: float | None = None) -> None:
        """Step servos and world up to ``until_s`` (default: now) in <= 1 ms substeps."""
        target = self.now() if until_s is None else until_s
        span = target - self.time_s
        if span <= 0.0:
            return
        count = math.ceil(span / MAX_SUBSTEP_S - 1e-9)
        dt = span / count
        for _ in range(count):
            self._substep(dt)
        self.time_s = target

    def _substep(self, dt: float) -> None:
        drive: dict[int, float | None] = {}
        for servo in self.servos:
            drive[self._home_ids[id(servo)]] = servo.drive_setpoint(dt)
        self.world.step(dt, {k: v for k, v in drive.items() if k in self._joint_ids})
        if self.leader is not None:
            self.leader.step(dt, {i: self.servo(i) for i in self.leader.ids}, drive)
        for servo in self.servos:
            home = self._home_ids[id(servo)]
            if self.leader is not None and home in self.leader.ids:
                continue  # the leader world observed it
            if home in self._joint_ids:
                raw = self.world.raw_tick(home)
                velocity = self.world.velocity(home)
                load = self.world.load_percent(home)
            else:
                shaft = self._free_shafts[home]
                setpoint = drive[home]
                new = shaft[0] if setpoint is None else setpoint
                raw, velocity, load = new, (new - shaft[0]) / dt, 0.0
                shaft[0], shaft[1] = new, velocity
            servo.observe(raw, velocity, load, dt)

    def receive(
        self, data: bytes, arrived_s: float | None = None, baud: int | None = None
    ) -> list[tuple[bytes, float]]:
        """``(packet, delay_s)`` to send, in order, for bytes from the controller that arrived at
        ``arrived_s`` (default: now) at ``baud`` bit/s (None: every servo hears them)."""
        now = self.now() if arrived_s is None else arrived_s
        self.advance(now)
        out: list[tuple[bytes, float]] = []
        for packet in self.parser.feed(data, now):
            self.packets += 1
            present = [
                s
                for s in self.servos
                if self.faults.present(self._home_ids[id(s)], now) and self.hears(s, baud)
            ]
            for servo in present:
                servo.refresh(now)
            replies = dispatch(packet, present)
            k = 0
            while k < len(replies):
                # servos answering as one ID talk at once: their replies collide on the wire
                end = k + 1
                while end < len(replies) and replies[end].servo_id == replies[k].servo_id:
                    end += 1
                together, k = replies[k:end], end
                packet_out = collide([r.packet for r in together])
                sent, extra = self.faults.outgoing(packet_out)
                if sent is not None:
                    out.append((sent, min(r.delay_s for r in together) + extra))
        return out

    def persist(self) -> None:
        """Write each changed EEPROM to its file, once replies are out (a write takes ms)."""
        for servo in self.servos:
            eeprom = self._eeproms.get(self._home_ids[id(servo)])
            if eeprom is not None:
                eeprom.save(servo)

    def _log_goal(self, servo: Servo, goal: int) -> None:
        if self._goal_log is None:
            return
        gimbal = {
            self._home_ids[id(s)]: s.goal_raw_tick()
            for s in self.servos
            if self._home_ids[id(s)] in self._joint_ids
        }
        direction = self.world.direction_for_ticks(gimbal) if gimbal else None
        line = {
            "t": round(self.time_s, 6),
            "id": servo.servo_id,
            "goal": goal,
            "limb_dir": None if direction is None else [float(v) for v in direction],
        }
        if self.world.has_roll and gimbal:
            line["limb_q"] = [float(v) for v in self.world.orientation_for_ticks(gimbal)]
        self._goal_log.write(json.dumps(line) + "\n")

    def close(self) -> None:
        """Flush and close the goal log (safe to call twice)."""
        if self._goal_log is not None:
            self._goal_log.close()
            self._goal_log = None
        if self.leader is not None:
            self.leader.close()

    def servo(self, servo_id: int) -> Servo:
        """The servo started with ``servo_id``; ValueError listing the IDs otherwise."""
        for servo in self.servos:
            if self._home_ids[id(servo)] == servo_id:
                return servo
        raise ValueError(f"no servo {servo_id} on this bus; it has {list(self.ids)}")

    def slots_answering(self, servo_id: int) -> tuple[int, ...]:
        """The slots of the servos whose ID register answers as ``servo_id`` now."""
        return tuple(self._home_ids[id(s)] for s in self.servos if s.servo_id == servo_id)

    def answering_ids(self) -> tuple[int, ...]:
        """The IDs the servos answer as now, ascending, each once."""
        return tuple(sorted({servo.servo_id for servo in self.servos}))

    def set_operator(self, operator: Mapping[str, Any] | None) -> None:
        """Give the leader to an operator (:class:`firmware_sim.leader.Operator` as data)."""
        if self.leader is None:
            raise ValueError("this simulator has no leader gimbal; start it with leader=...")
        self.advance()
        hand = None if operator is None else Operator.from_mapping(operator, len(self.leader.ids))
        self.leader.set_operator(hand)

    def push(self, servo_id: int, torque_percent: float) -> None:
        self.servo(servo_id)
        self.world.push(servo_id, torque_percent)

    def vanish(self, servo_id: int, duration_s: float) -> None:
        self.servo(servo_id)
        self.faults.vanish(servo_id, self.now(), duration_s)

    def restart(self, servo_id: int, off_s: float = 0.0) -> None:
        """Brown-out: off the bus for ``off_s`` s, then RAM at its defaults, EEPROM kept."""
        servo = self.servo(servo_id)
        self.advance()
        servo.reboot()
        self.faults.vanish(servo_id, self.now(), off_s)

    def set_environment(
        self, servo_id: int, voltage: float | None = None, temperature: float | None = None
    ) -> None:
        servo = self.servo(servo_id)
        old = servo.environment
        servo.environment = Environment(
            voltage=old.voltage if voltage is None else float(voltage),
            temperature=old.temperature if temperature is None else float(temperature),
        )

    def truth(self) -> dict[str, Any]:
        """Ground truth for tests: joint angles, and per servo shaft, setpoint, registers."""
        self.advance()
        servos = {}
        for servo in self.servos:
            home = self._home_ids[id(servo)]
            servos[home] = {
                "id": servo.servo_id,
                "raw_tick": servo.raw_tick,
                "velocity": servo.raw_velocity,
                "load_percent": servo.load_percent,
                "setpoint": servo.trajectory.position,
                "torque_on": servo.torque_on,
                "goal_position": servo.value(Register.GOAL_POSITION),
                "hardware_error_status": servo.value(Register.HARDWARE_ERROR_STATUS),
                "present": self.faults.present(home, self.time_s),
            }
        return {
            "time_s": self.time_s,
            "joints_deg": self.world.joint_angles_deg(),
            "servos": servos,
            "faults": self.faults.counters(),
            "leader": None if self.leader is None else self.leader.truth(),
            "packets": self.packets,
            "junk_bytes": self.parser.junk_bytes,
        }
