"""`python -m bwr_twin.batch`: see bwr_twin.batch.cli."""

import sys

from bwr_twin.batch.cli import main

sys.exit(main())
