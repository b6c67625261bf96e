"""The machine behind the OPC UA server: one run of a scene, advanced a control period at a time
under drive forces that someone else computes (the PLC, over the wire).

Nothing here knows of OPC UA or of clocks; `bwr_twin.serve.clock` decides when a period passes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.model.machine import Machine
from bwr_twin.sensing.outputs import ScanLog
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.record import RunResult

END_STOP_MARGIN = 1e-3  # share of a joint's range: closer than this to an end stop is "at" it, as the metrics say
# Limit switch changes kept until taken: a joint chattering on its limit through a long Step(n),
# or a user of the twin that never takes them, keeps the latest ones only.
SWITCHES_KEPT = 1000
# The per-axis values read with the encoders, in the order `Twin.measured` holds them.
MEASURED = ("EncoderPosition", "EncoderVelocity", "ReferencePosition", "ReferenceVelocity", "ReferenceAcceleration")


class Twin:
    """One run of `scene` as the machine: encoders, reference, drives and limit switches.

    Attributes:
        period: the control period, s.
        samples: the control periods of the path (of a bench plan, the most it may take until
            it ends); `loop.k` the next one to be advanced.
        reading: the latest values of the published variables (see `bwr_twin.serve.address_space`),
            SI units: encoder positions (m, rad) and velocities (m/s, rad/s) at the start of period
            k, the reference at k, the forces the drives were commanded and applied over period
            k - 1 (N, N m).
        measured, at_limit, sim_time: the same as Python values, without building `reading`:
            MEASURED's (3,) lists in its order, the three limit switches, SimTime (s);
            `drive_applied()` and `reclaim_rate()` give the rest.

    A run with instruments, scanners or faults reads them too, only as `reading` is built: the
    belt scale (t/h) and wheel current (A) of the last period ("BeltScale", "WheelCurrent"), the
    anemometer's wind (m/s along the scene's heading) of the last period in a windy plant ("WindSpeed"),
    each scanner's latest scan ("Scans", `LatestScan`s), each fault's state in the period
    that starts at SimTime ("Faults", bools in the scene's order), and a neighbour's latest
    position report ("NeighbourPosition", m and rad, true at "NeighbourReportTime", s).

    Every period's limit switches are read, so that a switch that closes and opens again
    between two publications is still seen: `take_limit_switches` hands over the changes.

    The FMU advances and reads the twin every control period, so a period here costs little more
    than the loop's own: what is read is kept as Python floats and bools (numpy's operations on
    three values cost ten times more), and `reading`'s arrays are built only when asked for.
    """

    def __init__(self, scene: Scene):
        """Raises BwrError if the scene's path or models are bad."""
        self.scene = scene
        self.reset()

    def reset(self) -> None:
        """Back to the start of the path: a fresh run of the scene, the same disturbances."""
        self.loop = loop = Lockstep([self.scene], nthread=1)
        self.period = loop.period
        self._low, self._high = limit_switch_bounds(loop.machine)
        self._command = np.zeros((1, 3))  # N, N m: the drive forces held over a period
        self._switches: deque[tuple[int, bool, float]] = deque(maxlen=SWITCHES_KEPT)
        self.at_limit: tuple[bool, bool, bool] | None = None  # none before the first reading: no change to report
        self._reading: dict[str, object] | None = None
        self._measure()

    @property
    def k(self) -> int:
        return self.loop.k

    @property
    def done(self) -> bool:
        """The path's last control period has been advanced."""
        return self.loop.done

    @property
    def failure(self) -> str | None:
        """Why the run stopped if it diverged (MuJoCo's warning, with the time), else None."""
        return self.loop.failures.get(0)

    @property
    def periods_left(self) -> int:
        return self.samples - self.loop.k

    @property
    def samples(self) -> int:
        return self.loop.samples

    @property
    def reading(self) -> dict[str, object]:
        """The published values by name, per axis as (3,) arrays: built when first asked for in a period."""
        if self._reading is None:
            self._reading = {
                "DriveCommanded": self._command[0].copy(),
                "DriveApplied": np.array(self.drive_applied()),
                "ReclaimRate": self.reclaim_rate(),
                "SimTime": self.sim_time,
                "PeriodsLeft": self.periods_left,
                **{name: np.array(values) for name, values in zip(MEASURED, self.measured)},
                "AtLimit": np.array(self.at_limit),
                **self._sensing(),
            }
        return self._reading

    def _sensing(self) -> dict[str, object]:
        """The readings of the run's instruments, scanners and faults: only those it has."""
        loop, found = self.loop, {}
        instruments = loop.instruments
        if instruments is not None:
            if instruments.scale is not None:
                found["BeltScale"] = self.belt_scale()
            if instruments.motor is not None:
                found["WheelCurrent"] = self.wheel_current()
        if loop.scanning is not None:
            found["Scans"] = tuple(latest_scan(log) for log in loop.scanning.logs)
        if loop.faults.faults:  # the period of SimTime: at the path's end, the last one advanced
            found["Faults"] = tuple(loop.faults.acting(min(loop.k, loop.samples - 1)))
        if loop.wind_speed is not None:
            found["WindSpeed"] = float(loop.wind_speed[0])
        if loop.neighbour is not None:  # its latest report, as the encoders are read
            found["NeighbourPosition"] = self.neighbour_position()
            found["NeighbourReportTime"] = self.neighbour_report_time()
        return found

    def neighbour_position(self) -> list[float]:
        """The neighbour's (3,) joints (m, rad, rad) as its latest report gives them; the run must have one."""
        return self.loop.neighbour.reported[0, 0].tolist()

    def neighbour_report_time(self) -> float:
        """s: when the neighbour stood where its latest report says."""
        return self.loop.neighbour.report_time

    def drive_applied(self) -> list[float]:
        """The forces the drives applied over the last period (N, N m); zero before the first."""
        return self.loop.drive_force[0].tolist() if self.loop.k > 0 else [0.0, 0.0, 0.0]

    def belt_scale(self) -> float:
        """The belt scale's reading of the last period, t/h (late and noisy); zero before the first."""
        return float(self.loop.instruments.belt_scale[0]) if self.loop.k > 0 else 0.0

    def wheel_current(self) -> float:
        """The wheel motor's current of the last period, A, as its drive measures it; zero before the first."""
        return float(self.loop.instruments.wheel_current[0]) if self.loop.k > 0 else 0.0

    def reclaim_rate(self) -> float:
        """What the wheel reclaimed over the last period, t/h; zero before the first or without a stockpile."""
        rate = self.loop.reclaim_rate
        return float(rate[0]) if rate is not None and self.loop.k > 0 else 0.0

    def advance(self, drive_force: np.ndarray | Sequence[float]) -> None:
        """Hold the (3,) drive forces (N, N m, N m) over one control period, then read the encoders."""
        loop = self.loop
        self._command[0] = drive_force
        loop.advance(self._command)  # inside the server's mujoco_warnings(): MuJoCo prints nothing
        self._reading = None
        if loop.k < loop.samples:  # at the end, the reading keeps the last period's encoders
            self._measure()

    def set_rate_trim(self, trim: float | None) -> None:
        """A bench reclaim's slew-speed trim set from outside from the next period on, held within the
        scene's `trim_limits`; None: the scene's own rate control trims again."""
        self.loop.tracking.external_trim = trim

    def take_limit_switches(self) -> list[tuple[int, bool, float]]:
        """The limit switches that changed since the last call, in order: (axis index, at the
        limit, SimTime s)."""
        switches = list(self._switches)
        self._switches.clear()
        return switches

    def results(self) -> RunResult:
        """The run's result once `done`; raises the SimulationError of a run that diverged."""
        (result,) = self.loop.results()
        if isinstance(result, Exception):
            raise result
        return result

    def _measure(self) -> None:
        """Read the encoders (once a period: their velocity filter has state), the limit switches
        and the reference of period k."""
        loop = self.loop
        q_measured, qd_measured = loop.measure()
        self.sim_time = sim_time = float(loop.time[loop.k])
        # The true joint, not the encoder; three Python comparisons cost a tenth of numpy's.
        (q0, q1, q2), (low0, low1, low2), (high0, high1, high2) = loop.q_true[0].tolist(), self._low, self._high
        at_limit = (q0 <= low0 or q0 >= high0, q1 <= low1 or q1 >= high1, q2 <= low2 or q2 >= high2)
        before = self.at_limit
        if before is not None and at_limit != before:
            self._switches.extend((j, now, sim_time) for j, (now, was) in enumerate(zip(at_limit, before))
                                  if now != was)
        self.at_limit = at_limit
        # The path's (3,) rows, or the bench plan's (1, 3) reference, which changes in place: copied.
        position, velocity, acceleration = loop.reference_now()
        if position.ndim > 1:
            position, velocity, acceleration = position[0], velocity[0], acceleration[0]
        self.measured = (q_measured[0].tolist(), qd_measured[0].tolist(), position.tolist(), velocity.tolist(),
                         acceleration.tolist())


