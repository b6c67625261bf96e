"""Simulation: the plant on MuJoCo's batch, encoders, disturbances and the lockstep loop; one run as
the machine, advanced a control period at a time under forces computed elsewhere (twin), and the
ranges its variables take (ranges), which the OPC UA server, the FMU and the gym share."""

from bwr_twin.sim.lockstep import lockstep_key, simulate, simulate_grouped, simulate_lockstep

__all__ = ["lockstep_key", "simulate", "simulate_grouped", "simulate_lockstep"]
