"""Every run's collision shapes against its neighbour's on the rail, once a control period: the
least clearance of each pair with its time, and each contact (clearance <= 0) as an event with
its start, end and depth (docs/anticollision.md). Here the wheel's envelope counts: it cuts the
pile, not the other machine.

The distances are MuJoCo's own (`mj_geomDistance`) between the two machines' boxes and capsules,
posed by `mj_kinematics` on a model of both (the first machine's file with the neighbour's
attached, bwr_twin.model.spec) that nothing steps: the plant keeps the state. A run's pairs are
measured only while the machines' slew axes are within both reaches and WATCH of each other;
farther, every pair is at least WATCH apart.
"""

from __future__ import annotations

import mujoco
import numpy as np

from bwr_twin.collision.monitor import WATCH
from bwr_twin.collision.shapes import COLLISION_GROUP, PREFIX
from bwr_twin.model.machine import Machine
from bwr_twin.model.spec import NEIGHBOUR, Edits, compile_model

_REACH_SAMPLES = 24  # slew and luff angles at which a machine's reach is taken


class MachineClearance:
    """(runs, pairs) clearances between the machine's shapes and its neighbour's.

    Attributes:
        pairs: each pair's names, (the machine's part, the neighbour's part).
        least, least_time: (runs, pairs) the least clearance so far (m, at most WATCH) and when (s).
    """

    def __init__(self, machine: Machine, neighbour: Machine, runs: int, period: float):
        self.model = model = compile_model(machine.path, Edits(payloads=machine.payloads, neighbour=neighbour.path))
        self.data = mujoco.MjData(model)
        self.period = period
        own = _shapes(model, PREFIX)
        other = _shapes(model, NEIGHBOUR + PREFIX)
        self.pairs = [(a, b) for a in own for b in other]
        self._geoms = np.array([(own[a], other[b]) for a, b in self.pairs], dtype=np.int64).reshape(-1, 2)
        (reach, base), (other_reach, other_base) = (_reach(model, machine, own.values(), 0),
                                                    _reach(model, neighbour, other.values(), 3))
        self._reach, self._offset = reach + other_reach, base - other_base
        self.least = np.full((runs, len(self.pairs)), WATCH)
        self.least_time = np.zeros((runs, len(self.pairs)))
        self._events: list[list[dict]] = [[] for _ in range(runs)]
        self._open = np.full((runs, len(self.pairs)), -1, dtype=np.int64)
        self._fromto = np.zeros(6)
        self.measured_periods = np.zeros(runs, dtype=np.int64)

    def step(self, k: int, q: np.ndarray, neighbour_q: np.ndarray, runs: np.ndarray | None) -> None:
        """Period k: the machines where the true joints q and neighbour_q (runs, 3) put them;
        only the `runs` given (None: all)."""
        order = range(len(q)) if runs is None else runs
        model, data, time = self.model, self.data, round(k * self.period, 9)
        for run in order:
            if abs(q[run, 0] - neighbour_q[run, 0] + self._offset) > self._reach + WATCH:
                if (self._open[run] >= 0).any():
                    self._record(run, np.full(len(self.pairs), WATCH), time)
                continue
            self.measured_periods[run] += 1
            data.qpos[:3], data.qpos[3:6] = q[run], neighbour_q[run]
            mujoco.mj_kinematics(model, data)
            distances = np.array([mujoco.mj_geomDistance(model, data, a, b, WATCH, self._fromto) for a, b in self._geoms])
            self._record(run, np.minimum(distances, WATCH), time)

    def _record(self, run: int, distances: np.ndarray, time: float) -> None:
        closer = distances < self.least[run]
        self.least[run, closer] = distances[closer]
        self.least_time[run, closer] = time
        events = self._events[run]
        for pair in np.flatnonzero((distances <= 0.0) | (self._open[run] >= 0)):
            index, depth = self._open[run, pair], float(-distances[pair])
            if distances[pair] > 0.0:
                events[index]["end_s"] = time
                self._open[run, pair] = -1
            elif index < 0:
                self._open[run, pair] = len(events)
                a, b = self.pairs[pair]
                events.append({"time_s": time, "end_s": None, "bodies": [a, NEIGHBOUR + b], "depth_m": depth,
                               "depth_time_s": time})
            elif depth > events[index]["depth_m"]:
                events[index]["depth_m"], events[index]["depth_time_s"] = depth, time

    def metrics(self, run: int) -> tuple[dict, list[dict]]:
        """The least clearance of each pair ('boom | neighbour/boom': clearance_m, time_s) and the contacts of `run`."""
        least = {f"{a} | {NEIGHBOUR}{b}": {"clearance_m": float(self.least[run, i]),
                                           "time_s": float(self.least_time[run, i])}
                 for i, (a, b) in enumerate(self.pairs)}
        return least, [dict(e) for e in self._events[run]]


def _shapes(model: mujoco.MjModel, prefix: str) -> dict[str, int]:
    """Part name -> geom id of the collision shapes whose names begin with `prefix`."""
    found = {}
    for g in np.flatnonzero(model.geom_group == COLLISION_GROUP):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or ""
        if name.startswith(prefix):
            found[name[len(prefix):]] = int(g)
    return found


def _reach(model: mujoco.MjModel, machine: Machine, geoms, first: int) -> tuple[float, float]:
    """m: the farthest, along the rail, any of the machine's shapes comes from its carriage over
    its slew and luff envelopes (its joints at qpos[first:first + 3]), and where its carriage
    stands along the rail at travel 0."""
    data = mujoco.MjData(model)
    geoms = list(geoms)
    carriage = int(model.jnt_bodyid[np.flatnonzero(model.jnt_qposadr == first)[0]])
    reach = 0.0
    for slew in np.linspace(-np.pi, np.pi, _REACH_SAMPLES):
        for luff in np.linspace(*machine.envelope[2], _REACH_SAMPLES):
            data.qpos[first:first + 3] = (0.0, slew, luff)
            mujoco.mj_kinematics(model, data)
            along = np.abs(data.geom_xpos[geoms, 0] - data.xpos[carriage, 0])
            reach = max(reach, float((along + model.geom_rbound[geoms]).max(initial=0.0)))
    return reach, float(data.xpos[carriage, 0])
