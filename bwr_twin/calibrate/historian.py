"""A plant historian's log, CSV or Parquet (`.parquet`, with the `parquet` extra: pyarrow), read
through a small TOML column map that says, for each signal the fit needs, which column holds it,
in what unit, and with what scale and offset:

    [time]
    column = "timestamp"      # seconds (or unit = "ms") from any origin
    unit = "s"
    [signals]
    travel_position = { column = "TRV_ENC", unit = "mm" }
    slew_position = { column = "SLW_ENC", unit = "deg", offset = -0.35 }
    slew_torque = { column = "SLW_TQ", unit = "kN m" }
    luff_current = { column = "LUF_I", unit = "A", torque_constant = 5.2e4 }  # N m per A
    slew_speed = { column = "SLW_V", unit = "deg/s" }   # optional, every axis or none
    wind_speed = { column = "WIND", unit = "km/h" }     # optional; needs [wind]
    [wind]                    # what the wind's force is computed from besides its speed
    direction = 90.0          # deg from world +X towards +Y: where the wind blows to
    air_density = 1.2         # kg/m^3

Each value read is (number x scale + offset) in the unit given, then converted to SI. Every axis
needs its position and its torque (or force), or its current with a torque constant.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bwr_twin.arrays import read_lines
from bwr_twin.calibrate.log import MachineLog
from bwr_twin.config.bounds import AIR_DENSITY
from bwr_twin.errors import BwrError
from bwr_twin.model.machine import AXES

MAX_ROWS = 4_000_000  # 1,000 Hz for an hour and then some
MAX_BYTES = 2 << 30

# Units each kind of signal may be given in, and their factor to SI (per axis kind: linear travel,
# angular slew and luff).
_LINEAR = {"position": {"m": 1.0, "mm": 1e-3}, "speed": {"m/s": 1.0, "m/min": 1 / 60, "mm/s": 1e-3},
           "force": {"N": 1.0, "kN": 1e3, "MN": 1e6}, "current": {"A": 1.0, "kA": 1e3}}
_ANGULAR = {"position": {"rad": 1.0, "deg": math.pi / 180}, "speed": {"rad/s": 1.0, "deg/s": math.pi / 180},
            "force": {"N m": 1.0, "kN m": 1e3, "MN m": 1e6}, "current": {"A": 1.0, "kA": 1e3}}
_TIME = {"s": 1.0, "ms": 1e-3}
_WIND = {"m/s": 1.0, "km/h": 1 / 3.6}
_ALIASES = {"torque": "force"}


def read_historian(path: Path, column_map: Path, machine) -> MachineLog:
    """The log in the CSV or Parquet file at `path` as `column_map` maps it; BwrError naming the
    file, the column and the row of the first problem."""
    entries, time_entry, air = _read_map(column_map)
    what = str(path)
    table = _Parquet(path) if path.suffix.lower() == ".parquet" else _Csv(path)

    def column(entry: dict, key: str) -> np.ndarray:
        name = entry["column"]
        if name not in table.header:
            raise BwrError(f"{what}: no column '{name}' ({column_map}: {key}); the file has {', '.join(table.header)}")
        return table.values(name) * entry.get("scale", 1.0) + entry.get("offset", 0.0)

    time = column(time_entry, "time") * _TIME[time_entry.get("unit", "s")]
    q = np.empty((len(time), 3))
    force = np.empty((len(time), 3))
    speeds = []
    for axis, name in enumerate(AXES):
        units = _LINEAR if axis == 0 else _ANGULAR
        q[:, axis] = column(entries[f"{name}_position"], f"{name}_position") * _factor(
            entries[f"{name}_position"], units["position"], column_map, f"{name}_position")
        if f"{name}_force" in entries:
            entry = entries[f"{name}_force"]
            force[:, axis] = column(entry, f"{name}_force") * _factor(entry, units["force"], column_map, f"{name}_force")
        else:
            entry = entries[f"{name}_current"]
            force[:, axis] = (column(entry, f"{name}_current") * _factor(entry, units["current"], column_map,
                                                                           f"{name}_current") * entry["torque_constant"])
        if f"{name}_speed" in entries:
            entry = entries[f"{name}_speed"]
            speeds.append(column(entry, f"{name}_speed") * _factor(entry, units["speed"], column_map, f"{name}_speed"))
    wind = None
    if "wind_speed" in entries:
        wind = column(entries["wind_speed"], "wind_speed") * _factor(entries["wind_speed"], _WIND, column_map,
                                                                      "wind_speed")
    qd = np.column_stack(speeds) if len(speeds) == 3 else None
    return MachineLog(path=path, time=time, q=q, force=force, qd=qd, wind=wind,
                      wind_heading=math.radians(air[0]) if wind is not None else 0.0,
                      air_density=air[1] if wind is not None else 0.0)


class _Csv:
    """A historian's CSV: a header of column names, then rows of numbers; streamed with a cap."""

    def __init__(self, path: Path):
        self.what = str(path)
        lines = read_lines(path, what=self.what, max_rows=MAX_ROWS + 1, max_bytes=MAX_BYTES,
                           why=f": a log of at most {MAX_ROWS:,} rows and a header")
        if not lines or not lines[0].strip():
            raise BwrError(f"{self.what}: no header; a historian's CSV starts with its column names")
        self.header = [name.strip() for name in lines[0].split(",")]
        self.rows = [line for line in lines[1:] if line.strip()]

    def values(self, name: str) -> np.ndarray:
        index = self.header.index(name)
        values = np.empty(len(self.rows))
        for r, line in enumerate(self.rows):
            fields = line.split(",")
            if len(fields) != len(self.header):
                raise BwrError(f"{self.what}: row {r + 1} has {len(fields)} values for the header's "
                               f"{len(self.header)} columns")
            try:
                values[r] = float(fields[index])
            except ValueError:
                raise BwrError(f"{self.what}: row {r + 1}, column '{name}': '{fields[index].strip()}' is not a "
                               "number") from None
            if not math.isfinite(values[r]):
                raise BwrError(f"{self.what}: row {r + 1}, column '{name}': {fields[index].strip()} (not a finite "
                               "number)")
        return values


