"""A candidate's score: the tuning file's weighted metrics, each normalised per axis by its value
at the starting point, averaged over the axes and the training seeds; smaller is better.

A candidate that breaks a constraint, or one of whose runs failed (diverged), is infeasible: its
score is INFEASIBLE plus how far it broke the constraints, so CMA-ES ranks it below every
feasible one and still prefers the lesser violation.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.config.tuning import Tuning
from bwr_twin.model.machine import AXES

INFEASIBLE = 1e6
TINY = 1e-12  # a normaliser of zero (a metric the start does not show at all) counts as this


@dataclass(frozen=True)
class Score:
    value: float
    feasible: bool
    why: str  # the constraint broken, or ""
    means: dict[str, list[float]]  # metric -> per-axis mean magnitude over the seeds


def axis_means(tuning: Tuning, metrics: Sequence[dict]) -> dict[str, list[float]]:
    """metric -> per-axis mean of its magnitude over the runs' metrics.json."""
    return {metric: [float(np.mean([abs(m[axis][metric]) for m in metrics])) for axis in AXES]
            for metric in tuning.objective}


def score(tuning: Tuning, metrics: Sequence[dict | None], normalisers: dict[str, list[float]]) -> Score:
    """The score of one candidate from its training runs' metrics.json (None: the run failed)."""
    if any(m is None for m in metrics):
        return Score(INFEASIBLE * 10, False, "a run diverged", {})
    means = axis_means(tuning, metrics)
    value = sum(weight * float(np.mean([v / max(n, TINY) for v, n in zip(means[metric], normalisers[metric])]))
                for metric, weight in tuning.objective.items())
    violation, why = 0.0, []
    if tuning.max_saturation is not None:
        worst = max(m[axis]["saturation_fraction"] for m in metrics for axis in AXES)
        if worst > tuning.max_saturation:
            violation += worst - tuning.max_saturation
            why.append(f"saturation {worst:.3f} > {tuning.max_saturation:g}")
    if tuning.max_drive_rms is not None:
        for j, axis in enumerate(AXES):
            worst = max(m[axis]["drive_force_rms"] for m in metrics)
            if worst > tuning.max_drive_rms[j]:
                violation += worst / tuning.max_drive_rms[j] - 1.0
                why.append(f"{axis} drive RMS {worst:.4g} > {tuning.max_drive_rms[j]:.4g}")
    if not tuning.limits_allowed:
        broken = sorted({flag for m in metrics for flag in m.get("limits", ())})
        if broken:
            violation += len(broken)
            why.append(broken[0])
    if why:
        return Score(INFEASIBLE * (1.0 + violation), False, "; ".join(why), means)
    return Score(value, True, "", means)
