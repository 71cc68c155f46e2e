"""``python -m spinstrike ...``: the ``spinstrike`` command line, for an interpreter whose scripts
folder is not on PATH (the same commands and options as the console script)."""

import sys

from spinstrike.agents.cli import main

if __name__ == "__main__":
    sys.exit(main())
