import sys

from bwr_twin.serve.cli import main

sys.exit(main())
