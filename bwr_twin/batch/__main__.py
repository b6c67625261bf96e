"""`python -m bwr_twin.batch`: see bwr_twin.batch.cli."""


from bwr_twin.batch.cli import main
from bwr_twin.errors import leave

leave(main())
