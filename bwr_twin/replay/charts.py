"""uPlot charts of a recording: position and velocity error per axis, the reclaim rate (with a
stockpile) and the joint trajectories, with a vertical line at the current time.

uPlot has no marker API reachable from viser, and viser sends data as float arrays (no nulls,
so no gaps), so the line is a series of its own on a fixed 0-1 scale: it lies below the plot
at -1, except for three samples inserted at the current time that go up to 2 and back. The
other series get their interpolated values at those samples. Moving the line means re-sending
the chart's data, so the charts are decimated to about 700 points per series.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.model.machine import AXES
from bwr_twin.replay.recording import Recording, decimate

CHART_STEP = 1.0  # s between chart points: 701 for the paper's reclaim
AXIS_COLOURS = ("#1f77b4", "#d62728", "#2ca02c")  # travel, slew, luff
NOW_COLOUR = "#555555"
MARKER_HIDDEN, MARKER_TOP = -1.0, 2.0  # on the marker's 0-1 scale: below and above the plot
DEGREES = np.degrees(1.0)


@dataclass
class Chart:
    """A chart's configuration and its data without the time marker."""

    title: str
    series: tuple[dict, ...]  # uPlot series, the first for x
    scales: dict
    axes: tuple[dict, ...]
    time: np.ndarray
    values: tuple[np.ndarray, ...]  # one per series after x, excluding the marker

    def data(self, t: float) -> tuple[np.ndarray, ...]:
        """x and every series, with the marker at time t (s) as the last series."""
        i = int(np.searchsorted(self.time, t))
        x = np.insert(self.time, i, [t, t, t])
        marker = np.full(len(x), MARKER_HIDDEN)
        marker[i + 1] = MARKER_TOP
        return (x, *(np.insert(v, i, [np.interp(t, self.time, v)] * 3) for v in self.values), marker)


def _line(label: str, colour: str, scale: str, *, dash: tuple[float, ...] | None = None) -> dict:
    series = {"label": label, "stroke": colour, "scale": scale, "width": 1.5}
    if dash:
        series["dash"] = dash
    return series


def _frame(
    title: str, lines: list[dict], time: np.ndarray, values: list[np.ndarray], left: str, right: str
) -> Chart:
    return Chart(
        title=title,
        series=(
            {"label": "t [s]"},
            *lines,
            {"label": "now", "stroke": NOW_COLOUR, "scale": "now", "width": 1.5},
        ),
        scales={
            "x": {"time": False},
            "m": {"auto": True},
            "deg": {"auto": True},
            "now": {"auto": False, "range": (0.0, 1.0)},
        },
        axes=(
            {"label": "t [s]"},
            {"scale": "m", "label": left},
            {"scale": "deg", "label": right, "side": 1, "grid": {"show": False}},
            {"scale": "now", "show": False},
        ),
        time=time,
        values=tuple(values),
    )


def charts(recording: Recording) -> list[Chart]:
    """Position and velocity error per axis (the paper's Figs. 10 and 13) and the joint trajectories."""
    samples = decimate(recording.plan.time, CHART_STEP)
    time = recording.plan.time[samples]
    display = (1.0, DEGREES, DEGREES)  # m and degrees
    scale = ("m", "deg", "deg")

    def error_chart(title: str, error: np.ndarray, per: str) -> Chart:
        error = error[samples] * display
        return _frame(
            title,
            [_line(f"{axis} [{scale[j]}{per}]", AXIS_COLOURS[j], scale[j]) for j, axis in enumerate(AXES)],
            time,
            [error[:, j] for j in range(3)],
            left=f"travel [m{per}]",
            right=f"slew, luff [deg{per}]",
        )

    desired = recording.plan.q_desired[samples] * display
    actual = recording.q_actual[samples] * display
    trajectory_lines, trajectory_values = [], []
    for j, axis in enumerate(AXES):
        trajectory_lines += [
            _line(f"{axis} desired [{scale[j]}]", AXIS_COLOURS[j], scale[j], dash=(6.0, 4.0)),
            _line(f"{axis} actual [{scale[j]}]", AXIS_COLOURS[j], scale[j]),
        ]
        trajectory_values += [desired[:, j], actual[:, j]]
    trajectory_chart = _frame(
        "Joint trajectories",
        trajectory_lines,
        time,
        trajectory_values,
        left="travel [m]",
        right="slew, luff [deg]",
    )
    out = [
        error_chart("Position error (desired - actual)", recording.q_error, ""),
        error_chart("Velocity error (desired - actual)", recording.qd_error, "/s"),
    ]
    if recording.reclaim_rate is not None:
        rate = recording.reclaim_rate[samples]
        out.append(_frame("Reclaim rate", [_line("rate [t/h]", AXIS_COLOURS[0], "m")], time, [rate],
                          left="rate [t/h]", right=""))
    return out + [trajectory_chart]
