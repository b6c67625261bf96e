"""What only watches the runs: the clearance monitors (docs/anticollision.md), as observers.

A watcher reads each control period as it starts, before any stage of the world acts
(bwr_twin.sim.stages), and changes nothing the loop, the controller or the world reads: it keeps
its own record, and adds its share to each run's metrics.json once the runs have ended. A
lockstep that keeps no results (`observe=False`, a learning agent's environment) has no watchers.

Unlike the observer's other work (bwr_twin.sim.observer), which reduces a full block of rows at a
time, the monitors read every period: the pile they measure against changes as the wheel cuts,
and no row holds it.
"""

from __future__ import annotations

from bwr_twin.collision.machines import MachineClearance
from bwr_twin.collision.monitor import WATCH, PileClearance
from bwr_twin.sim.block import Row
from bwr_twin.sim.plant import Plant
from bwr_twin.stockpile.reclaim import Reclaim


class Watcher:
    """Watches each period as it starts; adds its sections to a run's metrics."""

    def watch(self, k: int, row: Row) -> None:
        """Period k, with the true state at its start in `row`."""

    def metrics(self, run: int, metrics: dict) -> None:
        """Add this watcher's sections to `run`'s metrics, before the stages add theirs."""


class PileWatch(Watcher):
    """The machine's collision shapes against the pile as dug before this period's cut
    (bwr_twin.collision.monitor)."""

    def __init__(self, clearance: PileClearance, reclaim: Reclaim, plant: Plant):
        self._clearance, self._reclaim, self._plant = clearance, reclaim, plant

    def watch(self, k: int, row: Row) -> None:
        self._clearance.step(k, row.q, row.qd, self._reclaim.heights, self._plant.alive)

    def metrics(self, run: int, metrics: dict) -> None:
        metrics["collision"] = self._clearance.metrics(run)


class MachineWatch(Watcher):
    """The two machines' collision shapes against each other (bwr_twin.collision.machines)."""

    def __init__(self, clearance: MachineClearance, plant: Plant):
        self._clearance, self._plant = clearance, plant
        self._periods = 0

    def watch(self, k: int, row: Row) -> None:
        plant = self._plant
        self._clearance.step(k, row.q, row.qd, plant.neighbour_q, plant.neighbour_qd, plant.alive)
        self._periods = k + 1

    def metrics(self, run: int, metrics: dict) -> None:
        collision = metrics.setdefault("collision", {"watch_m": WATCH, "pile": {}, "contacts": [], "interventions": [],
                                                     "periods": self._periods, "measured_periods": 0})
        pairs, contacts = self._clearance.metrics(run)
        collision["machines"] = pairs
        collision["contacts"] = sorted(collision["contacts"] + contacts, key=lambda e: e["time_s"])
        collision["machine_measured_periods"] = int(self._clearance.measured_periods[run])
