"""Every run's collision shapes against its neighbour's on the rail, once a control period: the
least clearance of each pair with its time, and each contact (clearance <= 0) as an event with
its start, end and depth (docs/anticollision.md). Here the wheel's envelope counts: it cuts the
pile, not the other machine.

The distances are MuJoCo's own (`mj_geomDistance`) between the two machines' boxes and capsules,
posed by `mj_kinematics` on a model of both (the first machine's file with the neighbour's
attached, bwr_twin.model.spec) that nothing steps: the plant keeps the state. A run's pairs are
measured only while the machines' carriages are within both reaches and WATCH of each other
(farther, every pair is at least WATCH apart), and then a pair again only once the two machines
may have moved RECHECK of its clearance (or depth) measured last, and at least FLOOR of it: no
pair closes or opens faster than both machines' shapes move, each at most its joints' speeds on
its levers. Unlike the pile, which the wheel digs, nothing else changes a pair's clearance: two
machines at rest are not measured again.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numba
import numpy as np

from bwr_twin.collision.contacts import Contacts
from bwr_twin.collision.monitor import RECHECK, WATCH, levers_of
from bwr_twin.model.machine import Machine
from bwr_twin.model.shapes import COLLISION_GROUP, PREFIX
from bwr_twin.model.spec import NEIGHBOUR, Edits, compile_model

FLOOR = 0.05  # m: the clearance or depth below which a pair is measured again once moved RECHECK of FLOOR
_REACH_SAMPLES = 24  # slew and luff angles at which a machine's reach is taken


class MachineClearance:
    """(runs, pairs) clearances between the machine's shapes and its neighbour's.

    Attributes:
        pairs: each pair's names, (the machine's part, the neighbour's part).
        parts: the machine's parts, in order; `nearest()` gives each one's clearance to the neighbour.
        model: the model of both machines that poses them (`PairDistances`).
        now: (runs, pairs) m this period (WATCH where the machines are farther apart).
        least, least_time: (runs, pairs) the least clearance so far (m, at most WATCH) and when (s).
    """

    def __init__(self, machine: Machine, neighbour: Machine, runs: int, period: float):
        self._distances = distances = PairDistances(machine, neighbour)
        self.period = period
        own, other = distances.own, distances.other
        self.pairs = distances.pairs
        self.parts = list(own)
        self._part_of = np.array([self.parts.index(a) for a, _ in self.pairs], dtype=np.int64)
        self._reach = Reach.of(distances.model, machine, neighbour, own, other)
        self.now = np.full((runs, len(self.pairs)), WATCH)
        self.least = np.full((runs, len(self.pairs)), WATCH)
        self.least_time = np.zeros((runs, len(self.pairs)))
        self._contacts = Contacts(runs, len(self.pairs))
        self._measured = np.full((runs, len(self.pairs)), WATCH)  # each pair's last measure
        self._moved = np.full((runs, len(self.pairs)), np.inf)  # m each pair may have closed since: measure at once
        self._due = np.zeros((runs, len(self.pairs)), dtype=np.bool_)  # the pairs to measure this period
        self._all = np.arange(runs)
        self.measured_periods = np.zeros(runs, dtype=np.int64)

    @property
    def model(self) -> mujoco.MjModel:
        return self._distances.model

    def step(self, k: int, q: np.ndarray, qd: np.ndarray, neighbour_q: np.ndarray, neighbour_qd: np.ndarray,
             runs: np.ndarray | None) -> None:
        """Period k: the machines where joints q and neighbour_q (runs, 3) put them, moving at qd
        and neighbour_qd; only the `runs` given (None: all)."""
        order = self._all if runs is None else runs
        due, reach = self._due, self._reach
        if not _bound(order, q, qd, neighbour_q, neighbour_qd, reach.levers, reach.neighbour_levers, self.period,
                      reach.offset, reach.reach, WATCH, RECHECK, FLOOR, self._moved, self._measured, self.now, due):
            return
        time = round(k * self.period, 9)
        for run in np.flatnonzero(due.any(axis=1)).tolist():
            self.measured_periods[run] += 1
            measured = self._measured[run]
            self._distances.measure(q[run], neighbour_q[run], due[run], measured)
            self.now[run, due[run]] = measured[due[run]]
            if _changed(measured, self.least[run], self.least_time[run], self._contacts.open[run], time):
                self._record_contacts(run, measured, time)

    def clearance_at(self, q: np.ndarray, neighbour_q: np.ndarray) -> float:
        """m between the two machines' nearest shapes at joint values q and neighbour_q (3,),
        at most WATCH; no run's record changes."""
        return self._distances.nearest(q, neighbour_q)

    def nearest(self) -> np.ndarray:
        """(runs, parts) this period's clearance of each of the machine's parts to the neighbour's nearest."""
        out = np.full((len(self.now), len(self.parts)), WATCH)
        np.minimum.at(out.T, self._part_of, self.now.T)
        return out

    def _record_contacts(self, run: int, distances: np.ndarray, time: float) -> None:
        """Open, deepen or close run `run`'s contacts from its pairs' latest measures."""
        contacts = self._contacts
        for pair in np.flatnonzero((distances <= 0.0) | (contacts.open[run] >= 0)):
            a, b = self.pairs[pair]
            contacts.record(run, pair, not distances[pair] > 0.0, float(-distances[pair]), time, [a, NEIGHBOUR + b])

    def metrics(self, run: int) -> tuple[dict, list[dict]]:
        """The least clearance of each pair ('boom | neighbour/boom': clearance_m, time_s) and the contacts of `run`."""
        least = {f"{a} | {NEIGHBOUR}{b}": {"clearance_m": float(self.least[run, i]),
                                           "time_s": float(self.least_time[run, i])}
                 for i, (a, b) in enumerate(self.pairs)}
        return least, self._contacts.events(run)


