"""The readers of a run directory's files (docs/contracts.md, "Output contract"), one per format,
each giving a typed record:

    timeseries.csv   read_timeseries -> TimeSeries: the time, the signals by name with their units,
                     the CP, the wind, and a stockpile's, a stacking's, a neighbour's columns
    scene.json       read_scene -> RunScene: the scene file, the machine, the controller, the
                     timing, the path's via points and which parts the scene has

A file is hostile until checked: each reader refuses, in one line naming the file, the column or
key and the row, a missing column or key, a value of the wrong type, a cell that is not a number,
a non-finite value where the contract writes none, a time that does not increase and a position
no machine takes (within its operating envelope and as much again either side when the reader is
given it, within bwr_twin.config.bounds' yard otherwise). The time series is read through the
capped line reader (bwr_twin.arrays.read_lines). `timeseries_of` and `RunScene.of` build the
same records from a run held in memory.
"""

from __future__ import annotations

import difflib
import json
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.arrays import read_lines
from bwr_twin.config.bounds import JOINT_ANGLE, JOINT_ANGLE_SOURCE, YARD_EXTENT, YARD_EXTENT_SOURCE
from bwr_twin.errors import BwrError
from bwr_twin.model.machine import AXES, paper_to_world
from bwr_twin.signals import LOOP, NEIGHBOUR, RECLAIM, UNITS, Signal, column_name
from bwr_twin.values import is_integer, is_number

# The most rows a timeseries.csv is read with (a header besides): 12 h, the longest run the budget
# starts without --force (bwr_twin.sim.budget), recorded every 0.01 s are 4,320,000 rows. Its rows
# take some 500 bytes each (43 columns of a stacking), 2 GB; 4 GiB is the most a file is read with.
MAX_TIMESERIES_ROWS = 5_000_000
MAX_TIMESERIES_BYTES = 4 << 30
# A scene.json holds the resolved scene, a few kB; a path of many thousand via points some MB.
MAX_SCENE_LINES = 1_000_000
MAX_SCENE_BYTES = 64 << 20

TIME = "time_s"
WIND = "wind_speed_m/s"
STACKED = "stacked_t"
CP = {kind: tuple(f"cp_{kind}_{c}_m" for c in "xyz") for kind in ("desired", "actual")}
# Grade columns: their prefix, and what the grade is of (the replay's chart says it).
GRADE_PREFIXES = (("stacking_grade_in_", "stacked"), ("grade_out_", "reclaimed"))
# Columns the contract writes NaN in: instruments a machine lacks, a grade before the first discharge.
_MAY_BE_NAN = ("belt_scale_t/h", "wheel_current_A")
_POSITIONS = tuple(signal for signal in LOOP if signal.kind == "q")  # bounded by the machine's envelope
# The columns every timeseries.csv holds (bwr_twin.results.rundir.timeseries_columns writes the
# controller's signals after the loop's).
COLUMNS = (TIME, *(column_name(signal, j) for signal in LOOP for j in range(len(AXES))), *CP["desired"],
           *CP["actual"], WIND)


@dataclass(frozen=True)
class GradeSeries:
    """The grade a run charts: what was stacked as it arrived ("stacked"), or what left a stacked
    pile as the belt scale passed it ("reclaimed"); `values` (n,) at the record times, NaN before
    the first discharge passed."""

    name: str  # what the grade is: "Fe %"
    kind: str  # "stacked" or "reclaimed"
    values: np.ndarray


@dataclass(frozen=True)
class TimeSeries:
    """A run's timeseries.csv: every array has a row per record time, in SI units, per axis in the
    order travel, slew, luff; positions of the CP in world coordinates.

    `signals` holds the loop's signals by their RunResult name ("q_desired", "q", "qd_measured",
    ... bwr_twin.signals.LOOP) and the controller's by their column stem ("fuzzy_output"), each
    (n, 3), with `units` their units per axis ("m", "rad", "rad"); `controller_signals` names the
    controller's. `reclaim` (with a stockpile) holds bwr_twin.signals.RECLAIM's by name ("rate",
    t/h; "digging_force", (n, 3) N), `neighbour` (with a second machine) its "q_desired" and "q"
    (n, 3). `columns` is every column by the name the file gives it."""

    time: np.ndarray  # (n,) s
    signals: Mapping[str, np.ndarray]
    units: Mapping[str, tuple[str, str, str]]
    controller_signals: tuple[str, ...]
    cp_desired: np.ndarray  # (n, 3) m
    cp_actual: np.ndarray  # (n, 3) m
    wind_speed: np.ndarray  # (n,) m/s
    columns: Mapping[str, np.ndarray]
    reclaim: Mapping[str, np.ndarray] | None = None
    neighbour: Mapping[str, np.ndarray] | None = None
    grade: GradeSeries | None = None  # a stacking's grade arriving, or a stacked pile's reclaimed
    stacked: np.ndarray | None = None  # (n,) t laid by the deposit under way, of a stacking


