"""Command source ``page``: the live view's page steers the limb (drag, click, arrow keys).

The page sends the same JSON lines as every other source (``{"pan": deg, "tilt": deg}``) over
its WebSocket; the view's server hands the controlling page's text to :meth:`CommandSource.feed`,
so it meets the same parser, the same refusal accounting and the same gate. The page repeats its
command while it holds control; a page that freezes, closes or loses its network stops sending,
and the loop holds the last safe pose after its silence, exactly as for a silent stream.

Who may control, and how, is the view's business (a per-session secret, the Origin, one
controller at a time, taken only by a person's action: opening the address, reloading the
steering tab or clicking "take control", never by a page reconnecting on its own; see
:mod:`limbctl.view.control`): this source only needs a ``connect`` that attaches its ``feed`` to
the page and returns what detaches it again.
"""

from __future__ import annotations

from collections.abc import Callable

from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Attaches a text sink to the page's controller, returns the detach and a "who holds control".
Connect = Callable[[Callable[[str], None]], tuple[Callable[[], None], Callable[[], str]]]


class PageSource(CommandSource):
    """Commands from the page that holds control of the live view.

    Parameters
    ----------
    connect : callable
        ``connect(feed)`` attaches ``feed`` to the view's controller and returns
        ``(detach, holder)``: ``detach()`` stops the text, ``holder()`` says who controls.
    """

    name = "page"
    latest_only = True
    explains = True

    def __init__(self, connect: Connect) -> None:
        super().__init__()
        self._connect = connect
        self._holder: Callable[[], str] = lambda: "nobody"

    def describe(self) -> str:
        """Who steers, for the status line."""
        return f"page: {self._holder()}"

    def _run(self) -> None:
        detach, self._holder = self._connect(self.feed)
        try:
            # the text arrives on the view's thread; this one only waits for the close
            while not self._stop.wait(WAKE_INTERVAL_S):
                pass
        finally:
            detach()
