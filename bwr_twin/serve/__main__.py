from bwr_twin.errors import leave
from bwr_twin.serve.cli import main

leave(main())
