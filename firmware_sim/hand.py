"""Scripted hands that backdrive the simulated limb while its torque is off (REGION.yaml's form:
docs/simulator.md). A region hand moves pan and tilt along a
:class:`firmware_sim.hand_path.SwingPath` plus a tremor; with a twist band the twist is ``centre + u
(half_width - TWIST_INSET_DEG)``, ``u`` in [-1, 1] moving stop to stop, plus a tremor. The path is a
function of the seed and where it took hold."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml

from firmware_sim.hand_path import (
    DEFAULT_SPEED_DEG_S,
    DEFAULT_STYLE,
    MIN_REGION_DEPTH_DEG,
    PAUSE_S,
    STYLES,
    VISIT_EDGE_DEG,
    VISIT_KINDS,
    SwingPath,
    Track,
    Visit,
    progress,
)
from firmware_sim.orientation import chain_twist, roll_for_twist_deg, wrap_deg
from firmware_sim.regions import Region, region_from_mapping
from firmware_sim.twist_band import TwistBand

#: Peak tremor amplitude (deg): a hand steadying a light limb trembles a few tenths of a degree.
DEFAULT_TREMOR_DEG = 0.2
#: Physiological tremor band (Hz) the two tremor components per axis are drawn from.
TREMOR_BAND_HZ = (7.0, 12.0)
#: The twist tremor (one sine) as a fraction of tremor_deg: a wrist trembles half as much.
TWIST_TREMOR_FRACTION = 0.5
#: How far inside each twist stop (deg) the hand turns: it feels the stop and backs off.
TWIST_INSET_DEG = 1.0
#: Along the edge trace, one 0.9 s cycle to both stops, (u target, move s, hold s): a stop every
#: ~16 deg of edge, so a bridged band limit sags under a degree (docs/decisions/twist.md).
TRACE_TWIST_CYCLE = ((1.0, 0.4, 0.05), (-1.0, 0.4, 0.05))
#: Wandering, each twist move goes to the other stop over WANDER_MOVE_S s, then holds (s).
WANDER_MOVE_S = (0.2, 0.4)
WANDER_HOLD_S = (0.03, 0.08)

_TOP_LEVEL_KEYS = {"region", "script", "twist", "speed_deg_s", "tremor_deg", "style", "visits"}
_VISIT_KEYS = {"after_s", "at", "do", "length_deg"}
_COLUMNS = ("t_s", "pan_deg", "tilt_deg", "roll_deg")


def _positive(data: dict, key: str, default: float, source: str, allow_zero: bool) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{source}: {key} must be a finite number, got {value!r}")
    if value < 0 or (value == 0 and not allow_zero):
        raise ValueError(f"{source}: {key} must be {'>= 0' if allow_zero else '> 0'}, got {value}")
    return float(value)


def _parse_script(script: object, source: str) -> list[tuple[float, ...]]:
    """Rows of 3 numbers, or of 4 (with a roll) when the first row has 4; times increasing."""
    if not isinstance(script, (list, tuple)) or len(script) == 0:
        raise ValueError(f"{source}: script must be a non-empty list of [t_s, pan_deg, tilt_deg]")
    first = script[0]
    width = 4 if isinstance(first, (list, tuple)) and len(first) == 4 else 3
    columns = f"[{', '.join(_COLUMNS[:width])}]"
    waypoints: list[tuple[float, ...]] = []
    for k, row in enumerate(script):
        if not isinstance(row, (list, tuple)) or len(row) != width:
            raise ValueError(f"{source}: script[{k}] must be {columns} like row 0, got {row!r}")
        values = []
        for v in row:
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{source}: script[{k}] holds a non-finite or non-number {v!r}")
            values.append(float(v))
        if values[0] < 0 or (waypoints and values[0] <= waypoints[-1][0]):
            raise ValueError(
                f"{source}: script[{k}] time {values[0]} s must be >= 0 and later than the one "
                "before it"
            )
        waypoints.append(tuple(values))
    return waypoints


def _parse_visits(visits: object, source: str) -> list[Visit]:
    """``visits:`` entries as :class:`Visit`; ValueError names the entry and the problem."""
    if not isinstance(visits, (list, tuple)):
        raise ValueError(f"{source}: visits must be a list of {{after_s, at, do}} mappings")
    parsed = []
    for k, entry in enumerate(visits):
        where = f"{source}: visits[{k}]"
        if not isinstance(entry, dict) or not {"after_s", "at", "do"} <= set(entry):
            raise ValueError(f"{where} must be a mapping with after_s, at and do, got {entry!r}")
        unknown = sorted(set(entry) - _VISIT_KEYS, key=str)
        if unknown:
            raise ValueError(f"{where}: unknown key(s) {unknown}; allowed: {sorted(_VISIT_KEYS)}")
        if entry["do"] not in VISIT_KINDS:
            kinds = "; ".join(f"{name}: {meaning}" for name, meaning in VISIT_KINDS.items())
            raise ValueError(f"{where}: unknown do {entry['do']!r}; choose one of ({kinds})")
        at = entry["at"]
        if not isinstance(at, (list, tuple)) or len(at) != 2:
            raise ValueError(f"{where}: at must be [pan_deg, tilt_deg], got {at!r}")
        if not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in at
        ):
            raise ValueError(f"{where}: at must hold two finite numbers, got {at!r}")
        pan, tilt = at
        after = _positive(entry, "after_s", 0.0, where, allow_zero=True)
        length = _positive(entry, "length_deg", VISIT_EDGE_DEG, where, allow_zero=True)
        parsed.append(Visit(after, float(pan), float(tilt), entry["do"], length))
    return parsed


class Hand:
    """A scripted hand holding a ``region`` (with an optional twist ``band``) or following a
    ``script`` of (t_s, pan_deg, tilt_deg[, roll_deg]); build it with :meth:`from_yaml` or
    :meth:`from_mapping`. ``turns_roll``: whether :meth:`pose_deg` gives a roll."""

    def __init__(
        self,
        region: Region | None = None,
        script: list[tuple[float, ...]] | None = None,
        speed_deg_s: float = DEFAULT_SPEED_DEG_S,
        tremor_deg: float = DEFAULT_TREMOR_DEG,
        seed: int = 0,
        source: str = "<hand>",
        style: str = DEFAULT_STYLE,
        band: TwistBand | None = None,
        visits=(),
    ) -> None:
        if (region is None) == (script is None):
            raise ValueError(f"{source}: a Hand needs exactly one of region or script")
        if band is not None and region is None:
            raise ValueError(f"{source}: 'twist' applies to a region hand, not to a script")
        if style not in STYLES:
            choices = "; ".join(f"{name}: {meaning}" for name, meaning in STYLES.items())
            raise ValueError(f"{source}: unknown style {style!r}; choose one of ({choices})")
        if region is not None and region.depth_max_deg < MIN_REGION_DEPTH_DEG:
            raise ValueError(
                f"{source}: the region is too small for a hand to move in: its deepest point is "
                f"{region.depth_max_deg:.2f} deg inside; make it at least {MIN_REGION_DEPTH_DEG:g} "
                "deg deep"
            )
        self.style = style
        self.region = region
        self.script = script
        self.band = band
        self.turns_roll = band is not None or (script is not None and len(script[0]) == 4)
        self.speed_deg_s = float(speed_deg_s)
        self.tremor_deg = float(tremor_deg)
        self._seed = seed
        # per axis, two sines with frequencies in the tremor band; peak sum = tremor_deg
        tremor_rng = np.random.default_rng([seed, 0])
        freqs = tremor_rng.uniform(*TREMOR_BAND_HZ, size=4)
        phases = tremor_rng.uniform(0.0, 2.0 * math.pi, size=4)
        amps = self.tremor_deg * np.array([0.6, 0.4, 0.6, 0.4])
        self._tremor = [
            (float(a), 2.0 * math.pi * float(f), float(p))
            for a, f, p in zip(amps, freqs, phases, strict=True)
        ]
        if visits and region is None:
            raise ValueError(f"{source}: 'visits' apply to a region hand, not to a script")
        self.path = SwingPath(region, script, self.speed_deg_s, seed, style, visits)
        if script is not None and self.turns_roll:
            self._times = [row[0] for row in script]
            self._rolls = [row[3] for row in script]
        if band is not None:
            rng = np.random.default_rng([seed, 7])
            self._twist_tremor = (
                TWIST_TREMOR_FRACTION * self.tremor_deg,
                2.0 * math.pi * float(rng.uniform(*TREMOR_BAND_HZ)),
                float(rng.uniform(0.0, 2.0 * math.pi)),
            )
        if region is not None:
            self.start_from(*region.center_deg)

    def start_from(self, pan_deg: float, tilt_deg: float, roll_deg: float = 0.0) -> None:
        """Take hold at (pan_deg, tilt_deg, roll_deg): a region hand (re)starts its path there."""
        if self.script is not None:
            return
        self.path.start_from(pan_deg, tilt_deg)
        if self.band is None:
            return
        self._twist_rng = np.random.default_rng([self._seed, 8])
        twist = roll_deg + math.degrees(chain_twist(math.radians(pan_deg), math.radians(tilt_deg)))
        # the twist's segments (t0, t1, u0, u1), minimum-jerk in the band position u
        self._twist = Track()
        self._moves = 0
        self._cycle_step = 0
        u = self._u_of(pan_deg, tilt_deg, twist)
        self._twist.add(0.0, PAUSE_S[0], u, u)

    @classmethod
    def from_mapping(cls, data: object, seed: int = 0, source: str = "<mapping>") -> Hand:
        """A hand from a parsed REGION.yaml mapping; ValueError names ``source`` and the problem."""
        if not isinstance(data, dict):
            raise ValueError(
                f"{source}: expected a mapping with 'region' or 'script', got {data!r}"
            )
        unknown = sorted(set(data) - _TOP_LEVEL_KEYS, key=str)
        if unknown:
            raise ValueError(
                f"{source}: unknown key(s) {unknown}; allowed: {sorted(_TOP_LEVEL_KEYS)}"
            )
        if ("region" in data) == ("script" in data):
            raise ValueError(f"{source}: give exactly one of 'region' or 'script'")
        for key in ("style", "twist", "visits"):
            if key in data and "script" in data:
                raise ValueError(f"{source}: '{key}' applies to a region hand, not to a script")
        speed = _positive(data, "speed_deg_s", DEFAULT_SPEED_DEG_S, source, allow_zero=False)
        tremor = _positive(data, "tremor_deg", DEFAULT_TREMOR_DEG, source, allow_zero=True)
        common = {"speed_deg_s": speed, "tremor_deg": tremor, "seed": seed, "source": source}
        if "script" in data:
            return cls(script=_parse_script(data["script"], source), **common)
        region = region_from_mapping(data["region"], source)
        band = TwistBand.from_mapping(data["twist"], region, source) if "twist" in data else None
        visits = _parse_visits(data.get("visits", []), source)
        style = data.get("style", DEFAULT_STYLE)
        return cls(region=region, band=band, style=style, visits=visits, **common)

    @classmethod
    def from_yaml(cls, path: str | Path, seed: int = 0) -> Hand:
        """A hand from a REGION.yaml file; ValueError names the file and the problem."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text())
        except OSError as exc:
            raise ValueError(f"{path}: cannot read the region file ({exc.strerror})") from exc
        except yaml.YAMLError as exc:
            raise ValueError(f"{path}: not valid YAML ({exc})") from exc
        return cls.from_mapping(data, seed=seed, source=str(path))

    def pose_deg(self, t: float) -> tuple[float, ...]:
        """(pan_deg, tilt_deg[, roll_deg if :attr:`turns_roll`]) at ``t`` >= 0 s after hold."""
        if not math.isfinite(t):
            raise ValueError(f"Hand.pose_deg: t must be a finite time in s, got {t!r}")
        pan, tilt = self.path.at(t)
        (a0, w0, f0), (a1, w1, f1), (a2, w2, f2), (a3, w3, f3) = self._tremor
        pan += a0 * math.sin(w0 * t + f0) + a1 * math.sin(w1 * t + f1)
        tilt += a2 * math.sin(w2 * t + f2) + a3 * math.sin(w3 * t + f3)
        if not self.turns_roll:
            return pan, tilt
        if self.band is None:
            # a script's roll: linear between waypoints, held outside them, no tremor
            return float(pan), float(tilt), float(np.interp(t, self._times, self._rolls))
        low, high = self.band.limits_deg(pan, tilt)
        centre, reach = (low + high) / 2.0, (high - low) / 2.0 - TWIST_INSET_DEG
        amplitude, omega, phase = self._twist_tremor
        twist = centre + self._band_position(t) * reach + amplitude * math.sin(omega * t + phase)
        return float(pan), float(tilt), roll_for_twist_deg(pan, tilt, twist)

    def _u_of(self, pan_deg: float, tilt_deg: float, twist_deg: float) -> float:
        low, high = self.band.limits_deg(pan_deg, tilt_deg)
        centre, reach = (low + high) / 2.0, (high - low) / 2.0 - TWIST_INSET_DEG
        return min(max(wrap_deg(twist_deg - centre) / reach, -1.0), 1.0)

    def _band_position(self, t: float) -> float:
        """``u`` in [-1, 1]: where in the band the twist is held ``t`` s after taking hold."""
        while self._twist.segments[-1][1] <= t:
            self._plan_twist()
        t0, t1, u0, u1 = self._twist.at(t)
        s = progress(t, t0, t1)
        return u0 + s * (u1 - u0)

    def _plan_twist(self) -> None:
        """Append the twist's next move and hold: the trace's cycle, else a wander move."""
        t0, t1, _, u_end = self._twist.segments[-1]
        span = self.path.trace_span_s
        if (span is not None and t1 < span[1]) or self.path.in_visit(t1):
            target, move_s, hold_s = TRACE_TWIST_CYCLE[self._cycle_step % len(TRACE_TWIST_CYCLE)]
            self._cycle_step += 1
        else:
            self._moves += 1
            target = 1.0 if self._moves % 2 else -1.0
            fraction = abs(target - u_end) / 2.0
            move_s = WANDER_MOVE_S[0] + fraction * (WANDER_MOVE_S[1] - WANDER_MOVE_S[0])
            hold_s = float(self._twist_rng.uniform(*WANDER_HOLD_S))
        self._twist.add(t1, t1 + move_s, u_end, target)
        self._twist.add(t1 + move_s, t1 + move_s + hold_s, target, target)
