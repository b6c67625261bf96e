"""The machine behind the OPC UA server: one run of a scene, advanced a control period at a time
under drive forces that someone else computes (the PLC, over the wire).

Nothing here knows of OPC UA or of clocks; `bwr_twin.serve.clock` decides when a period passes.
"""

from __future__ import annotations

import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.sim.record import RunResult
from bwr_twin.sim.lockstep import Lockstep

END_STOP_MARGIN = 1e-3  # share of a joint's range: closer than this to an end stop is "at" it, as the metrics say


class Twin:
    """One run of `scene` as the machine: encoders, reference, drives and limit switches.

    Attributes:
        period: the control period, s.
        samples: the control periods of the path (of a bench plan, the most it may take until
            it ends); `loop.k` the next one to be advanced.
        reading: the latest values of the published variables (see `bwr_twin.serve.address_space`),
            SI units: encoder positions (m, rad) and velocities (m/s, rad/s) at the start of period
            k, the reference at k, the forces the drives applied over period k - 1 (N, N m).
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
        self.reading.update({
            "SimTime": float(loop.time[k]),
            "PeriodsLeft": self.periods_left,
            "EncoderPosition": q_measured[0].copy(),
            "EncoderVelocity": qd_measured[0].copy(),
            # The planned path's rows, or the bench plan's reference of this period: never written.
            **{name: np.reshape(value, (-1, 3))[0].copy() for name, value in zip(
                ("ReferencePosition", "ReferenceVelocity", "ReferenceAcceleration"), loop.reference_now())},
            # The limit switches see the true joint, not the encoder.
            "AtLimit": (q_true <= self._low) | (q_true >= self._high),
        })
