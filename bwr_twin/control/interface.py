"""The controller slot: what every controller of the twin implements, built in or an engineer's own.

A controller drives all runs of a lockstep at once. Once a control period it gets the measured
joint state and the reference of every run as (runs, 3) arrays (travel in m, slew and luff in
rad) and returns the drive forces (runs, 3) in N, N m, N m. It may use the controller's belief
of the machine (`context.belief`: M and bias at a state it chooses; `context.machine`:
kinematics, envelope, drive limits, all from the belief's MJCF) and nothing of the plant's true
state. Its settings are a frozen dataclass, `Settings`, whose fields are the scene's
`[controller]` keys, typed and checked like every scene key; numbers may differ between the runs
of a lockstep, anything else (a file, a choice) is shared by it. docs/controllers.md has a
complete example.
"""

from __future__ import annotations

import dataclasses
import functools
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from bwr_twin.model.machine import AXES, Machine
from bwr_twin.signals import Signal


class SettingsError(ValueError):
    """A setting that breaks a rule its type cannot express; the scene names its file and key."""

    def __init__(self, key: str, message: str):
        super().__init__(f"'{key}' {message}")
        self.key, self.message = key, message


@dataclass(frozen=True)
class ControllerContext:
    """What a controller may know: the believed machine and the loop's timing.

    Attributes:
        runs: the number of runs of the lockstep.
        control_period: s, the time between two calls of `compute`.
        machine: the believed machine (the scene's controller_mjcf): kinematics (`fk`, `ik`),
            `envelope`, `joint_range` and `drive_limits` (3, 2) in N and N m (inf if none).
        nthread: threads the lockstep's MuJoCo batch steps on (a controller that runs a batch
            of its own may use as many).
    """

    runs: int
    control_period: float
    machine: Machine
    nthread: int = 1

    @functools.cached_property
    def belief(self):  # -> bwr_twin.control.belief.Belief, built on first use: PID never needs it
        """M(q) and bias(q, qd) of every run's believed machine, at a state the controller
        chooses: `belief.update(q, qd, ids)`, then `belief.mass_matrix` (runs, 3, 3) and
        `belief.bias` (runs, 3), or `belief.torque(u)`; `belief.torque_at(q, qd, u, ids)` in one."""
        from bwr_twin.control.belief import Belief

        return Belief(self.machine, self.runs)


class Controller(ABC):
    """Drive forces from the measured state and the reference, for every run of a lockstep.

    Subclasses set `Settings` to a frozen dataclass of their scene keys (it may define
    `validate(self)`, raising SettingsError) and implement `compute`. A controller may declare
    the extra signals a run records of it in `signals` (bwr_twin.signals.Signal): each is an
    attribute of the same name, a (runs, 3) array that holds this period's value after `compute`.
    """

    Settings: ClassVar[type]
    signals: ClassVar[tuple[Signal, ...]] = ()

    def __init__(self, context: ControllerContext, settings: Sequence[Any]):
        self.context = context
        self.settings = settings

    @abstractmethod
    def compute(
        self,
        q: np.ndarray,
        qd: np.ndarray,
        q_ref: np.ndarray,
        qd_ref: np.ndarray,
        qdd_ref: np.ndarray,
        ids: np.ndarray | None,
    ) -> np.ndarray:
        """Drive forces (runs, 3) in N, N m, N m for the measured positions `q` and velocities
        `qd` (runs, 3) and the reference position, velocity and acceleration (runs, 3). `ids`
        lists the runs still simulated (None: all); the others' forces are ignored."""

    def per_run(self, name: str) -> np.ndarray:
        """A setting of every run as an array: (runs, 3) for a per-axis setting, (runs, 1) for a
        scalar, so that it broadcasts against (runs, 3)."""
        values = np.array([getattr(s, name) for s in self.settings], dtype=float)
        return values if values.ndim == 2 else values[:, None]


def check_non_negative(settings: Any, *keys: str) -> None:
    """SettingsError naming the key and axis of the first per-axis gain below zero."""
    for key in keys:
        for axis, gain in zip(AXES, getattr(settings, key)):
            if gain < 0:
                raise SettingsError(f"{key} ({axis})", f"must be >= 0, got {gain}")


def shared_settings(settings: Any) -> tuple:
    """The settings a lockstep shares (files, names, choices): everything but numbers, booleans
    and lists of them, which may differ from run to run."""
    return tuple(
        (field.name, str(value))
        for field in dataclasses.fields(settings)
        if not _per_run(value := getattr(settings, field.name))
    )


def _per_run(value: Any) -> bool:
    if isinstance(value, tuple):
        return all(_per_run(v) for v in value)
    return isinstance(value, (bool, int, float))
