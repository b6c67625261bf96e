"""The machine behind the OPC UA server: one run of a scene, advanced a control period at a time
under drive forces that someone else computes (the PLC, over the wire).

Nothing here knows of OPC UA or of clocks; `bwr_twin.serve.clock` decides when a period passes.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.sim.record import RunResult

END_STOP_MARGIN = 1e-3  # share of a joint's range: closer than this to an end stop is "at" it, as the metrics say
# Limit switch changes kept until taken: a joint chattering on its limit through a long Step(n),
# or a user of the twin that never takes them, keeps the latest ones only.
SWITCHES_KEPT = 1000


class Twin:
    """One run of `scene` as the machine: encoders, reference, drives and limit switches.

    Attributes:
        period: the control period, s.
        samples: the control periods of the path (of a bench plan, the most it may take until
            it ends); `loop.k` the next one to be advanced.
        reading: the latest values of the published variables (see `bwr_twin.serve.address_space`),
            SI units: encoder positions (m, rad) and velocities (m/s, rad/s) at the start of period
            k, the reference at k, the forces the drives applied over period k - 1 (N, N m).

    Every period's limit switches are read, so that a switch that closes and opens again
    between two publications is still seen: `take_limit_switches` hands over the changes.
    """

    def __init__(self, scene: Scene):
        """Raises BwrError if the scene's path or models are bad."""
        self.scene = scene
        self.reset()

    def reset(self) -> None:
        """Back to the start of the path: a fresh run of the scene, the same disturbances."""
        self.loop = loop = Lockstep([self.scene], nthread=1)
        self.period = loop.period
        machine = loop.machine
        margin = END_STOP_MARGIN * np.nan_to_num(machine.joint_range[:, 1] - machine.joint_range[:, 0], posinf=0.0)
        self._low = np.maximum(machine.envelope[:, 0], machine.joint_range[:, 0] + margin)  # m, rad
        self._high = np.minimum(machine.envelope[:, 1], machine.joint_range[:, 1] - margin)
        self._command = np.zeros((1, 3))  # N, N m: the drive forces held over a period
        self.reading: dict[str, object] = {"DriveApplied": np.zeros(3), "ReclaimRate": 0.0}
        self._switches: deque[tuple[int, bool, float]] = deque(maxlen=SWITCHES_KEPT)
        self._at_limit = None  # the switches of the period before: none at the path's start
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

    def advance(self, drive_force: np.ndarray) -> None:
        """Hold the (3,) drive forces (N, N m, N m) over one control period, then read the encoders."""
        self._command[0] = drive_force
        self.loop.advance(self._command)  # inside the server's mujoco_warnings(): MuJoCo prints nothing
        self.reading["DriveApplied"] = self.loop.drive_force[0].copy()
        if self.loop.reclaim_rate is not None:
            self.reading["ReclaimRate"] = float(self.loop.reclaim_rate[0])  # t/h
        if not self.loop.done:
            self._measure()
        self.reading["PeriodsLeft"] = self.periods_left

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
        loop = self.loop
        k = loop.k
        q_measured, qd_measured = loop.measure()
        q_true = loop.q_true[0]
        at_limit = (q_true <= self._low) | (q_true >= self._high)  # the true joint, not the encoder
        before = self._at_limit
        if before is not None and at_limit.tobytes() != before.tobytes():  # the cheapest test of three
            self._switches.extend((int(j), bool(at_limit[j]), float(loop.time[k]))
                                  for j in np.flatnonzero(at_limit != before))
        self._at_limit = at_limit
        # The planned path's rows, or the bench plan's reference of this period: never written.
        position, velocity, acceleration = (value.reshape(-1, 3)[0].copy() for value in loop.reference_now())
        self.reading.update({
            "SimTime": float(loop.time[k]),
            "PeriodsLeft": self.periods_left,
            "EncoderPosition": q_measured[0].copy(),
            "EncoderVelocity": qd_measured[0].copy(),
            "ReferencePosition": position,
            "ReferenceVelocity": velocity,
            "ReferenceAcceleration": acceleration,
            "AtLimit": at_limit,
        })
