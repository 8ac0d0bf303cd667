"""``python -m firmware_sim._child FD CONFIG_JSON``: the process :class:`SimulatedBus` starts."""

from __future__ import annotations

import json
import sys
from multiprocessing.connection import Connection

from firmware_sim.bus import child_main

if __name__ == "__main__":
    child_main(Connection(int(sys.argv[1])), json.loads(sys.argv[2]))