@dataclass(frozen=True)
class _Layout:
    """Which columns of a header make which part of a TimeSeries, checked to be all there."""

    signals: dict[str, tuple[str, str, str]]
    units: dict[str, tuple[str, str, str]]
    controller_signals: tuple[str, ...]
    reclaim: dict[str, tuple[str, ...]] | None
    neighbour: dict[str, tuple[str, str, str]] | None
    grade: tuple[str, str, str] | None  # (column, grade name, kind)

    @classmethod
    def of(cls, names: Sequence[str], what: str) -> _Layout:
        present = set(names)
        if len(present) < len(names):
            twice = next(name for name in names if names.count(name) > 1)
            raise BwrError(f"{what}: the column '{twice}' appears twice in the header")
        loop = {signal.name: _axis_columns(signal) for signal in LOOP}
        required = list(COLUMNS)
        neighbour = None
        if any(column in present for signal in NEIGHBOUR for column in _axis_columns(signal)):
            neighbour = {signal.name: _axis_columns(signal) for signal in NEIGHBOUR}
            required += [c for columns in neighbour.values() for c in columns]
        reclaim = None
        if RECLAIM[0][1] in present:
            reclaim = {name: (column,) if width == 1 else tuple(column.format(xyz=c) for c in "xyz")
                       for name, column, width in RECLAIM}
            required += [c for columns in reclaim.values() for c in columns]
        _require(required, names, what)
        controller = _controller_columns(names, set(required), what)
        units = {signal.name: UNITS[signal.kind] for signal in LOOP}
        units.update({stem: tuple(column.rpartition("_")[2] for column in columns)
                      for stem, columns in controller.items()})
        grade = next(((column, column.removeprefix(prefix), kind) for prefix, kind in GRADE_PREFIXES
                      for column in names if column.startswith(prefix)), None)
        return cls({**loop, **controller}, units, tuple(controller), reclaim, neighbour, grade)

    def series(self, names: Sequence[str], values: np.ndarray) -> TimeSeries:
        columns = {name: values[:, i] for i, name in enumerate(names)}

        def stack(group: tuple[str, ...]) -> np.ndarray:
            return columns[group[0]] if len(group) == 1 else np.column_stack([columns[c] for c in group])

        def stacked(groups: dict[str, tuple[str, ...]] | None) -> dict[str, np.ndarray] | None:
            return None if groups is None else {name: stack(group) for name, group in groups.items()}

        grade = None if self.grade is None else GradeSeries(self.grade[1], self.grade[2], columns[self.grade[0]])
        return TimeSeries(time=columns[TIME], signals=stacked(self.signals), units=self.units,
                          controller_signals=self.controller_signals, cp_desired=stack(CP["desired"]),
                          cp_actual=stack(CP["actual"]), wind_speed=columns[WIND], columns=columns,
                          reclaim=stacked(self.reclaim), neighbour=stacked(self.neighbour), grade=grade,
                          stacked=columns.get(STACKED))


def _axis_columns(signal: Signal) -> tuple[str, str, str]:
    return tuple(column_name(signal, j) for j in range(len(AXES)))


def _require(required: Sequence[str], names: Sequence[str], what: str) -> None:
    """A BwrError naming the first of `required` that `names` lacks, and the column it may have become."""
    present = set(names)
    missing = [name for name in required if name not in present]
    if missing:
        like = difflib.get_close_matches(missing[0], [name for name in names if name not in required], n=1)
        renamed = f": renamed '{like[0]}'?" if like else ""
        raise BwrError(f"{what}: no column '{missing[0]}', which bwr_twin.run writes (docs/contracts.md){renamed}")


