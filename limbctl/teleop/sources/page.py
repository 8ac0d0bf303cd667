"""Command source ``page``: the live view's page steers the limb (drag, click, arrow keys)."""

from __future__ import annotations

from collections.abc import Callable

from limbctl.teleop.sources.base import WAKE_INTERVAL_S, CommandSource

#: Attaches a text sink to the page's controller, returns the detach and a "who holds control".
Connect = Callable[[Callable[[str], None]], tuple[Callable[[], None], Callable[[], str]]]


class PageSource(CommandSource):
    """Commands from the page that holds control of the live view; ``connect(feed)`` attaches
    ``feed`` to its controller and returns ``(detach, holder)`` (see :data:`Connect`)."""

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