class _Parquet:
    """A historian's Parquet file: its schema and row count read first, each column read alone
    only when the map names it, and only if it holds numbers."""

    def __init__(self, path: Path):
        self.what = str(path)
        try:
            import pyarrow.parquet as pq
        except ModuleNotFoundError:
            raise BwrError(f"{self.what}: reading Parquet needs pyarrow: pip install 'bwr_twin[parquet]'") from None
        try:
            self.file = pq.ParquetFile(path)
        except FileNotFoundError:
            raise BwrError(f"{self.what}: no such file") from None
        except Exception as exc:  # noqa: BLE001 - pyarrow's errors for a file it cannot read have no common base
            raise BwrError(f"{self.what}: not a Parquet file pyarrow reads ({str(exc)[:120]})") from None
        rows = self.file.metadata.num_rows
        if rows > MAX_ROWS:
            raise BwrError(f"{self.what}: {rows:,} rows; a log of at most {MAX_ROWS:,} rows")
        self.header = list(self.file.schema_arrow.names)

    def values(self, name: str) -> np.ndarray:
        import pyarrow as pa

        kind = self.file.schema_arrow.field(name).type
        if not (pa.types.is_floating(kind) or pa.types.is_integer(kind)):
            raise BwrError(f"{self.what}: column '{name}' holds {kind}, not numbers")
        try:
            column = self.file.read(columns=[name]).column(0)
        except Exception as exc:  # noqa: BLE001 - as above
            raise BwrError(f"{self.what}: column '{name}' cannot be read ({str(exc)[:120]})") from None
        if column.null_count:
            row = int(np.flatnonzero(column.is_null().to_numpy(zero_copy_only=False))[0])
            raise BwrError(f"{self.what}: row {row + 1}, column '{name}': empty (null)")
        values = column.to_numpy().astype(float)
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise BwrError(f"{self.what}: row {bad[0] + 1}, column '{name}': {values[bad[0]]} (not a finite number)")
        return values


def _factor(entry: dict, units: dict[str, float], column_map: Path, key: str) -> float:
    unit = entry.get("unit")
    if unit not in units:
        raise BwrError(f"{column_map}: signals.{key}: unit {unit!r}; give one of {', '.join(units)}")
    return units[unit]


