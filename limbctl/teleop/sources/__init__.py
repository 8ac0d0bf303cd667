"""Command sources for teleoperation, one :data:`SOURCES` entry per scheme."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from limbctl.errors import ConfigError
from limbctl.teleop.sources.base import CommandSource, SourceStats
from limbctl.teleop.sources.keyboard import KeyboardSource, keyboard_source
from limbctl.teleop.sources.leader import LeaderSource
from limbctl.teleop.sources.leader_ids import check_leader_fits, leader_ids
from limbctl.teleop.sources.lines import PageSource, ReplaySource, StreamSource, UdpSource

__all__ = ["CommandSource", "SourceStats", "KeyboardSource", "LeaderSource", "ReplaySource"]
__all__ += ["check_leader_fits"]
__all__ += ["StreamSource", "UdpSource", "SOURCES", "SOURCE_FORMS", "SourceContext"]
__all__ += ["SourceKind", "SourceSpec", "parse_source", "open_source", "PageSource"]


@dataclass(frozen=True)
class SourceContext:
    """What a source may need of the job that opens it: the open ``rig`` (its bus holds the spec's
    ``extra_ids``), the ``gate`` (the keyboard starts from its pose), ``page`` (attaches the page
    source, :data:`~limbctl.teleop.sources.lines.Connect`) and ``twist`` (commands keep it)."""

    rig: Any = None
    #: The loop's rate (Hz): a felt leader checks at start that its cycle keeps it.
    rate_hz: float = 200.0
    gate: Any = None
    page: Any = None
    twist: bool = False

    @property
    def takes_twist(self) -> bool:
        """True for a three-servo rig (its profile has a roll joint) or when asked."""
        profile = getattr(self.rig, "profile", None)
        return self.twist or getattr(profile, "roll", None) is not None


@dataclass(frozen=True)
class SourceKind:
    """One scheme of command source: its prefix (``udp``), its written form, ``build(argument,
    context)`` making an unstarted source and the ``extra_ids(argument)`` the bus must hold."""

    scheme: str
    form: str
    build: Callable[[str, SourceContext], CommandSource]
    extra_ids: Callable[[str], tuple[int, ...]] = lambda argument: ()


def _no_argument(scheme: str, make: Callable[[SourceContext], CommandSource]) -> Callable:
    def build(argument: str, context: SourceContext) -> CommandSource:
        if argument:
            raise ConfigError(f"source {scheme!r} takes no argument, got {scheme}:{argument}")
        return make(context)

    return build


def _udp(argument: str, context: SourceContext) -> CommandSource:
    host, sep, port = argument.removeprefix("//").rpartition(":")
    if not argument.startswith("//") or not sep or not port.isdigit() or not host:
        raise ConfigError(f"bad UDP source 'udp:{argument}'; expected udp://127.0.0.1:PORT")
    return UdpSource(host, int(port))


def _page(context: SourceContext) -> CommandSource:
    if context.page is None:
        raise ConfigError("source 'page' steers from the live view: do not pass --no-view")
    return PageSource(context.page)


def _leader(argument: str, context: SourceContext) -> CommandSource:
    if context.rig is None:
        raise ConfigError(f"source 'leader:{argument}' reads servos: it needs the open rig")
    return LeaderSource(context.rig, leader_ids(argument), rate_hz=context.rate_hz)


#: Every command source by scheme.
SOURCES: dict[str, SourceKind] = {
    kind.scheme: kind
    for kind in (
        SourceKind("stdin", "stdin", _no_argument("stdin", lambda context: StreamSource())),
        SourceKind("udp", "udp://HOST:PORT", _udp),
        SourceKind("replay", "replay:FILE", lambda argument, context: ReplaySource(argument)),
        SourceKind(
            "keyboard", "keyboard", _no_argument("keyboard", lambda c: keyboard_source(c.gate))
        ),
        SourceKind("leader", "leader:ID,ID", _leader, extra_ids=leader_ids),
        SourceKind("page", "page", _no_argument("page", _page)),
    )
}
#: How each source is written, in the order of :data:`SOURCES`.
SOURCE_FORMS = tuple(kind.form for kind in SOURCES.values())


@dataclass(frozen=True)
class SourceSpec:
    """A checked source spec: its kind and the text after the scheme."""

    kind: SourceKind
    argument: str

    @property
    def extra_ids(self) -> tuple[int, ...]:
        """Servo ids the bus must hold besides the rig's."""
        return self.kind.extra_ids(self.argument)

    def open(self, context: SourceContext | None = None) -> CommandSource:
        """Build the source (not yet started); on a three-servo rig its lines keep their twist."""
        context = context or SourceContext()
        source = self.kind.build(self.argument, context)
        source.twist = context.takes_twist
        return source


def parse_source(spec: str) -> SourceSpec:
    """Check a source spec such as ``stdin``, ``udp://127.0.0.1:9000`` or ``leader:3,4``
    (ConfigError for an unknown scheme, listing the accepted forms, or a malformed argument)."""
    scheme, _, argument = spec.partition(":")
    kind = SOURCES.get(scheme)
    if kind is None:
        raise ConfigError(f"unknown source {spec!r}; choose one of {', '.join(SOURCE_FORMS)}")
    kind.extra_ids(argument)  # a malformed id list is refused before anything opens
    return SourceSpec(kind, argument)


def open_source(spec: str, context: SourceContext | None = None) -> CommandSource:
    """Build a command source from its spec (see :func:`parse_source`)."""
    return parse_source(spec).open(context)
