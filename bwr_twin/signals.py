"""The signals a run records: one schema for the recorder, the run directory's CSV columns and
units, and the budget's estimate of what a run holds in memory and on disk.

Every run records the loop's own signals (`LOOP`). A controller declares the extra signals it
keeps up to date (`Controller.signals`: the fuzzy controller its FLC output and acceleration
command, a PID none); each is an attribute of the controller of the same name, a (runs, 3)
array holding this period's values after `compute`. A scene with a stockpile adds `RECLAIM`.
"""

from __future__ import annotations

from dataclasses import dataclass

# Unit of each signal kind per axis (travel, slew, luff) as the CSV's column names write it.
UNITS = {
    "q": ("m", "rad", "rad"),
    "qd": ("m/s", "rad/s", "rad/s"),
    "qdd": ("m/s2", "rad/s2", "rad/s2"),
    "force": ("N", "Nm", "Nm"),
    "1": ("1", "1", "1"),
}


@dataclass(frozen=True)
class Signal:
    """One recorded signal: `name` is its RunResult attribute (or controller attribute), `column`
    the stem of its timeseries.csv columns, `kind` its unit kind (UNITS) and `width` its values a
    period: 3 for one per axis."""

    name: str
    column: str
    kind: str
    description: str
    width: int = 3


LOOP = (
    Signal("q_desired", "q_desired", "q", "the reference position"),
    Signal("q", "q_actual", "q", "the true joint position at the period's start"),
    Signal("q_measured", "q_measured", "q", "what the encoders read"),
    Signal("qd_desired", "qd_desired", "qd", "the reference velocity"),
    Signal("qd", "qd_actual", "qd", "the true joint velocity at the period's start"),
    Signal("qd_measured", "qd_measured", "qd", "the velocity the controller was given"),
    Signal("qdd_desired", "qdd_desired", "qdd", "the reference acceleration"),
    Signal("qdd", "qdd_actual", "qdd", "the mean acceleration over the period"),
    Signal("drive_force_command", "drive_force_command", "force", "the controller's drive forces"),
    Signal("drive_force", "drive_force", "force", "what the actuators applied, within their ratings"),
    Signal("disturbance", "disturbance", "force", "the random disturbance plus the digging load, on the joints"),
)

FUZZY_OUTPUT = Signal("fuzzy_output", "fuzzy_output", "1", "the FLC output, in its output universe")
ACCELERATION_COMMAND = Signal("acceleration_command", "acceleration_command", "qdd",
                              "u, the acceleration the controller commands")

# Columns of a run with a stockpile (bwr_twin.stockpile.reclaim): name, CSV column, width.
RECLAIM = (
    ("rate", "reclaim_rate_t/h", 1),
    ("cut_depth", "cut_depth_m", 1),
    ("wheel_power", "wheel_power_W", 1),
    ("digging_force", "digging_force_{xyz}_N", 3),
    ("belt_scale", "belt_scale_t/h", 1),  # as the machine's instruments read them, NaN without instruments
    ("wheel_current", "wheel_current_A", 1),
)
# Signals of a second machine on the rail (bwr_twin.sim.neighbour): 'travel_neighbour_q_actual_m'.
NEIGHBOUR = (
    Signal("q_desired", "neighbour_q_desired", "q", "the neighbour's schedule"),
    Signal("q", "neighbour_q_actual", "q", "the neighbour's true joint position at the period's start"),
)
# Columns every run has beyond its signals: time, the CP desired and actual, the wind.
OTHER_COLUMNS = 1 + 6 + 1


def column_name(signal: Signal, axis: int, axes: tuple[str, ...] = ("travel", "slew", "luff")) -> str:
    """The timeseries.csv column of one axis of a signal: 'slew_qd_actual_rad/s'."""
    return f"{axes[axis]}_{signal.column}_{UNITS[signal.kind][axis]}"


def recorded_values(controller_signals: tuple[Signal, ...] = (), *, reclaim: bool = False,
                    neighbour: bool = False) -> int:
    """Float values a run records a row: the loop's and the controller's signals, the wind, a
    stockpile's columns and a neighbour's."""
    values = sum(s.width for s in LOOP + tuple(controller_signals)) + 1
    return (values + (sum(width for _, _, width in RECLAIM) if reclaim else 0)
            + (sum(s.width for s in NEIGHBOUR) if neighbour else 0))


def csv_columns(controller_signals: tuple[Signal, ...] = (), *, reclaim: bool = False, neighbour: bool = False) -> int:
    """Columns of a run's timeseries.csv."""
    return recorded_values(controller_signals, reclaim=reclaim, neighbour=neighbour) - 1 + OTHER_COLUMNS
