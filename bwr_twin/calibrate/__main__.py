"""Calibrate a machine's MJCF from its own records.

    python -m bwr_twin.calibrate fit LOG [LOG ...] --model MJCF --out DIR [--params P ...] [--holdout LOG]
    python -m bwr_twin.calibrate plan MJCF --out test.toml [--minutes 10]

`fit` replays the logged drive forces into the MJCF window by window from the measured state and
fits the parameters named (default: every axis's viscous damping, Coulomb friction and reflected
drive inertia) with MuJoCo's system identification. DIR gets calibrated.xml (the MJCF with each
fitted number changed in place and commented), calibration.json and the report. A parameter the
logs cannot determine is named, left at its nominal value, and paired with the test motion that
would determine it. `plan` writes a scene of a test motion to run on the machine during a stop.
Bad input exits with status 2 and one line naming the file, the column or the row; nothing is
written.
"""

from __future__ import annotations

from bwr_twin.calibrate.cli import main
from bwr_twin.errors import leave

if __name__ == "__main__":
    leave(main())