def limit_switch_bounds(machine: Machine) -> tuple[list[float], list[float]]:
    """The (3,) low and high joint values (m, rad) at or beyond which a limit switch closes: the
    operating envelope, or END_STOP_MARGIN inside an end stop. Python floats: compared with the
    true joint every period."""
    margin = END_STOP_MARGIN * np.nan_to_num(machine.joint_range[:, 1] - machine.joint_range[:, 0], posinf=0.0)
    return (np.maximum(machine.envelope[:, 0], machine.joint_range[:, 0] + margin).tolist(),
            np.minimum(machine.envelope[:, 1], machine.joint_range[:, 1] - margin).tolist())


@dataclass(frozen=True, eq=False)
class LatestScan:
    """A scanner's latest scan of run 0: the `count`-th of `log`, at SimTime `time` s, from
    `origin` (3,) world m, its `hits` (rays, 3) world m (float32, NaN: dropped or missed)."""

    log: ScanLog
    count: int
    time: float
    origin: np.ndarray
    hits: np.ndarray

    def ranges(self) -> np.ndarray:
        """(rays,) m from the origin to each hit along its ray; NaN where nothing returned."""
        return np.sqrt(((self.hits.astype(float) - self.origin) ** 2).sum(axis=1))


def latest_scan(log: ScanLog) -> LatestScan | None:
    """Run 0's latest scan; None before the first."""
    latest = log.latest(0)
    return None if latest is None else LatestScan(log, log.count, *latest)