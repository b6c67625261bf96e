"""The paper's figures for one run (Fig. 6-10 and 12-13), plus drive forces and the CP path.

Joint values are shown in engineering units: travel in m, slew and luff in degrees. Only a run of
the paper's machine (`is_papers_machine`) cites the paper's figure numbers and its frame 0; the
same figures of any other machine say what they plot and nothing more.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure  # no pyplot: no global state, no display backend
from matplotlib.text import Text

from bwr_twin.model.machine import AXES, UNITS, Machine, world_to_paper
from bwr_twin.results.layout import DPI, fit_titles
from bwr_twin.results.reclaim_plots import reclaim_figures
from bwr_twin.results.scan_plots import scan_figure
from bwr_twin.results.stacking_plots import blend_figure, stacking_figure
from bwr_twin.shipped import MJCF
from bwr_twin.sim.record import RunResult

_DEG = (1.0, 180 / np.pi, 180 / np.pi)
PAPER_MJCF = MJCF / "bwr.xml"
COINCIDE_PX = 4.0  # via points closer than this on the figure share one label ("1, 5")


def is_papers_machine(machine: Machine) -> bool:
    """Whether the run's plant is the paper's machine: the shipped mjcf/bwr.xml, byte for byte (a
    copy elsewhere counts, an edited copy does not), carrying no payload the file does not hold."""
    path = Path(machine.path)
    try:
        same = path.samefile(PAPER_MJCF) or path.read_bytes() == PAPER_MJCF.read_bytes()
    except OSError:
        same = False
    return same and not machine.payloads


def legend(axes: Sequence[Axes], **kwargs) -> None:
    """One legend, on the first of `axes`, for the lines of them all, one entry per label: a line
    drawn on every row (the via points' times) is named once, and one drawn only on a lower row
    (a drive limit) is named too."""
    unique = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            unique.setdefault(label, handle)
    axes[0].legend(list(unique.values()), list(unique.keys()), **kwargs)


def run_figures(result: RunResult) -> Iterator[tuple[str, Figure]]:
    """The figures of one run, as (file name, figure), in the order save_run_figures writes them."""
    paper = is_papers_machine(result.machine)
    scene = result.scene
    subtitle = f"{scene.path.stem}, {scene.controller.label()}, seed {scene.simulation.seed}"

    def titled(title: str, figures: str) -> str:
        return f"{title} (paper Fig. {figures})\n{subtitle}" if paper else f"{title}\n{subtitle}"

    r = result
    per_axis = (  # file, title, the paper's figures, unit suffix, [(label, (n, 3) values, style), ...]
        ("positions.png", "Joint positions, desired vs actual", "6, 12", "",
         [("desired", r.q_desired, "k--"), ("actual", r.q, "C0-")]),
        ("velocities.png", "Joint velocities, desired vs actual", "7, 12", "/s",
         [("desired", r.qd_desired, "k--"), ("actual", r.qd, "C0-")]),
        ("accelerations.png", "Joint accelerations, desired vs actual", "8, 12", "/s²",
         [("actual (mean over a control period)", r.qdd, "C0-"), ("desired", r.qdd_desired, "k--")]),
        ("errors_position.png", "Position error, desired - actual", "10, 13 left", "",
         [("error", r.q_desired - r.q, "C3-")]),
        ("errors_velocity.png", "Velocity error, desired - actual", "10, 13 middle", "/s",
         [("error", r.qd_desired - r.qd, "C3-")]),
        ("errors_acceleration.png", "Acceleration error, desired - actual", "10, 13 right", "/s²",
         [("error", r.qdd_desired - r.qdd, "C3-")]),
    )
    for name, title, figures, suffix, series in per_axis:
        yield name, _per_axis(result, titled(title, figures), series, suffix)
    if result.reclaim is not None:
        yield from reclaim_figures(result, subtitle)
    if result.scan is not None and result.reclaim is not None:
        yield "survey.png", scan_figure(result, subtitle)
    if result.stacking is not None:
        yield "stacking.png", stacking_figure(result, subtitle)
    if result.reclaim is not None and result.reclaim.grade_out is not None:
        yield "blend.png", blend_figure(result, subtitle)
    fuzzy_output = result.controller_signals.get("fuzzy_output")
    if fuzzy_output is not None:  # a controller with fuzzy logic
        fuzzy_title = titled("Fuzzy logic output signals", "9")
        yield "fuzzy_outputs.png", _fuzzy_figure(result, fuzzy_output, fuzzy_title)
    forces = f"Drive forces and torques against their limits\n{subtitle}"
    yield "drive_forces.png", _drive_force_figure(result, forces)
    yield "cp_path.png", _cp_figure(result, subtitle, paper)


def save_run_figures(result: RunResult, out_dir: Path) -> list[Path]:
    """Write the figures of one run into out_dir; returns their paths."""
    paths = []
    for name, fig in run_figures(result):
        paths.append(Path(out_dir) / name)
        fig.savefig(paths[-1], dpi=DPI)
    return paths


def _via_times(ax: Axes, result: RunResult) -> None:
    for t in result.trajectory.times:
        ax.axvline(t, color="0.8", lw=0.8, zorder=0, label="via point times")


def _per_axis(result: RunResult, title: str, series, unit_suffix: str) -> Figure:
    """One row per axis; `series` is [(label, array (n, 3), style), ...]."""
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        for label, values, style in series:
            ax.plot(result.time, values[:, j] * _DEG[j], style, label=label, lw=1.0)
        ax.set_ylabel(f"{AXES[j]} [{UNITS[j]}{unit_suffix}]")
        ax.grid(alpha=0.3)
        _via_times(ax, result)
    legend(axes, loc="upper right")  # "best" scans every point: seconds per figure
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fit_titles(fig)
    return fig


def _fuzzy_figure(result: RunResult, fuzzy_output: np.ndarray, title: str) -> Figure:
    """Fig. 9: the FLC output itself (dimensionless)."""
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(result.time, fuzzy_output[:, j], "C1-", lw=0.6, label="FLC output")
        ax.set_ylabel(f"{AXES[j]} FLC [-]")
        ax.set_ylim(-4.8, 4.8)
        ax.grid(alpha=0.3)
    legend(axes, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fit_titles(fig)
    return fig


def _drive_force_figure(result: RunResult, title: str) -> Figure:
    """Drive forces and torques, commanded and applied, against their limits."""
    limits = result.machine.drive_limits
    force_units = ("kN", "kN m", "kN m")
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(result.time, result.drive_force_command[:, j] / 1e3, "C7-", lw=0.6, label="commanded")
        ax.plot(result.time, result.drive_force[:, j] / 1e3, "C0-", lw=0.8, label="applied")
        for limit in limits[j]:
            if np.isfinite(limit):
                ax.axhline(limit / 1e3, color="C3", ls="--", lw=1.0, label="drive limit")
        ax.set_ylabel(f"{AXES[j]} [{force_units[j]}]")
        ax.grid(alpha=0.3)
    legend(axes, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fit_titles(fig)
    return fig


def _cp_figure(result: RunResult, subtitle: str, paper: bool) -> Figure:
    """The CP path in frame 0 (the world's axes renamed: x = -Y lateral, y = -Z down, z = X along
    the rail): plan view and elevation. Only the paper's machine calls it the paper's frame."""
    desired, actual = world_to_paper(result.cp_desired), world_to_paper(result.cp)
    via = world_to_paper(result.trajectory.points)
    if paper:
        title, suffix = "Bucket wheel centre path in the paper's frame 0", "_p"
    else:
        title, suffix = "Bucket wheel centre path in the rail frame: x lateral, y down, z along the rail", ""
    fig = Figure(figsize=(12, 5), layout="constrained")
    (top, side) = fig.subplots(1, 2)
    views = ((top, (2, 0), (f"z{suffix}, along the rail [m]", f"x{suffix}, lateral [m]")),
             (side, (2, 1), (f"z{suffix}, along the rail [m]", f"y{suffix}, down [m]")))
    for ax, (a, b), labels in views:
        ax.plot(desired[:, a], desired[:, b], "k--", lw=1, label="desired")
        ax.plot(actual[:, a], actual[:, b], "C0-", lw=1, label="actual")
        ax.plot(via[:, a], via[:, b], "rs", label="via points")
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        ax.grid(alpha=0.3)
        ax.set_aspect("equal", adjustable="datalim")
    side.invert_yaxis()
    legend((top, side), loc="best")
    fig.suptitle(f"{title}\n{subtitle}")
    fit_titles(fig)
    fig.draw_without_rendering()  # the final layout: where the via points land on the figure
    for ax, (a, b), _ in views:
        number_points(ax, via[:, [a, b]])
    return fig


def number_points(ax: Axes, points: np.ndarray) -> list[Text]:
    """Number `points` (k, 2), data coordinates, 1..k beside their marks, where the numbers are
    readable: points that coincide on the figure share one label ("1, 5"), and a label that would
    overlap one placed before it is left out. Needs the figure's final layout (drawn once, its
    titles fitted); the labels take no part in it. Returns the labels placed."""
    pixels = ax.transData.transform(points)
    groups: list[list[int]] = []
    for i, p in enumerate(pixels):
        near = [g for g in groups if np.linalg.norm(pixels[g[0]] - p) < COINCIDE_PX]
        if near:
            near[0].append(i)
        else:
            groups.append([i])
    placed, boxes = [], []
    for group in groups:
        label = ax.annotate(", ".join(str(i + 1) for i in group), points[group[0]], xytext=(3, 3),
                            textcoords="offset points", fontsize=9)
        label.set_in_layout(False)
        box = label.get_window_extent()
        if any(box.overlaps(other) for other in boxes):
            label.remove()
        else:
            placed.append(label)
            boxes.append(box)
    return placed
