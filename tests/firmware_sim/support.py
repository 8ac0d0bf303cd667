"""Shared helpers of the simulator's tests."""

from __future__ import annotations

import time


def wait_for(condition, timeout_s: float, what: str):
    """Poll ``condition`` until it returns a truthy value; fail naming ``what`` on timeout."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
