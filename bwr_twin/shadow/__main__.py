"""`python -m bwr_twin.shadow`: the shadow over a recorded log (bwr_twin.shadow.cli)."""

import sys

from bwr_twin.shadow.cli import main

if __name__ == "__main__":
    sys.exit(main())
