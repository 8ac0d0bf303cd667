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
    """Reboot every servo in alarm; 0 (also when none was), errors raised as usual."""
    from limbctl.servo.alarms import reboot_servos_in_alarm

    conn = options.connection
    with open_rig(
        conn.port, conn.rig, conn.baud, seed=conn.seed, latency_timer_ms=conn.latency_timer_ms
    ) as session:
        rebooted = reboot_servos_in_alarm(session.rig.bus)
        ids = ", ".join(str(i) for i in session.rig.bus.ids)
    if not rebooted:
        say(f"no servo is in alarm (servos {ids} report no hardware error): nothing rebooted")
        return 0
    for servo in rebooted:
        say(servo.describe())
    say(
        "torque is off and RAM settings are back at their defaults: the next record, teleop or "
        "calibrate sets them again"
    )
    return 0
