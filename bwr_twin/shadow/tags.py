"""The tag map: which OPC UA variables of the machine's PLC the live shadow reads, from tags.toml.

    machine = "bwr_heavy"                 # the model name of the MJCF the shadow runs (<mujoco model=...>)
    namespace = "urn:bwr_twin:reclaimer"  # the namespace URI of the node ids below
    time = "Reclaimer.SimTime"            # s: when the readings were taken

    [travel]                              # and [slew], [luff]
    position = "Reclaimer.Travel.EncoderPosition"   # m (rad): the position encoder
    speed = "Reclaimer.Travel.EncoderVelocity"      # m/s (rad/s): the drive's speed feedback
    force = "Reclaimer.Travel.DriveSetpoint"        # N (N m): the drive's force, as the drive reports it

    [wind]                                # optional: the machine's anemometer
    speed = "Reclaimer.WindSpeed"         # m/s towards `direction`, over the period that ended at `time`
    direction = 90.0                      # deg from world +X towards +Y: where the wind blows to
    air_density = 1.204                   # kg/m^3

Node ids are string identifiers in the namespace. A map written for another machine is refused
(its `machine` names another model than the MJCF's), and so is a key it does not know.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.errors import BwrError
from bwr_twin.shadow.measured import Air
from bwr_twin.tomlfile import read_toml

AXES = ("travel", "slew", "luff")
SIGNALS = ("position", "speed", "force")
# The unit each tag must carry (its EngineeringUnits' display name), per axis: travel, then slew and luff.
UNITS = {"time": ("s", "s"), "position": ("m", "rad"), "speed": ("m/s", "rad/s"), "force": ("N", "N·m")}
WIND_KEYS = ("speed", "direction", "air_density")
MAX_AIR_DENSITY = 2.0  # kg/m^3: above any air a machine works in (1.52 at -40 degC and 1,050 hPa)


@dataclass(frozen=True)
class WindTag:
    """The anemometer's node id, and the air its wind blows in."""

    speed: str
    air: Air


@dataclass(frozen=True)
class Tags:
    """A tags.toml: the machine's model name, the namespace URI, the time's node id and per axis
    (travel, slew, luff) the node ids of SIGNALS; the anemometer's, or None."""

    path: Path
    machine: str
    namespace: str
    time: str
    axes: dict[str, dict[str, str]]
    wind: WindTag | None = None

    def nodes(self) -> list[tuple[str, str, str]]:
        """(node id, what it is, unit) of every tag: the time, then per axis position, speed,
        force, then the wind's speed if the map has it."""
        found = [(self.time, "time", "s")]
        for j, axis in enumerate(AXES):
            found += [(self.axes[axis][signal], f"{axis}.{signal}", UNITS[signal][min(j, 1)]) for signal in SIGNALS]
        if self.wind is not None:
            found.append((self.wind.speed, "wind.speed", "m/s"))
        return found


def read_tags(path: Path, model_name: str) -> Tags:
    """The tag map at `path` for the machine whose MJCF model is `model_name`; BwrError naming
    the file and the key otherwise."""
    data = read_toml(path, "tag map")
    known = {"machine", "namespace", "time", "wind", *AXES}
    for key in data:
        if key not in known:
            raise BwrError(f"{path}: '{key}' is not a key of a tag map (it has: {', '.join(sorted(known))})")
    for key in ("machine", "namespace", "time"):
        if not isinstance(data.get(key), str) or not data[key]:
            raise BwrError(f"{path}: '{key}' must be a string" + (" (it is missing)" if key not in data else ""))
    if data["machine"] != model_name:
        raise BwrError(f"{path}: the tag map is for machine {data['machine']!r}, the model is {model_name!r}: "
                       "a map for another machine is refused")
    axes = {}
    for axis in AXES:
        table = data.get(axis)
        if not isinstance(table, dict):
            raise BwrError(f"{path}: '[{axis}]' is missing: it names the axis's {', '.join(SIGNALS)} tags")
        for key in table:
            if key not in SIGNALS:
                raise BwrError(f"{path}: '{axis}.{key}' is not a tag of an axis (they are: {', '.join(SIGNALS)})")
        for signal in SIGNALS:
            if not isinstance(table.get(signal), str) or not table[signal]:
                raise BwrError(f"{path}: '{axis}.{signal}' must be a node id string")
        axes[axis] = dict(table)
    return Tags(path, data["machine"], data["namespace"], data["time"], axes,
                _wind(path, data["wind"]) if "wind" in data else None)


def _wind(path: Path, table: object) -> WindTag:
    """The [wind] table: the anemometer's node id, the heading and the air density, checked."""
    if not isinstance(table, dict):
        raise BwrError(f"{path}: 'wind' must be a table: [wind] with {', '.join(WIND_KEYS)}")
    for key in table:
        if key not in WIND_KEYS:
            raise BwrError(f"{path}: 'wind.{key}' is not a key of [wind] (it has: {', '.join(WIND_KEYS)})")
    if not isinstance(table.get("speed"), str) or not table["speed"]:
        raise BwrError(f"{path}: 'wind.speed' must be a node id string")
    numbers = {}
    for key, low, high, unit in (("direction", -360.0, 360.0, "deg"), ("air_density", 0.0, MAX_AIR_DENSITY, "kg/m^3")):
        value = table.get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not low < value <= high:
            raise BwrError(f"{path}: 'wind.{key}' must be a number in ({low:g}, {high:g}] {unit}, got {value!r}")
        numbers[key] = float(value)
    return WindTag(table["speed"], Air(math.radians(numbers["direction"]), numbers["air_density"]))
