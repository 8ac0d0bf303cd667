"""The jobs' side of the live view: open it, feed it from a recording and from the teleop loop."""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from limbctl.errors import ConfigError
from limbctl.teach.guide import Guidance
from limbctl.teach.twist_guide import CELL_DEG, MIN_CELL_SAMPLES, TwistGuidance
from limbctl.teleop.cycle import Cycle
from limbctl.teleop.explain import PLANE_NAMES, explain
from limbctl.view import (
    Board,
    GuideFigure,
    HardLimits,
    Live,
    PanTilt,
    Scene,
    TeleopStatus,
    ViewServer,
)
from limbctl.view.feed import PoseTap, SceneFeeder
from limbctl.view.leader import LeaderLive, LeaderStatus, with_twist
from limbctl.view.region import model_loops
from limbctl.view.server import DEFAULT_PORT
from limbctl.view.twist import band_gauge, model_band_map, pose_twist, taught_map

#: How often the teleop loop's shown rate is recomputed (s): steady to read, recent enough.
RATE_WINDOW_S = 1.0


@dataclass(frozen=True)
class ViewOptions:
    """Whether (None: when stderr is a terminal) and where (``port`` None: :data:`DEFAULT_PORT`,
    or any free port when taken) to serve the live view."""

    enabled: bool | None = None
    host: str = "127.0.0.1"
    port: int | None = None

    def wanted(self) -> bool:
        """Whether to serve the view."""
        if self.enabled is not None:
            return self.enabled
        return bool(getattr(sys.stderr, "isatty", lambda: False)())


def rig_limits(profile: Any) -> HardLimits:
    """A rig profile's hard joint limits for the view."""
    return HardLimits(
        (profile.pan.min_deg, profile.pan.max_deg), (profile.tilt.min_deg, profile.tilt.max_deg)
    )


@dataclass(frozen=True)
class Teaching:
    """The recorder's side of a live teaching: the ``limb`` to read, the guides' hooks (None: not
    shown) and the scene ``feeder``."""

    limb: Any
    on_guidance: Callable[[Guidance], None] | None
    feeder: SceneFeeder | None = None
    on_twist: Callable[[TwistGuidance], None] | None = None


def guide_figures(guidance: Guidance) -> tuple[tuple[GuideFigure, ...], str]:
    """The guide's assessment as the page shows it: its figures and its one-line advice."""
    figures = (
        GuideFigure("edge closed", 100.0 * guidance.edge_closed, "%"),
        GuideFigure("inside covered", 100.0 * guidance.inside_covered, "%"),
        GuideFigure("edge gaps", len(guidance.edge_gaps)),
        GuideFigure("inside gaps", len(guidance.inside_gaps)),
    )
    return figures, guidance.line()


def twist_figures(twist: TwistGuidance) -> tuple[GuideFigure, ...]:
    """The twist guide's assessment as the page's guide figures (a three-servo rig)."""
    return (
        GuideFigure("twist: places judged", twist.cells),
        GuideFigure("twist: turned both ways", twist.turned),
        GuideFigure("twist: widest span", twist.wide_span_deg, "deg"),
    )


class TwistTeaching:
    """Hands the guide's assessments to the view, and a three-servo teaching's twist cells."""

    def __init__(self, feeder: SceneFeeder, tap: PoseTap) -> None:
        self.feeder = feeder
        self.tap = tap
        self.guidance: Guidance | None = None
        self.twist: TwistGuidance | None = None

    def on_guidance(self, guidance: Guidance) -> None:
        self.guidance = guidance
        self._show()

    def on_twist(self, twist: TwistGuidance) -> None:
        self.twist = twist
        shown = taught_map(twist.places, CELL_DEG, MIN_CELL_SAMPLES)
        self.tap.set_twist_map(shown)
        self.feeder.set_twist(shown)
        self._show()

    def _show(self) -> None:
        figures, advice = guide_figures(self.guidance) if self.guidance else ((), "")
        if self.twist is not None:
            figures += twist_figures(self.twist)
            advice = f"{advice}; {self.twist.line()}" if advice else self.twist.line()
        self.feeder.set_guide(figures, advice)


