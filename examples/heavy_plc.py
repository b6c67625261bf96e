"""A PLC for the heavy machine that `python -m bwr_twin.serve` plays: an OPC UA client that, each
cycle, reads the encoders and the path's reference, computes scenes/pid_heavy.toml's per-axis PID
with its holding force, writes the three drive setpoints and steps the machine a cycle's control
periods (lockstep). examples/shadow_demo.py, tools/shadow_latency.py and the live shadow's tests
drive the machine with it.

    plc = await HeavyPlc.attach(client, step=10, period=0.01)
    for _ in range(cycles):
        await plc.cycle()
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from asyncua import Client, ua

from bwr_twin.config.scene import load_scene

GAINS = Path(__file__).resolve().parents[1] / "scenes" / "pid_heavy.toml"
AXES = ("Travel", "Slew", "Luff")
NAMESPACE = "urn:bwr_twin:reclaimer"


class HeavyPlc:
    """The PID of GAINS over OPC UA, `step` control periods of `period` s a cycle."""

    def __init__(self, client: Client, namespace: int, step: int, period: float):
        def node(name: str):
            return client.get_node(ua.NodeId(name, namespace))

        self.client, self.step, self.cycle_s = client, step, step * period
        pid = load_scene(GAINS).controller.settings
        self.kp, self.ki, self.kd = np.array(pid.kp), np.array(pid.ki), np.array(pid.kd)
        self.hold = np.array(pid.holding_force)  # N, N m, N m: the luff's weight held
        self.integral = np.zeros(3)
        self.measured = [node(f"Reclaimer.{a}.{s}") for s in ("EncoderPosition", "EncoderVelocity") for a in AXES]
        self.reference = [node(f"Reclaimer.{a}.{s}") for s in ("ReferencePosition", "ReferenceVelocity") for a in AXES]
        self.setpoints = [node(f"Reclaimer.{a}.DriveSetpoint") for a in AXES]
        self.reclaimer, self.step_method = node("Reclaimer"), node("Reclaimer.Step")

    @classmethod
    async def attach(cls, client: Client, step: int, period: float) -> HeavyPlc:
        """The PLC on `client`, connected to serve's endpoint."""
        return cls(client, await client.get_namespace_index(NAMESPACE), step, period)

    async def cycle(self) -> None:
        """Read, compute, write, and step the machine one cycle."""
        values = np.array(await self.client.read_values(self.measured + self.reference))
        error, rate = values[6:9] - values[0:3], values[9:12] - values[3:6]
        self.integral += error * self.cycle_s
        forces = self.hold + self.kp * error + self.kd * rate + self.ki * self.integral
        await self.client.write_values(self.setpoints, [ua.Variant(float(f), ua.VariantType.Double) for f in forces])
        await self.reclaimer.call_method(self.step_method, ua.Variant(self.step, ua.VariantType.UInt32))