class PairDistances:
    """MuJoCo's distances between the machine's shapes and its neighbour's, on a model of both
    that nothing steps (the plant keeps the state): the one owner of its MjData.

    Attributes:
        own, other: part name -> geom id of the machine's and the neighbour's collision shapes.
        pairs: each pair's names, (the machine's part, the neighbour's part).
    """

    def __init__(self, machine: Machine, neighbour: Machine):
        self.model = model = compile_model(machine.path, Edits(payloads=machine.payloads, neighbour=neighbour.path))
        self._data = mujoco.MjData(model)
        self.own, self.other = _shapes(model, PREFIX), _shapes(model, NEIGHBOUR + PREFIX)
        self.pairs = [(a, b) for a in self.own for b in self.other]
        self._geoms = np.array([(self.own[a], self.other[b]) for a, b in self.pairs], dtype=np.int64).reshape(-1, 2)
        self._fromto = np.zeros(6)

    def measure(self, q: np.ndarray, neighbour_q: np.ndarray, due: np.ndarray, measured: np.ndarray) -> None:
        """Write into `measured` (pairs,) the distance (m, at most WATCH) of each pair `due` at
        joint values q and neighbour_q (3,)."""
        model, data = self.model, self._data
        data.qpos[:3], data.qpos[3:6] = q, neighbour_q
        mujoco.mj_kinematics(model, data)
        for pair in np.flatnonzero(due).tolist():
            a, b = self._geoms[pair]
            measured[pair] = min(mujoco.mj_geomDistance(model, data, a, b, WATCH, self._fromto), WATCH)

    def nearest(self, q: np.ndarray, neighbour_q: np.ndarray) -> float:
        """m between the nearest pair at joint values q and neighbour_q (3,), at most WATCH."""
        data = self._data
        data.qpos[:3], data.qpos[3:6] = q, neighbour_q
        mujoco.mj_kinematics(self.model, data)
        return min(min(mujoco.mj_geomDistance(self.model, data, a, b, WATCH, self._fromto) for a, b in self._geoms),
                   WATCH)


@dataclass(frozen=True)
class Reach:
    """How near and how fast the two machines' shapes can come: what bounds a pair's clearance
    between its measures (the module's docstring).

    reach: m, both machines' farthest shape from its carriage along the rail, summed.
    offset: m, where the machine's carriage stands less the neighbour's, at travel 0.
    levers, neighbour_levers: (3,) m a unit of each joint's speed moves either machine's shapes.
    """

    reach: float
    offset: float
    levers: np.ndarray
    neighbour_levers: np.ndarray

    @classmethod
    def of(cls, model: mujoco.MjModel, machine: Machine, neighbour: Machine, own: dict[str, int],
           other: dict[str, int]) -> Reach:
        (reach, base), (other_reach, other_base) = (_reach(model, machine, own.values(), 0),
                                                    _reach(model, neighbour, other.values(), 3))
        return cls(reach + other_reach, base - other_base, levers_of(machine.collision_shapes),
                   levers_of(neighbour.collision_shapes))


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


@numba.njit(cache=True)
def _bound(order, q, qd, other_q, other_qd, levers, other_levers, period, offset, reach, watch, recheck, floor, moved,
           measured, now, due):  # pragma: no cover - compiled
    """Each run's pairs this period, bounded by the machines' motion since each was measured:
    `now` at least its last measure less that motion; `due` the pairs to measure (all of a run
    whose machines came within reach; none of one farther apart, each pair then `watch`). Whether
    any is due."""
    any_due = False
    for run in order:
        due[run, :] = False
        if abs(q[run, 0] - other_q[run, 0] + offset) > reach + watch:
            now[run, :] = watch
            moved[run, :] = np.inf
            continue
        closing = 0.0
        for j in range(3):
            closing += abs(qd[run, j]) * levers[j] + abs(other_qd[run, j]) * other_levers[j]
        closing *= period
        for p in range(moved.shape[1]):
            moved[run, p] += closing
            last = measured[run, p]
            if moved[run, p] >= recheck * max(abs(last), floor):
                due[run, p] = True
                moved[run, p] = 0.0
                any_due = True
            else:
                now[run, p] = min(last - moved[run, p], watch)
    return any_due


@numba.njit(cache=True)
def _changed(measured, least, least_time, open_, time):  # pragma: no cover - compiled
    """A run's least clearances updated from its pairs' latest measures (the unmeasured ones'
    last: no nearer); whether a contact opens, goes on or closes."""
    contacts = False
    for p in range(len(measured)):
        if measured[p] < least[p]:
            least[p] = measured[p]
            least_time[p] = time
        if measured[p] <= 0.0 or open_[p] >= 0:
            contacts = True
    return contacts