def _controller_columns(names: Sequence[str], known: set[str], what: str) -> dict[str, tuple[str, str, str]]:
    """The controller's signals (bwr_twin.signals: 'travel_fuzzy_output_1', ...) by their column
    stem: every other column of the form '<axis>_<stem>_<unit>', each with its three axes."""
    by_axis: dict[str, dict[str, str]] = {axis: {} for axis in AXES}
    for name in names:
        axis, _, rest = name.partition("_")
        stem, _, unit = rest.rpartition("_")
        if axis in by_axis and stem and unit and name not in known:
            by_axis[axis][stem] = name
    signals = {}
    for stem, travel in by_axis["travel"].items():
        for axis in AXES[1:]:
            if stem not in by_axis[axis]:
                raise BwrError(f"{what}: no column '{axis}_{stem}_<unit>' beside '{travel}': a controller's "
                               "signal has a column per axis")
        signals[stem] = (travel, by_axis["slew"][stem], by_axis["luff"][stem])
    return signals


def timeseries_of(names: Sequence[str], values: np.ndarray, what: str = "the run") -> TimeSeries:
    """The TimeSeries of columns `names` holding `values` (n, columns): a run's in memory
    (bwr_twin.results.rundir.timeseries_columns)."""
    return _Layout.of(list(names), what).series(names, values)


def read_timeseries(path: str | Path, *, envelope: np.ndarray | None = None,
                    neighbour_envelope: np.ndarray | None = None) -> TimeSeries:
    """A run directory's timeseries.csv, checked: its columns all there, every row complete and
    numbers, finite (NaN only where the contract writes it), the time increasing, and the joint
    positions within `envelope` (3, 2) (m, rad: the machine's operating envelope, bwr_twin.model)
    and as much again either side, the neighbour's within `neighbour_envelope`; without them
    within bwr_twin.config.bounds' yard, as are the CP's. A problem is one BwrError naming the
    file, the row (1 = the first after the header) and the column."""
    what = str(path)
    lines = read_lines(path, what=what, max_rows=MAX_TIMESERIES_ROWS + 1, max_bytes=MAX_TIMESERIES_BYTES,
                       why=f": a time series of at most {MAX_TIMESERIES_ROWS:,} rows and a header")
    if not lines or not lines[0].strip():
        raise BwrError(f"{what}: no header; a time series starts with its column names")
    names = lines[0].strip().split(",")
    layout = _Layout.of(names, what)
    rows = [line for line in lines[1:] if line.strip()]
    values = _numbers(what, names, rows)
    _check_finite(what, names, values)
    steps = np.diff(values[:, names.index(TIME)])
    if not (steps > 0).all():
        row, column = int(np.argmax(~(steps > 0))) + 2, names.index(TIME)
        raise BwrError(f"{what}: row {row}, column '{TIME}': {values[row - 1, column]:g} s does not come after the "
                       f"row before's {values[row - 2, column]:g} s")
    for j in range(len(AXES)):
        for signals, limits in ((_POSITIONS, envelope), (NEIGHBOUR if layout.neighbour else (), neighbour_envelope)):
            low, high, why = _position_bounds(j, limits)
            for signal in signals:
                _check_within(what, names, values, column_name(signal, j), low, high, why)
    for column in CP["desired"] + CP["actual"]:
        _check_within(what, names, values, column, -YARD_EXTENT, YARD_EXTENT, YARD_EXTENT_SOURCE)
    return layout.series(names, values)


