"""The logged wind's force on the machine, for the fit to apply.

A rollout cannot vary `opt.wind` within a window, so the wind enters the fit as what it does:
the generalised force of MuJoCo's fluid model at each logged state (bwr_twin.model.wind). The
fit's own model stays in still air (`Edits.still_air`), so that the wind is not counted twice;
the force is taken at the model's nominal geometry (a fitted mass or position does not move the
wind areas).
"""

from __future__ import annotations

import mujoco
import numpy as np

from bwr_twin.calibrate.log import MachineLog
from bwr_twin.model.wind import wind_forces as forces_at


def wind_forces(model: mujoco.MjModel, joint_ids, log: MachineLog) -> np.ndarray | None:
    """(n, nv) the wind's generalised force (N, N m) at each row of `log`, on `model` (still air);
    None for a log without a wind to apply."""
    if not log.windy:
        return None
    speeds = np.array([log.velocity_at(row) for row in range(len(log.time))]).reshape(-1, 3)
    return forces_at(model, joint_ids, log.q, speeds, log.wind, log.wind_heading, log.air_density)
