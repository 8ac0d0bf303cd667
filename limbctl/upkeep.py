"""Jobs that look after the servos rather than drive them: ``limbctl reboot``.

Typed like :mod:`limbctl.jobs` (one options value in, an exit status out); kept apart so the
jobs that drive the limb stay in one module of readable size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from limbctl.jobs import Connection, say
from limbctl.session import open_rig


@dataclass(frozen=True)
class RebootOptions:
    """``limbctl reboot``: reboot the rig's servos that are in alarm (say what each alarm was)."""

    connection: Connection = field(default_factory=Connection)


def run_reboot(options: RebootOptions) -> int:
    """Reboot every servo in alarm and read their alarms again; 0 when every servo is clear
    (also when none was in alarm), 3 when one is in alarm again at once (its cause remains)."""
    from limbctl.servo.alarms import reboot_servos_in_alarm

    conn = options.connection
    with open_rig(
        conn.port, conn.rig, conn.baud, seed=conn.seed, latency_timer_ms=conn.latency_timer_ms
    ) as session:
        bus = session.rig.bus
        rebooted = reboot_servos_in_alarm(bus)
        ids = ", ".join(str(i) for i in bus.ids)
        # a cause that remains (a low supply, a hot motor) raises the alarm again at once
        again = {i: bits for i, bits in bus.read_hardware_errors().items() if bits}
    if not rebooted:
        say(f"no servo is in alarm (servos {ids} report no hardware error): nothing rebooted")
        return 0
    for servo in rebooted:
        say(servo.describe())
    for servo_id, bits in again.items():
        say(
            f"servo {servo_id} is in alarm again right after its reboot ({', '.join(bits)}): "
            f"its cause is still there; fix it (supply voltage, temperature, load), then "
            f"`limbctl reboot` again"
        )
    say(
        "torque is off and RAM settings are back at their defaults: the next record, teleop or "
        "calibrate sets them again"
    )
    return 3 if again else 0
