"""survey.png: the pile a run knew from its scans beside the true pile, and their difference
(docs/sensing.md): at the plan's start after a survey (nothing is dug before it), else at the end."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure

from bwr_twin.results.layout import fit_titles
from bwr_twin.sim.record import RunResult


def scan_figure(result: RunResult, subtitle: str) -> Figure:
    scan, pile = result.scan, result.reclaim
    known = scan.plan_start
    if known is not None:
        when, truth, scanned, seen = "at the plan's start", pile.z_start, known.z, known.seen
        tonnes, time = result.metrics["scan"]["plan_start"], known.time
    else:
        when, truth, scanned, seen = "at the end", pile.z_end, scan.z, scan.seen
        tonnes, time = result.metrics["scan"], scan.t_end
    extent = (pile.x[0], pile.x[-1], pile.y[0], pile.y[-1])
    fig = Figure(figsize=(12, 9), layout="constrained")
    true_ax, scanned_ax, difference_ax = fig.subplots(3, 1, sharex=True)
    top = float(np.nanmax(truth))
    heights = matplotlib.colormaps["viridis"].with_extremes(bad="0.85")  # grey: never seen
    for ax, z, title in ((true_ax, truth, "the true pile"), (scanned_ax, scanned, "the pile known from the scans "
                                                                                  "(grey: never seen)")):
        image = ax.imshow(z, origin="lower", extent=extent, cmap=heights, vmin=0.0, vmax=top, aspect="equal")
        ax.set_title(f"{title} [m above the yard floor]")
        fig.colorbar(image, ax=ax, label="height [m]")
    difference = np.where(seen > 0, scanned - truth, np.nan)
    bound = max(float(np.nanpercentile(np.abs(difference), 99)) if np.isfinite(difference).any() else 0.0, 0.01)
    image = difference_ax.imshow(difference, origin="lower", extent=extent, vmin=-bound, vmax=bound,
                                 cmap=matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.85"),
                                 aspect="equal")
    error = tonnes["error_share"]
    difference_ax.set_title(
        f"scanned - true [m] where seen: {tonnes['scanned_t']:,.0f} t against {tonnes['true_t']:,.0f} t "
        f"({'n/a' if error is None else f'{100 * error:+.2f} %'}), {100 * tonnes['footprint_seen_share']:.0f} % "
        "of the footprint seen")
    fig.colorbar(image, ax=difference_ax, label="height difference [m]")
    for ax in (true_ax, scanned_ax, difference_ax):
        ax.set_ylabel("Y, beside the rail [m]")
    difference_ax.set_xlabel("X, along the rail [m]")
    fig.suptitle(f"The pile known from the scans, {when} ({time:.1f} s)\n{subtitle}")
    fit_titles(fig)
    return fig
