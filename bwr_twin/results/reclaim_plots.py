"""The reclaim's figures for one run with a stockpile: the pile before and after as height maps,
and the reclaim rate, cut depth, wheel power and digging load over time."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bwr_twin.results.layout import DPI, fit_titles
from bwr_twin.sim.record import RunResult


def reclaim_figures(result: RunResult, subtitle: str) -> Iterator[tuple[str, Figure]]:
    """pile.png and reclaim.png, as (file name, figure)."""
    yield "pile.png", _pile_figure(result, subtitle)
    yield "reclaim.png", _rate_figure(result, subtitle)


def save_reclaim_figures(result: RunResult, out_dir: Path, subtitle: str) -> list[Path]:
    """Write pile.png and reclaim.png into out_dir; returns their paths."""
    paths = []
    for name, fig in reclaim_figures(result, subtitle):
        paths.append(Path(out_dir) / name)
        fig.savefig(paths[-1], dpi=DPI)
    return paths


def _pile_figure(result: RunResult, subtitle: str) -> Figure:
    pile = result.reclaim
    extent = (pile.x[0], pile.x[-1], pile.y[0], pile.y[-1])
    cut = pile.z_start - pile.z_end
    fig = Figure(figsize=(12, 9), layout="constrained")
    before, after, removed = fig.subplots(3, 1, sharex=True)
    top = float(pile.z_start.max())
    for ax, z, title in ((before, pile.z_start, "before"), (after, pile.z_end, "after")):
        image = ax.imshow(z, origin="lower", extent=extent, cmap="terrain", vmin=0.0, vmax=top, aspect="equal")
        ax.set_title(f"pile {title} [m above the yard floor]")
        fig.colorbar(image, ax=ax, label="height [m]")
    image = removed.imshow(np.where(cut > 0, cut, np.nan), origin="lower", extent=extent, cmap="magma_r", aspect="equal")
    removed.set_title(f"cut [m]: {result.metrics['reclaim']['pile_volume_lost_m3']:.1f} m³ dug")
    fig.colorbar(image, ax=removed, label="depth removed [m]")
    cp = result.cp
    for ax in (before, after, removed):
        ax.plot(cp[:, 0], cp[:, 1], "C0-", lw=0.8, label="bucket wheel centre")
        ax.set_ylabel("Y, beside the rail [m]")
    before.legend(loc="upper right")
    removed.set_xlabel("X, along the rail [m]")
    fig.suptitle(f"The stockpile, dug\n{subtitle}")
    fit_titles(fig)
    return fig


def _rate_figure(result: RunResult, subtitle: str) -> Figure:
    r, m = result.reclaim, result.metrics["reclaim"]
    fig = Figure(figsize=(10, 9), layout="constrained")
    rate, depth, power, force = fig.subplots(4, 1, sharex=True)
    rate.plot(result.time, r.rate, "C0-", lw=0.8, label="reclaim rate")
    if np.isfinite(r.belt_scale).any():  # the machine's belt scale, late and noisy
        rate.plot(result.time, r.belt_scale, "C4-", lw=0.6, alpha=0.8, label="belt scale")
    rate.axhline(m["wheel_capacity_tph"], color="C3", ls="--", lw=1.0, label="bucket capacity")
    title = (f"{m['mass_t']:.0f} t reclaimed, {m['spill_t']:.1f} t spilled; "
             f"mean {m['rate_mean_tph']:.0f} t/h while carrying, "
             f"reclaim rate CV while carrying (std/mean) {m['rate_cv']:.2f}")
    if "target_rate_tph" in m:  # a bench plan's target, and how steady cutting held it
        rate.axhline(m["target_rate_tph"], color="k", ls=":", lw=1.0, label="target")
        if m["steady_time_s"] > 0:
            cv = m["steady_rate_cv"]  # None if the steady rate's mean is zero
            title += (f"\nsteady cutting: {m['steady_rate_mean_tph']:.0f} t/h, "
                      f"steady reclaim rate CV (std/mean) {'n/a' if cv is None else f'{cv:.3f}'}, "
                      f"{100 * m['steady_within_10pct']:.0f} % within ±10 % of the target")
    rate.set_ylabel("rate [t/h]")
    rate.set_title(title)
    rate.legend(loc="upper right")
    # A line alone in its panel is named by the panel's label.
    depth.plot(result.time, r.cut_depth, "C1-", lw=0.8, label="cut depth")
    depth.set_ylabel("cut depth [m]")
    power.plot(result.time, r.wheel_power / 1e3, "C2-", lw=0.8, label="wheel power")
    power.set_ylabel("wheel power [kW]")
    if np.isfinite(r.wheel_current).any():  # the wheel motor's current, as its drive measures it
        current = power.twinx()
        current.plot(result.time, r.wheel_current, "C5-", lw=0.5, alpha=0.6, label="wheel current")
        current.set_ylabel("wheel current [A]")
        power.legend(handles=power.get_lines() + current.get_lines(), loc="upper right")
    for label, component, style in (("X", 0, "C0-"), ("Y", 1, "C1-"), ("Z", 2, "C2-")):
        force.plot(result.time, r.digging_force[:, component] / 1e3, style, lw=0.8, label=label)
    force.set_ylabel("digging load [kN]")
    force.legend(loc="upper right")
    force.set_xlabel("time [s]")
    for ax in (rate, depth, power, force):
        ax.grid(alpha=0.3)
    fig.suptitle(f"Reclaim rate, cut depth, wheel power and digging load on the wheel (world frame)\n{subtitle}")
    fit_titles(fig)
    return fig
