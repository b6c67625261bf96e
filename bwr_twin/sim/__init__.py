"""Simulation: the plant on MuJoCo's batch, encoders, disturbances and the lockstep loop."""

from bwr_twin.sim.lockstep import lockstep_key, simulate, simulate_grouped, simulate_lockstep

__all__ = ["lockstep_key", "simulate", "simulate_grouped", "simulate_lockstep"]
