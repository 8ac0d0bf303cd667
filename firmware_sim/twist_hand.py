"""A scripted hand that also turns the limb about its own axis, within a twist band.

:class:`TwistHand` moves the swing as a :class:`firmware_sim.hand.Hand` does and adds the twist,
read from a REGION.yaml with a ``twist:`` section (:mod:`firmware_sim.twist_band`). It teaches as
the protocol asks: while the swing hand traces the edge, the twist goes to both stops along the
way (a cycle of TRACE_TWIST_CYCLE: to one stop, hold, to the other, hold); afterwards, while
the swing wanders, the twist wanders too, and every STOP_EVERY-th twist move goes to a stop
(alternately the upper and the lower one), so the middle is taught to its stops as well. The
twist's position in the band is ``u`` in [-1, 1]: the twist is ``centre + u (half_width -
TWIST_INSET_DEG)`` at the present swing pose (so it follows the band as the swing moves), plus
a tremor. :meth:`TwistHand.pose_deg` returns (pan, tilt, roll) with
the roll that gives that twist at that swing (``roll = twist - chain_twist(pan, tilt)``).
The path is a function of the seed and the pose the hand took hold at, as for :class:`Hand`.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import yaml

from firmware_sim.hand import DEFAULT_TREMOR_DEG, PAUSE_S, TREMOR_BAND_HZ, Hand
from firmware_sim.orientation import chain_twist, roll_for_twist_deg, wrap_deg
from firmware_sim.twist_band import TwistBand

#: How far inside each twist stop (deg) the hand turns: as the swing trace keeps EDGE_INSET_DEG
#: (1 deg) from the swing edge, a person feels the stop and backs off about a degree.
TWIST_INSET_DEG = 1.0
#: Along the edge trace, one cycle to both stops: (u target, move s, hold s) steps. 0.9 s a
#: cycle at the trace's 18 deg/s reaches each stop about every 16 deg of edge, so a band limit
#: bridged between stops sags well under a degree (ENVELOPE_CURVATURE in
#: limbctl/region/twist_band.py). The earlier cycle (one stop, the other, the middle: 2.2 s, each
#: stop every 40 deg of edge) left the demo region's inner orientations 13 deg from the nearest
#: stop at the 90th percentile, and its 60 s teaching held 65 % of them (docs/decisions/twist.md;
#: at six seconds a cycle half widths came out ~20 deg short, docs/decisions/hand.md).
TRACE_TWIST_CYCLE = ((1.0, 0.4, 0.05), (-1.0, 0.4, 0.05))
#: Wandering: every STOP_EVERY-th twist move goes to a stop, alternately the upper and the lower
#: one; the others to a uniform draw in the band. 1: every move, so the twist keeps turning from
#: stop to stop while the swing wanders (a place passed once still sees both stops). A move over
#: the whole band takes WANDER_MOVE_S[1] s, a short one at least WANDER_MOVE_S[0] (a brisk
#: wrist turns through its range in under half a second), and each ends in a hold of
#: WANDER_HOLD_S (a touch of the stop). At (0.3, 0.8) and (0.05, 0.2) s the swing's 40 deg/s
#: carried the limb ~70 deg between two visits of the same stop, at these ~35.
STOP_EVERY = 1
WANDER_MOVE_S = (0.2, 0.4)
WANDER_HOLD_S = (0.03, 0.08)
#: The twist tremor's amplitude as a fraction of the hand's tremor_deg (one sine: the wrist's
#: tremor about the forearm is about half that of the swing).
TWIST_TREMOR_FRACTION = 0.5


class TwistHand:
    """A swing hand plus a twist band; ``pose_deg(t)`` gives (pan_deg, tilt_deg, roll_deg).

    Parameters
    ----------
    swing : Hand
        A region hand (not a script): it moves pan and tilt.
    band : TwistBand
        The allowed twist at each swing pose.
    seed : int
        Draws the twist's wander and tremor.
    """

    #: The world gives this hand the roll joint too (see :meth:`firmware_sim.world.World.set_hand`).
    turns_roll = True

    def __init__(self, swing: Hand, band: TwistBand, seed: int = 0) -> None:
        if swing.region is None:
            raise ValueError("a twist hand needs a region hand for its swing, not a script")
        self.swing = swing
        self.band = band
        self._seed = seed
        rng = np.random.default_rng([seed, 7])
        self._tremor = (
            TWIST_TREMOR_FRACTION * swing.tremor_deg,
            2.0 * math.pi * float(rng.uniform(*TREMOR_BAND_HZ)),
            float(rng.uniform(0.0, 2.0 * math.pi)),
        )
        self.start_from(*swing.region.center_deg, 0.0)

    @property
    def region(self):
        """The swing outline (as :attr:`Hand.region`)."""
        return self.swing.region

    @property
    def trace_span_s(self) -> tuple[float, float] | None:
        """(start, end) s of the swing's full edge trace (as :attr:`Hand.trace_span_s`)."""
        return self.swing.trace_span_s

    def start_from(self, pan_deg: float, tilt_deg: float, roll_deg: float = 0.0) -> None:
        """Take hold of the limb at (pan, tilt, roll) deg; the twist starts where it is."""
        self.swing.start_from(pan_deg, tilt_deg)
        self._rng = np.random.default_rng([self._seed, 8])
        twist = roll_deg + math.degrees(chain_twist(math.radians(pan_deg), math.radians(tilt_deg)))
        self._t0: list[float] = [0.0]
        self._segments: list[tuple[float, float, float, float]] = []
        self._moves = 0
        self._cycle_step = 0
        u = self._u_of(pan_deg, tilt_deg, twist)
        self._segments.append((0.0, PAUSE_S[0], u, u))
        self._current = 0

    def _u_of(self, pan_deg: float, tilt_deg: float, twist_deg: float) -> float:
        low, high = self.band.limits_deg(pan_deg, tilt_deg)
        centre, reach = (low + high) / 2.0, (high - low) / 2.0 - TWIST_INSET_DEG
        return min(max(wrap_deg(twist_deg - centre) / reach, -1.0), 1.0)

    def _plan_next(self) -> None:
        t0, t1, _, u_end = self._segments[-1]
        span = self.swing.trace_span_s
        tracing = span is not None and t1 < span[1]
        if tracing:
            target, move_s, hold_s = TRACE_TWIST_CYCLE[self._cycle_step % len(TRACE_TWIST_CYCLE)]
            self._cycle_step += 1
        else:
            self._moves += 1
            if self._moves % STOP_EVERY == 0:
                target = 1.0 if (self._moves // STOP_EVERY) % 2 else -1.0
            else:
                target = float(self._rng.uniform(-1.0, 1.0))
            fraction = abs(target - u_end) / 2.0
            move_s = WANDER_MOVE_S[0] + fraction * (WANDER_MOVE_S[1] - WANDER_MOVE_S[0])
            hold_s = float(self._rng.uniform(*WANDER_HOLD_S))
        self._append(t1, t1 + move_s, u_end, target)
        self._append(t1 + move_s, t1 + move_s + hold_s, target, target)

    def _append(self, t0: float, t1: float, u0: float, u1: float) -> None:
        self._t0.append(t0)
        self._segments.append((t0, t1, u0, u1))

    def band_position(self, t: float) -> float:
        """``u`` in [-1, 1]: where in the band the twist is held ``t`` s after taking hold."""
        while self._segments[-1][1] <= t:
            self._plan_next()
        k = self._current
        t0, t1, _, _ = self._segments[k]
        if not t0 <= t < t1:
            k = max(bisect.bisect_right(self._t0, t) - 1, 0)
            self._current = k
        t0, t1, u0, u1 = self._segments[k]
        s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
        # minimum-jerk profile: s' = 10 s^3 - 15 s^4 + 6 s^5
        s = s * s * s * (10.0 + s * (-15.0 + 6.0 * s))
        return u0 + s * (u1 - u0)

    def pose_deg(self, t: float) -> tuple[float, float, float]:
        """(pan_deg, tilt_deg, roll_deg) the hand holds the limb at, ``t`` >= 0 s after hold."""
        pan, tilt = self.swing.pose_deg(t)
        low, high = self.band.limits_deg(pan, tilt)
        centre, reach = (low + high) / 2.0, (high - low) / 2.0 - TWIST_INSET_DEG
        amplitude, omega, phase = self._tremor
        twist = centre + self.band_position(t) * reach + amplitude * math.sin(omega * t + phase)
        return float(pan), float(tilt), roll_for_twist_deg(pan, tilt, twist)

    def twist_deg(self, pan_deg: float, tilt_deg: float, roll_deg: float) -> float:
        """The twist (deg, in (-180, 180]) of a pose: ``roll + chain_twist(pan, tilt)``."""
        tau = chain_twist(math.radians(pan_deg), math.radians(tilt_deg))
        return wrap_deg(roll_deg + math.degrees(tau))


class RollScriptHand:
    """A script hand that also turns the roll: ``script: [[t_s, pan, tilt, roll], ...]`` (deg),
    linear in time between the waypoints, the first held before and the last after them (as a
    :class:`Hand` script). Used where the simulator's "person" follows prompts, e.g. a
    calibration of the roll joint."""

    turns_roll = True
    region = None
    trace_span_s = None

    def __init__(self, script: object, tremor_deg: float, seed: int, source: str) -> None:
        rows = script if isinstance(script, (list, tuple)) else []
        swing_rows, rolls = [], []
        for k, row in enumerate(rows):
            if not isinstance(row, (list, tuple)) or len(row) != 4:
                raise ValueError(
                    f"{source}: script[{k}] must be [t_s, pan_deg, tilt_deg, roll_deg] like the "
                    f"first row, got {row!r}"
                )
            swing_rows.append(list(row[:3]))
            rolls.append(row[3])
        data = {"script": swing_rows, "tremor_deg": tremor_deg}
        self.swing = Hand.from_mapping(data, seed=seed, source=source)
        for k, value in enumerate(rolls):
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{source}: script[{k}] roll must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"{source}: script[{k}] roll must be finite, got {value!r}")
        self._times = [float(row[0]) for row in swing_rows]
        self._rolls = [float(v) for v in rolls]

    def start_from(self, pan_deg: float, tilt_deg: float, roll_deg: float = 0.0) -> None:
        """A script says where the limb is: nothing to do."""

    def pose_deg(self, t: float) -> tuple[float, float, float]:
        """(pan_deg, tilt_deg, roll_deg) at ``t`` s after the hand took hold."""
        pan, tilt = self.swing.pose_deg(t)
        # roll = linear between waypoints, held outside them
        return float(pan), float(tilt), float(np.interp(t, self._times, self._rolls))


