"""Fixtures of the page's browser tests: a served board (the browser: tests/conftest.py)."""

from __future__ import annotations

import pytest

from limbctl.view import Board, ViewServer


@pytest.fixture
def served():
    """A :class:`Board` served on a free port: ``(board, server)``; the server must stop."""
    board = Board()
    with ViewServer(board, port=0) as server:
        yield board, server
    assert not server.running
