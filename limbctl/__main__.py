"""``python -m limbctl``: the same as the ``limbctl`` command."""

import sys

from limbctl.cli import main

if __name__ == "__main__":
    sys.exit(main())
