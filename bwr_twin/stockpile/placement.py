"""Whether a pile stands where its machine can dig it and clear of its rail."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bwr_twin.errors import SceneError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.surface import Surface


def check_placement(surface: Surface, machine: Machine, scene_path: Path) -> None:
    """Raise SceneError if the pile reaches into the rail's strip, or if no part of it lies
    within the wheel's reach anywhere in the operating envelope; also if the machine has no wheel."""
    where = f"{scene_path}: [stockpile]"
    if machine.wheel is None:
        raise SceneError(f"{where}: {machine.path.name} describes no bucket wheel (custom numerics "
                         "'wheel_diameter' and the rest, model contract): it cannot dig a pile")
    g, radius = machine.geometry, machine.wheel.radius
    gy, gx = np.meshgrid(surface.y, surface.x, indexing="ij")
    material = surface.z > 0
    lateral = np.abs(gy - g.slew_axis_xy[1])
    clearance = machine.rail_clearance
    if np.any(material & (lateral < clearance)):
        closest = float(lateral[material].min())
        raise SceneError(
            f"{where}: the pile comes within {closest:.2f} m of the rail axis; the machine needs "
            f"{clearance:.2f} m clear ('rail_clearance' of {machine.path.name})"
        )
    luff = np.linspace(*machine.envelope[2], 181)
    elevation = g.boom_angle0 + luff
    reach = float(np.max(g.pivot_reach + g.boom_length * np.cos(elevation))) + radius
    lowest = float(np.min(g.pivot_height + g.boom_length * np.sin(elevation))) - radius
    travel_low, travel_high = machine.envelope[0] + g.slew_axis_xy[0]
    along = np.maximum(np.maximum(travel_low - gx, gx - travel_high), 0.0)  # outside the slew axis' run
    within = material & (surface.z > lowest) & (np.hypot(along, lateral) <= reach)
    if not within.any():
        raise SceneError(
            f"{where}: no part of the pile (X {surface.x[0]:.1f} to {surface.x[-1]:.1f} m, Y {surface.y[0]:.1f} "
            f"to {surface.y[-1]:.1f} m, up to {surface.z.max():.2f} m high) is within the wheel's reach: "
            f"{reach:.1f} m from the slew axis, whose X runs {travel_low:.1f} to {travel_high:.1f} m, "
            f"down to {lowest:.2f} m"
        )
