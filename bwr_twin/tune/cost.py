"""What a tuning's budget will cost, estimated before anything runs (bwr_twin.sim.budget)."""

from __future__ import annotations

import math

from bwr_twin.config.tuning import Tuning
from bwr_twin.sim.budget import FILES_S, Estimate, estimate


def budget_estimate(tuning: Tuning, workers: int, *, force: bool = False) -> Estimate:
    """The whole budget: every evaluation on every training seed and the start and the best on the
    held-out seeds, each run costing what the base scene's does. A tuning keeps the metrics only
    (no run directories: no disk, no file writing); a wall-time budget caps the time."""
    seeds = len(tuning.training_seeds)
    runs = tuning.evaluations * seeds + 2 * len(tuning.held_out_seeds)
    one = estimate([tuning.base], chunk=seeds, force=force)  # its plan and faults counted first
    parallel = max(1, min(workers, math.ceil(runs / seeds)))
    seconds = runs * (one.seconds - FILES_S) / parallel
    if tuning.wall_time is not None:
        seconds = min(seconds, tuning.wall_time)
    return Estimate(runs, runs * one.physics_steps, seconds, parallel * one.memory_bytes, 0.0, one.slowest, one.largest)
