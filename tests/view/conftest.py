"""Fixtures of the page's browser tests: one headless Chromium per module, a served board."""

from __future__ import annotations

import pytest

from limbctl.view import Board, ViewServer
from tests.view.browser import chromium


@pytest.fixture(scope="module")
def browser():
    """Debian's headless Chromium through chromedriver, shared by a module's tests."""
    with chromium() as driver:
        yield driver


@pytest.fixture
def served():
    """A :class:`Board` served on a free port: ``(board, server)``; the server must stop."""
    board = Board()
    with ViewServer(board, port=0) as server:
        yield board, server
    assert not server.running
