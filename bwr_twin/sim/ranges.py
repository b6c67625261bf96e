"""The EURange of every analog variable of the address space: the range its value takes in
normal operation (OPC UA Part 8), from the machine's MJCF where it says, else by a rule that
docs/opcua.md states; never infinite, never empty.

    Encoder/ReferencePosition  the joint's end stops (`range`), else the envelope; else UNLIMITED_POSITION
    Encoder/ReferenceVelocity  ± `rated_speed_<axis>`; else ± the position range crossed in UNRATED_CROSSING
    DriveSetpoint/Applied      the drive rating (`forcerange`, or `ctrlrange` × gear); else what gives
                               ± UNRATED_ACCELERATION from rest at home, against gravity
    ReferenceAcceleration      what the drive's range gives from rest at home: (force − gravity) / inertia

SimTime spans the path (of a bench plan, the most it may take), ControlPeriod 0 to the period,
ReclaimRate 0 to the wheel's capacity at the stockpile's bulk density.

The instruments and scanners, served only by a run that has them (bwr_twin.serve.sensing):

    BeltScale                  as ReclaimRate: what it weighs is what the wheel carries
    WheelCurrent               0 to the motor's current at the wheel drive's rating (`wheel_power`);
                               without one, at the power of cutting the wheel's capacity with the
                               scene's [digging]; without that, NO_POWER_CURRENT
    a scanner's Ranges         0 to its range (`{site}_range`); Angles its fan; ScanTime as SimTime
    WindSpeed                  the scene's mean wind less and plus its gust amplitude, and 0 (a
                               plant with wind)
"""

from __future__ import annotations

import math

import numpy as np

from bwr_twin.model.machine import AXES
from bwr_twin.sim.lockstep import Lockstep
from bwr_twin.units import KG_PER_T, SECONDS_PER_HOUR

# Conventions for what the machine's file does not rate; none is a number of a machine.
UNRATED_ACCELERATION = 1.0  # m/s², rad/s²: an unrated drive's range gives this, from rest at home
UNRATED_CROSSING = 60.0  # s: an axis without a rated speed crosses its position range in this time
UNLIMITED_POSITION = (1000.0, math.pi)  # m (a stockyard's rail), rad (a turn): no end stops, no envelope
NO_STOCKPILE_RATE = 1.0  # t/h: the span without a stockpile (the rate reads 0 throughout)
NO_POWER_CURRENT = 1.0  # A: the span of a wheel current that no [digging] loads (it reads its noise about 0)

Range = tuple[float, float]


def eu_ranges(loop: Lockstep) -> dict[tuple[str, str | None], Range]:
    """(variable, axis or None) -> (low, high) in SI units (t/h for ReclaimRate), for the run of `loop`."""
    machine = loop.machine
    position = np.array(machine.joint_range, dtype=float)
    position = np.where(np.isfinite(position), position, machine.envelope)
    unlimited = np.array([[-UNLIMITED_POSITION[j > 0], UNLIMITED_POSITION[j > 0]] for j in range(3)])
    position = np.where(np.isfinite(position), position, unlimited)
    crossing = (position[:, 1] - position[:, 0]) / UNRATED_CROSSING
    speed = np.where(np.isfinite(machine.rated_speed), machine.rated_speed, crossing)
    velocity = np.stack([-speed, speed], axis=1)
    mass, bias = machine.dynamics.at(np.zeros(3), np.zeros(3))  # at home, at rest: gravity only
    inertia = np.diag(mass)[:, None]
    unrated = bias[:, None] + inertia * np.array([-UNRATED_ACCELERATION, UNRATED_ACCELERATION])
    force = np.where(np.isfinite(machine.drive_limits), machine.drive_limits, unrated)
    acceleration = (force - bias[:, None]) / inertia
    per_axis = {"EncoderPosition": position, "ReferencePosition": position, "EncoderVelocity": velocity,
                "ReferenceVelocity": velocity, "ReferenceAcceleration": acceleration, "DriveSetpoint": force,
                "DriveCommanded": force, "DriveApplied": force}
    ranges: dict[tuple[str, str | None], Range] = {
        (name, axis): (float(values[j, 0]), float(values[j, 1]))
        for name, values in per_axis.items() for j, axis in enumerate(AXES)}
    ranges["SimTime", None] = (0.0, float(loop.duration))
    ranges["ControlPeriod", None] = (0.0, float(loop.period))
    ranges["ReclaimRate", None] = (0.0, _reclaim_capacity(loop))
    instruments = loop.instruments
    if instruments is not None and instruments.scale is not None:
        ranges["BeltScale", None] = (0.0, belt_scale_span(loop))
    if instruments is not None and instruments.motor is not None:
        ranges["WheelCurrent", None] = (0.0, wheel_current_span(loop))
    if loop.wind_speed is not None:
        plant = loop.scenes[0].plant
        low, high = plant.wind_speed - plant.gust_amplitude, plant.wind_speed + plant.gust_amplitude
        ranges["WindSpeed", None] = (min(0.0, low), max(0.0, high))
    if loop.neighbour is not None:  # its envelope, and the run's time
        for j, axis in enumerate(AXES):
            ranges["NeighbourPosition", axis] = tuple(float(v) for v in loop.neighbour.machine.envelope[j])
        ranges["NeighbourReportTime", None] = (0.0, float(loop.duration))
    return ranges


def belt_scale_span(loop: Lockstep) -> float:
    """t/h: the top of the belt scale's range, the wheel's capacity (as ReclaimRate's)."""
    return _reclaim_capacity(loop)


def wheel_current_span(loop: Lockstep) -> float:
    """A: the top of the wheel current's range, the current at the wheel drive's rated power (the
    digging load never draws more), else at the power of cutting the wheel's capacity; ValueError
    if the run has no wheel motor."""
    motor = loop.instruments.motor if loop.instruments is not None else None
    if motor is None:
        raise ValueError("the run has no wheel motor (custom numeric 'wheel_motor', docs/sensing.md)")
    wheel = loop.machine.wheel
    power = wheel.power
    if not math.isfinite(power):
        digging = loop.scenes[0].digging
        if digging is None:
            return NO_POWER_CURRENT
        power = digging.cutting_energy * wheel.capacity + digging.idle_power
    return power * motor.amps_per_watt


def scanner_ranges(scanner, duration: float) -> dict[str, Range]:
    """A scanner's Ranges (m), Angles (rad) and ScanTime (s) ranges, for a run of `duration` s."""
    return {"Ranges": (0.0, float(scanner.max_range)), "Angles": (float(scanner.fan[0]), float(scanner.fan[1])),
            "ScanTime": (0.0, float(duration))}


def _reclaim_capacity(loop: Lockstep) -> float:
    """t/h the bucket wheel carries at most: its volume a second times the pile's bulk density."""
    if loop.reclaim is None:
        return NO_STOCKPILE_RATE
    density = float(loop.reclaim.density[0])  # kg/m³
    return loop.machine.wheel.capacity * density * SECONDS_PER_HOUR / KG_PER_T
