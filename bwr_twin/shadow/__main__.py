"""`python -m bwr_twin.shadow`: the shadow over a recorded log (bwr_twin.shadow.cli)."""

from bwr_twin.errors import leave
from bwr_twin.shadow.cli import main

if __name__ == "__main__":
    leave(main())
