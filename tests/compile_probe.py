"""The numba compile counter the first-run tests run in a fresh process: :data:`COUNTER`, the head
of a ``python -c`` script, lists in ``compiled`` each kernel numba compiles after it registers
``Count()`` (``"module.qualname"``), and in ``signatures`` the same with argument types."""

COUNTER = r"""
import json, sys
import numba.core.event as ev

compiled = []
signatures = []

class Count(ev.Listener):
    def on_start(self, event):
        pass

    def on_end(self, event):
        f = event.data["dispatcher"].py_func
        name = f"{f.__module__}.{f.__qualname__}"
        compiled.append(name)
        signatures.append([name, str(event.data["args"])])
"""