class LiveView:
    """An open live view on ``board`` at ``url`` from ``server``; with no board, none."""

    def __init__(
        self, board: Board | None = None, url: str = "", server: ViewServer | None = None
    ) -> None:
        self.board = board
        self.url = url
        self.server = server

    @property
    def control_url(self) -> str:
        """The address that steers (with the session's secret); "" when off."""
        return self.server.control_url if self.server is not None else ""

    @property
    def page_connect(self):
        """How a page source attaches to the controller slot (None when off)."""
        return self.server.desk.attach if self.server is not None else None

    @property
    def active(self) -> bool:
        return self.board is not None

    @contextlib.contextmanager
    def teaching(self, limb: Any, profile: Any, mode: str = "record") -> Iterator[Teaching]:
        """What the recorder reads and tells while the view shows the teaching (a pose tap)."""
        if self.board is None:
            yield Teaching(limb, None)
            return
        tap = PoseTap(limb, self.board, mode, note="torque off: move the limb by hand")
        with SceneFeeder(self.board, tap.samples, rig_limits(profile)) as feeder:
            shown = TwistTeaching(feeder, tap)
            on_twist = shown.on_twist if getattr(profile, "twists", False) else None
            yield Teaching(tap, shown.on_guidance, feeder, on_twist)

    def start_observer(self, mode: str = "teleop: waiting") -> Callable[[Any], None] | None:
        """Publishes each StartStatus while teleop waits for a limb outside; None if off."""
        board = self.board
        if board is None:
            return None

        def publish(status: Any) -> None:
            pose = PanTilt(*status.pose_deg[:2])
            board.publish_live(Live(mode, pose, note=status.line()))

        return publish

    def teleop_observer(
        self, envelope: Any, profile: Any, mode: str = "teleop"
    ) -> Callable[[Cycle], None] | None:
        """Show the model's region and the rig's limits; the loop's ``on_cycle`` (None if off)."""
        if self.board is None:
            return None
        loops = model_loops(envelope)
        kind = getattr(envelope, "kind", type(envelope).__name__)
        note = f"the {kind} model's region" if loops else f"a {kind} model: region not drawn"
        limits = rig_limits(profile)
        twist = None
        if getattr(profile, "twists", False):  # three servos: the learned band too
            twist = model_band_map(envelope, limits.pan_deg, limits.tilt_deg)
        self.board.publish_scene(Scene(loops=loops, limits=limits, region_note=note, twist=twist))
        feed = TeleopFeed(self.board, mode)
        if twist is not None:
            feed.band = envelope.region.band
        return feed


