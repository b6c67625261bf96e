"""Charts of the runs a replay shows: position and velocity error, the reclaim rate (with a
stockpile), the grade stacked or reclaimed (on a pile with grade) and the joint trajectories, as uPlot charts for the live page (and drawn again by
bwr_twin.replay.export_charts for the HTML export).

One run's charts hold its three axes in their colours (travel on the left scale, slew and luff in
degrees on the right). Several runs get a chart per quantity and axis, each run's line in its
colour, the y-range fitted to the runs shown. The cursor at the current time and click-to-seek are
the page's (bwr_twin.replay.page_script): the data is sent once, and again only when the runs
shown change. Charts are sampled about once a second of the run.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bwr_twin.model.machine import AXES
from bwr_twin.replay.recording import Recording, decimate
from bwr_twin.replay.style import DESIRED_COLOUR, hex_colour, run_colour

CHART_STEP = 1.0  # s between chart points: 701 for the paper's reclaim
AXIS_COLOURS = ("#1f77b4", "#d62728", "#2ca02c")  # travel, slew, luff
RANGE_PAD = 0.05  # of the shown lines' span, above and below them
DEGREES = np.degrees(1.0)
DISPLAY = (1.0, DEGREES, DEGREES)  # m and degrees
UNITS = ("m", "deg", "deg")
DESIRED_DASH = (6.0, 4.0)


@dataclass(frozen=True)
class Line:
    """One line of a chart: its uPlot series, its values at the chart's times, and the run it
    belongs to (None: every run's, as a desired path is)."""

    series: dict
    values: np.ndarray
    run: int | None = None


@dataclass(frozen=True)
class Chart:
    """A chart's title, lines and axes; `fitted` charts get y-ranges from the lines shown."""

    title: str
    time: np.ndarray
    lines: tuple[Line, ...]
    scales: dict
    axes: tuple[dict, ...]
    fitted: bool = False

    def shown(self, runs: Sequence[bool]) -> list[Line]:
        """The lines of the runs shown (runs[k] for run k) and the lines of all runs."""
        return [line for line in self.lines if line.run is None or runs[line.run]]

    def data(self, runs: Sequence[bool]) -> tuple[np.ndarray, ...]:
        """x and the shown lines' values, for uPlot."""
        return (self.time, *(line.values for line in self.shown(runs)))

    def series(self, runs: Sequence[bool]) -> tuple[dict, ...]:
        return ({"label": "t [s]"}, *(line.series for line in self.shown(runs)))

    def ranges(self, runs: Sequence[bool]) -> dict:
        """The scales, each fitted to the shown lines on it when the chart is `fitted`."""
        if not self.fitted:
            return self.scales
        scales = dict(self.scales)
        for name in self.scales:
            values = [line.values for line in self.shown(runs) if line.series.get("scale") == name]
            if values:
                scales[name] = {"auto": False, "range": y_range(np.concatenate(values))}
        return scales


def y_range(values: np.ndarray) -> tuple[float, float]:
    """The values' span with RANGE_PAD above and below; a flat line gets a span of its own."""
    low, high = float(values.min()), float(values.max())
    pad = RANGE_PAD * (high - low) or RANGE_PAD * max(abs(high), 1e-9)
    return low - pad, high + pad


def _line(label: str, colour: str, scale: str, *, dash: tuple[float, ...] | None = None) -> dict:
    series = {"label": label, "stroke": colour, "scale": scale, "width": 1.5}
    if dash:
        series["dash"] = dash
    return series


def charts(recordings: Recording | Sequence[Recording], names: Sequence[str] = ()) -> list[Chart]:
    """One run's charts (its axes together), or several runs' (a chart per quantity and axis)."""
    if isinstance(recordings, Recording) or len(recordings) == 1:
        return _one_run(recordings if isinstance(recordings, Recording) else recordings[0])
    return _several_runs(list(recordings), list(names) or [f"run {k + 1}" for k in range(len(recordings))])


def _two_scales(title: str, time: np.ndarray, lines: list[Line], left: str, right: str) -> Chart:
    return Chart(
        title=title,
        time=time,
        lines=tuple(lines),
        scales={"x": {"time": False}, "m": {"auto": True}, "deg": {"auto": True}},
        axes=(
            {"label": "t [s]"},
            {"scale": "m", "label": left},
            {"scale": "deg", "label": right, "side": 1, "grid": {"show": False}},
        ),
    )


def _one_run(recording: Recording) -> list[Chart]:
    """Position and velocity error per axis (the paper's Figs. 10 and 13) and the joint trajectories."""
    samples = decimate(recording.plan.time, CHART_STEP)
    time = recording.plan.time[samples]

    def error_chart(title: str, error: np.ndarray, per: str) -> Chart:
        error = error[samples] * DISPLAY
        lines = [Line(_line(f"{axis} [{UNITS[j]}{per}]", AXIS_COLOURS[j], UNITS[j]), error[:, j])
                 for j, axis in enumerate(AXES)]
        return _two_scales(title, time, lines, left=f"travel [m{per}]", right=f"slew, luff [deg{per}]")

    desired = recording.plan.q_desired[samples] * DISPLAY
    actual = recording.q_actual[samples] * DISPLAY
    trajectory = []
    for j, axis in enumerate(AXES):
        trajectory += [
            Line(_line(f"{axis} desired [{UNITS[j]}]", AXIS_COLOURS[j], UNITS[j], dash=DESIRED_DASH), desired[:, j]),
            Line(_line(f"{axis} actual [{UNITS[j]}]", AXIS_COLOURS[j], UNITS[j]), actual[:, j]),
        ]
    out = [
        error_chart("Position error (desired - actual)", recording.q_error, ""),
        error_chart("Velocity error (desired - actual)", recording.qd_error, "/s"),
    ]
    if recording.reclaim_rate is not None:
        rate = Line(_line("rate [t/h]", AXIS_COLOURS[0], "m"), recording.reclaim_rate[samples])
        out.append(_two_scales("Reclaim rate", time, [rate], left="rate [t/h]", right=""))
    if recording.grade is not None:
        out += _grade_chart([recording], ["grade"], recording.plan.time[samples])
    return out + [_two_scales("Joint trajectories", time, trajectory, left="travel [m]", right="slew, luff [deg]")]


def _grade_chart(recordings: Sequence[Recording], names: Sequence[str], time: np.ndarray) -> list[Chart]:
    """The grade each run stacked or reclaimed, over the times all of them have one (a reclaim's
    from the first discharge past the belt scale: uPlot draws no gaps from NaN); none without."""
    graded = [(k, r) for k, r in enumerate(recordings) if r.grade is not None]
    if not graded:
        return []
    series = [(k, np.interp(time, r.plan.time, r.grade.values)) for k, r in graded]  # NaN where either side is
    known = np.all([np.isfinite(values) for _, values in series], axis=0)
    if known.sum() < 2:
        return []
    first = graded[0][1].grade
    unit = first.name
    colours = [AXIS_COLOURS[0]] if len(recordings) == 1 else [hex_colour(run_colour(k)) for k, _ in graded]
    lines = [Line(_line(f"{names[k]} [{unit}]", colour, "y"), values[known], run=None if len(recordings) == 1 else k)
             for (k, values), colour in zip(series, colours)]
    title = "Grade stacked, as it arrived" if first.kind == "stacked" else "Grade reclaimed, at the belt scale"
    return [Chart(title=title, time=time[known], lines=tuple(lines), scales={"x": {"time": False}, "y": {"auto": True}},
                  axes=({"label": "t [s]"}, {"scale": "y", "label": unit}), fitted=True)]


def chart_time(recordings: Sequence[Recording]) -> np.ndarray:
    """The times several runs are charted at: the first's samples if all share its record times,
    else evenly over all of them."""
    first = recordings[0].plan.time
    if all(np.array_equal(r.plan.time, first) for r in recordings):
        return first[decimate(first, CHART_STEP)]
    start = min(float(r.plan.time[0]) for r in recordings)
    end = max(float(r.plan.time[-1]) for r in recordings)
    return np.linspace(start, end, max(2, round((end - start) / CHART_STEP) + 1))


def _several_runs(recordings: list[Recording], names: list[str]) -> list[Chart]:
    """Per quantity and axis, each run's line in its colour (a run that ended holds its last value)."""
    time = chart_time(recordings)

    def at(recording: Recording, series: np.ndarray) -> np.ndarray:
        return np.interp(time, recording.plan.time, series)

    def fitted(title: str, unit: str, lines: list[Line]) -> Chart:
        return Chart(title=title, time=time, lines=tuple(lines), scales={"x": {"time": False}, "y": {"auto": True}},
                     axes=({"label": "t [s]"}, {"scale": "y", "label": unit}), fitted=True)

    def per_run(series: Sequence[np.ndarray], unit: str) -> list[Line]:
        return [Line(_line(f"{names[k]} [{unit}]", hex_colour(run_colour(k)), "y"), values, run=k)
                for k, values in enumerate(series)]

    out = []
    for quantity, per, error in (("Position error", "", "q_error"), ("Velocity error", "/s", "qd_error")):
        for j, axis in enumerate(AXES):
            unit = f"{UNITS[j]}{per}"
            values = [at(r, getattr(r, error)[:, j] * DISPLAY[j]) for r in recordings]
            out.append(fitted(f"{quantity}, {axis} (desired - actual)", f"{axis} [{unit}]", per_run(values, unit)))
    rates = [(k, r) for k, r in enumerate(recordings) if r.reclaim_rate is not None]
    if rates:
        lines = [Line(_line(f"{names[k]} [t/h]", hex_colour(run_colour(k)), "y"), at(r, r.reclaim_rate), run=k)
                 for k, r in rates]
        out.append(fitted("Reclaim rate", "rate [t/h]", lines))
    out += _grade_chart(recordings, names, time)
    for j, axis in enumerate(AXES):
        desired = Line(_line(f"desired [{UNITS[j]}]", hex_colour(DESIRED_COLOUR), "y", dash=DESIRED_DASH),
                       at(recordings[0], recordings[0].plan.q_desired[:, j] * DISPLAY[j]))
        actual = per_run([at(r, r.q_actual[:, j] * DISPLAY[j]) for r in recordings], UNITS[j])
        out.append(fitted(f"Joint trajectory, {axis}", f"{axis} [{UNITS[j]}]", [desired, *actual]))
    return out