def _numbers(what: str, names: list[str], rows: list[str]) -> np.ndarray:
    """The rows as an (n, columns) array, or the BwrError naming the first row that is short, long
    or holds something not a number, and its column."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # no rows: numpy warns of an empty input
            values = np.loadtxt(rows, delimiter=",", ndmin=2)
    except ValueError:
        values = None
    if values is not None and values.size == 0:
        return np.empty((0, len(names)))
    if values is not None and values.shape[1] == len(names):
        return values
    for number, line in enumerate(rows, start=1):  # numpy's message names no column: find the row and say it
        fields = line.split(",")
        if len(fields) != len(names):
            raise BwrError(f"{what}: row {number} has {len(fields)} values for the header's {len(names)} columns "
                           f"(a truncated or damaged file): column '{names[min(len(fields), len(names)) - 1]}' "
                           "is the last it fills")
        for name, field in zip(names, fields):
            try:
                float(field)
            except ValueError:
                raise BwrError(f"{what}: row {number}, column '{name}': {field.strip()!r} is not a number") from None
    raise BwrError(f"{what}: unreadable as numbers")


def _check_finite(what: str, names: list[str], values: np.ndarray) -> None:
    """A BwrError naming the first NaN or infinity, in row order, beyond the NaN the contract writes."""
    bad = ~np.isfinite(values)
    for i, name in enumerate(names):
        if name in _MAY_BE_NAN or name.startswith(tuple(prefix for prefix, _ in GRADE_PREFIXES)):
            bad[:, i] = np.isinf(values[:, i])
    if bad.any():
        row, i = np.argwhere(bad)[0]
        raise BwrError(f"{what}: row {row + 1}, column '{names[i]}': {values[row, i]}, not a finite number")


def _position_bounds(axis: int, envelope: np.ndarray | None) -> tuple[float, float, str]:
    """(low, high, why) of a position of one axis: the machine's envelope and its width again
    either side where it is known and limited, the physical bound otherwise."""
    unit = UNITS["q"][axis]
    if envelope is not None and np.isfinite(envelope[axis]).all():
        low, high = (float(v) for v in envelope[axis])
        width = high - low
        return low - width, high + width, (f"the machine's operating envelope [{low:g}, {high:g}] {unit} and as "
                                           "much again either side")
    limit, why = (YARD_EXTENT, YARD_EXTENT_SOURCE) if unit == "m" else (JOINT_ANGLE, JOINT_ANGLE_SOURCE)
    return -limit, limit, why


def _check_within(what: str, names: list[str], values: np.ndarray, column: str, low: float, high: float,
                  why: str) -> None:
    i = names.index(column)
    outside = np.flatnonzero((values[:, i] < low) | (values[:, i] > high))
    if outside.size:
        row = int(outside[0])
        unit = column.rpartition("_")[2]
        raise BwrError(f"{what}: row {row + 1}, column '{column}': {values[row, i]:g} {unit} lies outside "
                       f"[{low:g}, {high:g}] {unit} ({why})")


@dataclass(frozen=True)
class RunScene:
    """What a run's scene.json (the resolved scene, bwr_twin.config.scene.Scene.to_dict) says
    that its readers use. Tables a run of an earlier version did not write (`stockpile`,
    `reclaim`, `stacking`, `neighbour`) read as absent."""

    path: Path  # the scene file the run was resolved from
    mjcf: Path  # the machine's MJCF
    controller: str  # the controller's type, as the scene names it: "fuzzy_model", "pid", ...
    timestep: float  # s, physics
    control_period: float  # s
    record_period: float  # s, the rows of timeseries.csv
    seed: int
    via_times: np.ndarray | None  # (k,) s of a [path]'s via points; None: the run's plan decided them
    via_points: np.ndarray | None  # (k, 3) world m
    stockpile: bool  # the scene has a pile
    reclaim: bool  # a bench reclaim planned from the pile ([reclaim])
    stacking: bool  # the machine stacks a pile ([stacking])
    neighbour_mjcf: Path | None  # a second machine on the rail, if the scene has one
    wind_direction: float = 0.0  # deg from world +X towards +Y: where the plant's wind blew to
    air_density: float = 0.0  # kg/m^3 the plant's wind met; 0 for a run in still air (no wind, no gusts)

    @property
    def title(self) -> str:
        return self.path.name

    @property
    def activity(self) -> str:
        """What the machine does, for labels: "reclaim" or "stacking"."""
        return "stacking" if self.stacking else "reclaim"

    @classmethod
    def of(cls, data: Any, what: str) -> RunScene:
        """From scene.json's object (or a Scene's to_dict); a BwrError naming `what` and the key
        that is missing or of the wrong type."""
        if not isinstance(data, dict):
            raise _not_a_scene(what, f"{_described(data)}, not an object")
        path = _key(data, "trajectory", what, "object", optional=False)  # null: the run's plan decides
        via_times = via_points = None
        if path is not None:
            frame = _key(data, "trajectory.frame", what, "text")
            if frame not in ("paper", "world"):
                raise _not_a_scene(what, f"'trajectory.frame' is {frame!r}, not 'paper' or 'world'")
            via = _key(data, "trajectory.via_points", what, "list")
            via_times = np.array([_key(v, "t", what, "number", where=f"trajectory.via_points[{i}]")
                                  for i, v in enumerate(via)], dtype=float)
            via_points = np.array([_point(v, i, what) for i, v in enumerate(via)], dtype=float).reshape(-1, 3)
            if frame == "paper":
                via_points = paper_to_world(via_points)
        neighbour = _key(data, "neighbour", what, "object", optional=True)
        plant = {k: _key(data, f"plant.{k}", what, "number", optional=True)
                 for k in ("wind_speed", "gust_amplitude", "wind_direction", "air_density")}
        windy = bool(plant["wind_speed"] or plant["gust_amplitude"])  # the plant's rule: still air costs no drag
        return cls(
            path=Path(_key(data, "path", what, "text")),
            mjcf=Path(_key(data, "machine.mjcf", what, "text")),
            controller=_key(data, "controller.type", what, "text"),
            timestep=float(_key(data, "simulation.timestep", what, "number")),
            control_period=float(_key(data, "simulation.control_period", what, "number")),
            record_period=float(_key(data, "simulation.record_period", what, "number")),
            seed=_key(data, "simulation.seed", what, "whole number"),
            via_times=via_times,
            via_points=via_points,
            stockpile=_key(data, "stockpile", what, "object", optional=True) is not None,
            reclaim=_key(data, "reclaim", what, "object", optional=True) is not None,
            stacking=_key(data, "stacking", what, "object", optional=True) is not None,
            neighbour_mjcf=None if neighbour is None else Path(_key(data, "neighbour.mjcf", what, "text")),
            wind_direction=float(plant["wind_direction"] or 0.0),
            air_density=float(plant["air_density"] or 0.0) if windy else 0.0,
        )


def read_scene(path: str | Path) -> RunScene:
    """A run directory's scene.json as a RunScene; one BwrError naming the file (and the key) for
    a file that is missing, too large, not JSON or not a scene as bwr_twin.run writes it."""
    what = str(path)
    lines = read_lines(path, what=what, max_rows=MAX_SCENE_LINES, max_bytes=MAX_SCENE_BYTES,
                       why=": a run's resolved scene")
    try:
        data = json.loads("\n".join(lines))
    except json.JSONDecodeError as exc:
        raise BwrError(f"{what}: not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})") from None
    except RecursionError:
        raise BwrError(f"{what}: not a scene as bwr_twin.run writes it: nested too deep") from None
    return RunScene.of(data, what)


_TYPES = {"text": lambda v: isinstance(v, str), "number": is_number, "whole number": is_integer,
          "object": lambda v: isinstance(v, dict), "list": lambda v: isinstance(v, list)}


def _not_a_scene(what: str, why: str) -> BwrError:
    return BwrError(f"{what}: not a scene as bwr_twin.run writes it: {why}")


def _described(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f"text ({value[:40]!r})"
    if isinstance(value, (int, float)):
        return f"the number {value:g}"
    return "a list" if isinstance(value, list) else "an object"


def _key(data: dict, dotted: str, what: str, kind: str, *, optional: bool | None = None, where: str = "") -> Any:
    """The value at the dotted key, checked to be of `kind`; with `optional` it may also be null,
    and with optional=True (a table a scene of an earlier version lacks) absent too. `where` is
    the key of `data` itself in the scene, for messages: "trajectory.via_points[2]"."""
    value: Any = data
    parts = [where, *dotted.split(".")] if where else dotted.split(".")
    for depth, part in enumerate(parts[1:] if where else parts, start=1 if where else 0):
        if not isinstance(value, dict):
            raise _not_a_scene(what, f"'{'.'.join(parts[:depth])}' is {_described(value)}, not an object")
        if part not in value:
            if optional:
                return None
            raise _not_a_scene(what, f"no key '{'.'.join(parts)}'")
        value = value[part]
    if (value is None and optional is not None) or _TYPES[kind](value):
        return value
    wanted = f"{'an' if kind[0] in 'aeiou' else 'a'} {kind}" if kind != "text" else "text"
    null = " or null" if optional is not None else ""
    raise _not_a_scene(what, f"'{'.'.join(parts)}' is {_described(value)}, not {wanted}{null}")


def _point(value: Any, index: int, what: str) -> list[float]:
    where = f"trajectory.via_points[{index}]"
    p = _key(value, "p", what, "list", where=where)
    if len(p) != 3 or not all(is_number(x) for x in p):
        raise _not_a_scene(what, f"'{where}.p' is not three numbers (x, y, z m)")
    return p
