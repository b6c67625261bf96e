"""The paper's figures for one run (Fig. 6-10 and 12-13), plus drive forces and the CP path.

Joint values are shown in engineering units: travel in m, slew and luff in degrees.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure  # no pyplot: no global state, no display backend

from bwr_twin.model.machine import AXES, UNITS, world_to_paper
from bwr_twin.sim.record import RunResult

_DEG = (1.0, 180 / np.pi, 180 / np.pi)


def _per_axis(result: RunResult, title: str, series, unit_suffix: str, path: Path) -> None:
    """One row per axis; `series` is [(label, array (n, 3), style), ...]."""
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        for label, values, style in series:
            ax.plot(result.time, values[:, j] * _DEG[j], style, label=label, lw=1.0)
        ax.set_ylabel(f"{AXES[j]} [{UNITS[j]}{unit_suffix}]")
        ax.grid(alpha=0.3)
        for t in result.trajectory.times:
            ax.axvline(t, color="0.8", lw=0.8, zorder=0)
    axes[0].legend(loc="upper right")  # "best" scans every point: seconds per figure
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fig.savefig(path, dpi=110)


def save_run_figures(result: RunResult, out_dir: Path) -> list[Path]:
    """Write the figures of one run into out_dir; returns their paths."""
    out_dir = Path(out_dir)
    name = result.scene.path.stem
    subtitle = f"{name}, {result.scene.controller.label()}, seed {result.scene.simulation.seed}"
    paths = []

    def save(filename, title, series, unit_suffix=""):
        path = out_dir / filename
        _per_axis(result, f"{title}\n{subtitle}", series, unit_suffix, path)
        paths.append(path)

    save("positions.png", "Joint positions, desired vs actual (paper Fig. 6, 12)",
         [("desired", result.q_desired, "k--"), ("actual", result.q, "C0-")])
    save("velocities.png", "Joint velocities, desired vs actual (paper Fig. 7, 12)",
         [("desired", result.qd_desired, "k--"), ("actual", result.qd, "C0-")], "/s")
    save("accelerations.png", "Joint accelerations, desired vs actual (paper Fig. 8, 12)",
         [("actual (mean over a control period)", result.qdd, "C0-"), ("desired", result.qdd_desired, "k--")], "/s²")
    save("errors_position.png", "Position error, desired - actual (paper Fig. 10, 13 left)",
         [("error", result.q_desired - result.q, "C3-")])
    save("errors_velocity.png", "Velocity error, desired - actual (paper Fig. 10, 13 middle)",
         [("error", result.qd_desired - result.qd, "C3-")], "/s")
    save("errors_acceleration.png", "Acceleration error, desired - actual (paper Fig. 10, 13 right)",
         [("error", result.qdd_desired - result.qdd, "C3-")], "/s²")

    if result.reclaim is not None:
        from bwr_twin.results.reclaim_plots import save_reclaim_figures

        paths += save_reclaim_figures(result, out_dir, subtitle)
    fuzzy_output = result.controller_signals.get("fuzzy_output")
    if fuzzy_output is None:  # a controller without fuzzy logic
        return paths + [_drive_force_figure(result, subtitle, out_dir), _cp_figure(result, subtitle, out_dir)]
    # Fig. 9: the FLC output itself (dimensionless) and the acceleration command it makes.
    fig = Figure(figsize=(10, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for j, ax in enumerate(axes):
        ax.plot(result.time, fuzzy_output[:, j], "C1-", lw=0.6, label="FLC output")
        ax.set_ylabel(f"{AXES[j]} FLC [-]")
        ax.set_ylim(-4.8, 4.8)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Fuzzy logic output signals (paper Fig. 9)\n{subtitle}")
    paths.append(out_dir / "fuzzy_outputs.png")
    fig.savefig(paths[-1], dpi=110)

    return paths + [_drive_force_figure(result, subtitle, out_dir), _cp_figure(result, subtitle, out_dir)]


def _drive_force_figure(result: RunResult, subtitle: str, out_dir: Path) -> Path:
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
    handles, labels = axes[0].get_legend_handles_labels()
    axes[0].legend(dict(zip(labels, handles)).values(), dict(zip(labels, handles)).keys(), loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(f"Drive forces and torques against their limits\n{subtitle}")
    fig.savefig(out_dir / "drive_forces.png", dpi=110)
    return out_dir / "drive_forces.png"


def _cp_figure(result: RunResult, subtitle: str, out_dir: Path) -> Path:
    """The CP path in the paper's frame 0: plan view and elevation."""
    desired, actual = world_to_paper(result.cp_desired), world_to_paper(result.cp)
    via = world_to_paper(result.trajectory.points)
    fig = Figure(figsize=(12, 5), layout="constrained")
    (top, side) = fig.subplots(1, 2)
    for ax, (a, b), labels in (
        (top, (2, 0), ("z_p, along the rail [m]", "x_p, lateral [m]")),
        (side, (2, 1), ("z_p, along the rail [m]", "y_p, down [m]")),
    ):
        ax.plot(desired[:, a], desired[:, b], "k--", lw=1, label="desired")
        ax.plot(actual[:, a], actual[:, b], "C0-", lw=1, label="actual")
        ax.plot(via[:, a], via[:, b], "rs", label="via points")
        for i, p in enumerate(via):
            ax.annotate(f" {i + 1}", (p[a], p[b]))
        ax.set_xlabel(labels[0])
        ax.set_ylabel(labels[1])
        ax.grid(alpha=0.3)
        ax.set_aspect("equal", adjustable="datalim")
    side.invert_yaxis()
    top.legend(loc="best")
    fig.suptitle(f"Bucket wheel centre path in the paper's frame 0\n{subtitle}")
    fig.savefig(out_dir / "cp_path.png", dpi=110)
    return out_dir / "cp_path.png"
