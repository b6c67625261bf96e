"""The plant's own faults: a friction that rises and material that cakes at the wheel end.

They change the machine, not what it is told or what its sensors read, so they act through the
per-simulation fields of the plant's batch (`mujoco.batch.Batch.expand`, as bwr_twin.sim.plant
sets each run's friction loss and wind): a `friction_rise` scales its axis's viscous damping
(`dof_damping`) and Coulomb friction (`dof_frictionloss`); a `mass_change` adds a point mass at
the CP to the CP's body (its `body_mass`, centre of mass, principal inertia and frame), after
which MuJoCo's constants derived from the masses follow (`Batch.set_const`). Each grows linearly
over its ramp (bwr_twin.sensing.faults.grown) and is undone when its duration ends. A scene
without them builds nothing here, and no field of its batch is expanded: it runs as before, to
the bit. (A derated drive scales its command: bwr_twin.sensing.faults.Faults.command.)
"""

from __future__ import annotations

from collections.abc import Sequence

import mujoco
import numpy as np

from bwr_twin.config.faults import FAULT_AXES, FaultSection
from bwr_twin.model.machine import Machine
from bwr_twin.sensing.faults import fault_periods, grown, ramp_periods

_FRICTION_FIELDS = ("dof_damping", "dof_frictionloss")
_MASS_FIELDS = ("body_mass", "body_ipos", "body_inertia", "body_iquat")


class PlantFaults:
    """The friction rises and mass changes of a scene, written into a batch's per-run fields."""

    def __init__(self, faults: Sequence[FaultSection], machine: Machine, batch, period: float):
        """`batch`: the plant's `mujoco.batch.Batch`, whose model holds the machine's bodies first."""
        self._batch = batch
        self._friction = [(FAULT_AXES.index(f.axis), *fault_periods(f, period), f.percent / 100.0,
                           ramp_periods(f, period)) for f in faults if f.kind == "friction_rise"]
        self._mass = [(*fault_periods(f, period), f.mass, ramp_periods(f, period))
                      for f in faults if f.kind == "mass_change"]
        self.active = bool(self._friction or self._mass)
        self._body = int(machine.model.site_bodyid[machine.cp_site])
        self._at = machine.model.site_pos[machine.cp_site].copy()  # the CP in its body's frame, m
        model = batch.model
        self._nominal = {name: np.array(getattr(model, name)) for name in _FRICTION_FIELDS + _MASS_FIELDS}
        if batch.expanded("dof_frictionloss") is not None:  # each run's own friction loss (RunParameters)
            self._nominal["dof_frictionloss"] = batch.expanded("dof_frictionloss").copy()
        self._added = 0.0  # kg at the CP now, shared by every run (the faults are the scene's)

    def step(self, k: int, alive: np.ndarray | None) -> None:
        """Write period k's friction and mass into the runs' fields (`alive`: the runs stepped, None: all)."""
        if self._friction:
            scale = np.ones(3)
            for axis, first, last, share, ramp in self._friction:
                if first <= k <= last:
                    scale[axis] += share * grown(k - first, ramp)
            for name in _FRICTION_FIELDS:
                self._batch.expand(name)[:, :3] = self._nominal[name][..., :3] * scale
        if self._mass:
            added = sum(mass * grown(k - first, ramp) for first, last, mass, ramp in self._mass if first <= k <= last)
            if added != self._added:
                self._added = added
                self._write_mass(added, alive)

    def _write_mass(self, added: float, alive: np.ndarray | None) -> None:
        """The CP body with `added` kg at the CP: its mass, centre of mass and principal inertia."""
        b, nominal = self._body, self._nominal
        mass, com = nominal["body_mass"][b], nominal["body_ipos"][b]
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, nominal["body_iquat"][b])
        rotation = rotation.reshape(3, 3)
        total = mass + added
        centre = (mass * com + added * self._at) / total
        tensor = rotation @ np.diag(nominal["body_inertia"][b]) @ rotation.T
        tensor += _shifted(mass, com - centre) + _shifted(added, self._at - centre)
        principal, axes = np.linalg.eigh(tensor)
        if np.linalg.det(axes) < 0:  # a right-handed frame, for a quaternion
            axes[:, 0] = -axes[:, 0]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, axes.ravel())
        batch = self._batch
        batch.expand("body_mass")[:, b] = total
        batch.expand("body_ipos")[:, b] = centre
        batch.expand("body_inertia")[:, b] = principal
        batch.expand("body_iquat")[:, b] = quat
        batch.set_const(alive)


def _shifted(mass: float, offset: np.ndarray) -> np.ndarray:
    """A point mass's inertia tensor (kg m^2) about a point `offset` (m) from it (parallel axes)."""
    return mass * (offset @ offset * np.eye(3) - np.outer(offset, offset))