def hand_from_mapping(
    data: object, seed: int = 0, source: str = "<mapping>"
) -> Hand | TwistHand | RollScriptHand:
    """A :class:`TwistHand` when the REGION.yaml mapping has ``twist:``, a
    :class:`RollScriptHand` for a script whose rows carry a roll, else a :class:`Hand`."""
    if isinstance(data, Mapping) and isinstance(data.get("script"), list):
        first = data["script"][0] if data["script"] else None
        if isinstance(first, (list, tuple)) and len(first) == 4:
            extra = sorted(set(data) - {"script", "tremor_deg"}, key=str)
            if extra:
                raise ValueError(
                    f"{source}: a script hand takes script and tremor_deg, not {extra}"
                )
            tremor = data.get("tremor_deg", DEFAULT_TREMOR_DEG)
            return RollScriptHand(data["script"], tremor, seed, source)
    if isinstance(data, Mapping) and "twist" in data:
        rest = {k: v for k, v in data.items() if k != "twist"}
        if "script" in rest:
            raise ValueError(f"{source}: 'twist' applies to a region hand, not to a script")
        swing = Hand.from_mapping(rest, seed=seed, source=source)
        return TwistHand(swing, TwistBand.from_mapping(data["twist"], swing.region, source), seed)
    return Hand.from_mapping(data, seed=seed, source=source)


def hand_from_yaml(path: str | Path, seed: int = 0) -> Hand | TwistHand | RollScriptHand:
    """A hand from a REGION.yaml file (with or without ``twist:``); ValueError names the file."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise ValueError(f"{path}: cannot read the region file ({exc.strerror})") from exc
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: not valid YAML ({exc})") from exc
    return hand_from_mapping(data, seed=seed, source=str(path))