class TeleopFeed:
    """The teleop loop's ``on_cycle``: publishes each cycle's poses, outcome and rate, quickly."""

    def __init__(self, board: Board, mode: str = "teleop") -> None:
        self.board = board
        self.mode = mode
        self.written: PanTilt | None = None
        self.present: PanTilt | None = None
        self.rate_hz = 0.0
        self._window_start: tuple[int, float] | None = None
        #: A felt leader's push now (N m), said in the note each cycle; None: it does not push.
        self.push_nm: Callable[[], float] | None = None
        #: The model's twist band (a three-servo rig; None on two servos): the gauge's range.
        self.band: Any = None
        self.written_twist: float | None = None
        self.gauge = None
        #: A leader source's part of the page (:func:`leader_status`); None: no leader.
        self.leader: Callable[[], LeaderStatus] | None = None

    def __call__(self, cycle: Cycle) -> None:
        previous = self.written
        if cycle.written and cycle.result is not None:
            written = cycle.result.pose
            self.written = PanTilt.of_rad(written)
            if len(written) == 3:
                self.written_twist = pose_twist(*written)
        self._update_rate(cycle)
        if cycle.present is not None:
            self.present = PanTilt.of_rad(cycle.present)
        commanded = PanTilt(*cycle.command_deg) if cycle.command_deg is not None else None
        outcome = cycle.result.outcome.value if cycle.result is not None else cycle.state.value
        if cycle.result is not None and cycle.result.reason:
            outcome += f" ({cycle.result.reason})"
        before = (previous.pan_deg, previous.tilt_deg) if previous is not None else None
        told = explain(cycle.result, cycle.command_deg, before, PLANE_NAMES)
        status = TeleopStatus(
            commanded, self.written, outcome, self.rate_hz, cycle.index, told.words, told.blocked
        )
        note = f"ended by {cycle.ended_by}" if cycle.ended_by else "every command through the gate"
        if self.push_nm is not None and not cycle.ended_by:
            push = self.push_nm()
            note = f"the leader pushes back with {push:.2f} N m" if push else "the leader is free"
        if self.band is not None and cycle.present is not None and len(cycle.present) == 3:
            self.gauge = band_gauge(self.band, cycle.present, self.written_twist)
        live = Live(
            self.mode, self.present, teleop=status, fault=cycle.fault, note=note, twist=self.gauge
        )
        if self.leader is not None:
            live = LeaderLive(**vars(live), leader=self.leader())
        self.board.publish_live(live)

    def _update_rate(self, cycle: Cycle) -> None:
        """rate = cycles completed / time, over the last RATE_WINDOW_S."""
        if self._window_start is None:
            self._window_start = (cycle.index, cycle.t)
            return
        first_index, first_t = self._window_start
        if cycle.t - first_t >= RATE_WINDOW_S:
            self.rate_hz = (cycle.index - first_index) / (cycle.t - first_t)
            self._window_start = (cycle.index, cycle.t)


def leader_status(source: Any) -> Callable[[], LeaderStatus]:
    """What the page shows of a leader source each cycle: pose, a felt leader's push, twist."""

    def status() -> LeaderStatus:
        pose, push = source.last_pose, source.last_push
        if pose is None or len(pose) == 2:  # two servos, or not read yet
            return plain()
        goal = getattr(push, "goal", None) if push is not None and push.torque_nm else None
        return with_twist(plain(), pose, goal if source.felt else None)

    def plain() -> LeaderStatus:
        pose = source.last_pose
        shown = PanTilt.of_rad(pose) if pose else None
        if not source.felt:
            events = source.feel_stats.events
            return LeaderStatus(shown, state=events[-1] if events else source.notice)
        push, read = source.last_push, source.last_torque_nm
        # sensed = |tau| over the joints, as their Present Current reads
        sensed = None if read is None else math.hypot(*read)
        if push is None or push.torque_nm == 0.0:
            beyond = push.distance_deg if push is not None else None
            return LeaderStatus(shown, 0.0, source.cap_nm, None, beyond, "free", sensed_nm=sensed)
        toward = PanTilt.of_rad(push.goal)
        return LeaderStatus(
            shown,
            push.torque_nm,
            source.cap_nm,
            toward,
            push.distance_deg,
            "pushing back",
            sensed_nm=sensed,
        )

    return status


@contextlib.contextmanager
def open_view(options: ViewOptions, say: Callable[[str], None]) -> Iterator[LiveView]:
    """Serve the live view if wanted (printing its address) and stop it on exit."""
    if not options.wanted():
        yield LiveView()
        return
    board = Board()
    try:
        port = DEFAULT_PORT if options.port is None else options.port
        server = ViewServer(board, options.host, port)
        server.start()
    except ConfigError:
        if options.port is not None:
            raise
        server = ViewServer(board, options.host, 0)
        server.start()
    try:
        say(f"live view: {server.url}")
        yield LiveView(board, server.url, server)
    finally:
        server.stop()