def _read_map(path: Path) -> tuple[dict[str, dict], dict, tuple[float, float]]:
    """The map's signal entries by canonical name (`AXIS_force` for a torque), its time entry and
    its wind's direction (deg) and air density (kg/m^3), checked."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise BwrError(f"{path}: no such column map") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise BwrError(f"{path}: not a TOML column map: {exc}") from None
    time_entry = raw.get("time")
    if not isinstance(time_entry, dict) or not isinstance(time_entry.get("column"), str):
        raise BwrError(f"{path}: [time] needs column = \"NAME\" (and unit = \"s\" or \"ms\")")
    if time_entry.get("unit", "s") not in _TIME:
        raise BwrError(f"{path}: time.unit {time_entry.get('unit')!r}; give one of {', '.join(_TIME)}")
    signals = raw.get("signals")
    if not isinstance(signals, dict):
        raise BwrError(f"{path}: no [signals] table")
    entries: dict[str, dict] = {}
    known = {f"{a}_{k}" for a in AXES for k in ("position", "force", "torque", "current", "speed")} | {"wind_speed"}
    for key, entry in signals.items():
        if key not in known:
            raise BwrError(f"{path}: signals.{key}: not a signal the fit reads; give AXIS_position, AXIS_torque "
                           "(or AXIS_force), AXIS_current, AXIS_speed or wind_speed")
        if not isinstance(entry, dict) or not isinstance(entry.get("column"), str):
            raise BwrError(f"{path}: signals.{key} needs column = \"NAME\" and unit = \"...\"")
        for number in ("scale", "offset", "torque_constant"):
            if number in entry and (not isinstance(entry[number], (int, float)) or not math.isfinite(entry[number])):
                raise BwrError(f"{path}: signals.{key}.{number} must be a finite number")
        axis, _, kind = key.partition("_")
        entries[f"{axis}_{_ALIASES.get(kind, kind)}"] = entry
    for axis in AXES:
        if f"{axis}_position" not in entries:
            raise BwrError(f"{path}: signals.{axis}_position missing: the fit needs every axis's encoder")
        if f"{axis}_force" not in entries:
            current = entries.get(f"{axis}_current")
            if current is None:
                raise BwrError(f"{path}: signals.{axis}_torque missing: give the drive's torque (or force), or its "
                               f"current with a torque_constant")
            if not current.get("torque_constant", 0) > 0:
                raise BwrError(f"{path}: signals.{axis}_current needs a torque_constant > 0 (N or N m per A)")
    speeds = [f"{axis}_speed" in entries for axis in AXES]
    if any(speeds) and not all(speeds):
        raise BwrError(f"{path}: signals: give the speed of every axis or of none")
    return entries, time_entry, _read_wind(path, raw.get("wind"), "wind_speed" in entries)


def _read_wind(path: Path, table, logged: bool) -> tuple[float, float]:
    """[wind]'s direction (deg) and air density (kg/m^3): what the logged wind speed's force is
    computed from; (0, 0) where no wind speed is logged."""
    if table is None and not logged:
        return 0.0, 0.0
    if table is None:
        raise BwrError(f"{path}: signals.wind_speed needs a [wind] table: direction = DEG (where the wind blows "
                       "to, from world +X towards +Y) and air_density = KG/M3")
    if not logged:
        raise BwrError(f"{path}: [wind] without signals.wind_speed: map the wind speed's column, or drop [wind]")
    if not isinstance(table, dict):
        raise BwrError(f"{path}: wind must be a table: [wind] with direction = DEG and air_density = KG/M3")
    unknown = sorted(set(table) - {"direction", "air_density"})
    if unknown:
        raise BwrError(f"{path}: wind.{unknown[0]}: not a key of [wind]; give direction and air_density")
    values = []
    for key, unit in (("direction", "deg"), ("air_density", "kg/m^3")):
        value = table.get(key)
        if value is None:
            raise BwrError(f"{path}: wind.{key} missing: give it in {unit}")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise BwrError(f"{path}: wind.{key} is {value!r}; give a finite number in {unit}")
        values.append(float(value))
    direction, density = values
    if not -360.0 <= direction <= 360.0:
        raise BwrError(f"{path}: wind.direction is {direction:g} deg; give -360 to 360 deg")
    low, high = AIR_DENSITY
    if not low <= density <= high:
        raise BwrError(f"{path}: wind.air_density is {density:g} kg/m^3; air at a mine is {low:g} to {high:g} kg/m^3 "
                       "(ISO 2533)")
    return direction, density
