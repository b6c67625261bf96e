"""stacking.png: the pile a run stacked and the grade through it (docs/blending.md): its heights
from above, its layers cut across and along the axis, coloured by grade, and the grade that came
in against time. blend.png: the grade a reclaim took from a stacked pile."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from bwr_twin.results.layout import fit_titles
from bwr_twin.results.summary import law_text, pattern_text
from bwr_twin.sim.record import RunResult

SECTION_STEP = 0.05  # m between the heights a section is drawn at


def stacking_figure(result: RunResult, subtitle: str) -> Figure:
    record, metrics, section = result.stacking, result.metrics["stacking"], result.scene.stacking
    name = record.grade_name
    mean, sd = metrics["grade_in_mean"], max(metrics["grade_in_sd"], 1e-9)
    grades = matplotlib.colormaps["viridis"].with_extremes(bad="white")
    limits = {"vmin": mean - 2.5 * sd, "vmax": mean + 2.5 * sd, "cmap": grades}
    fig = Figure(figsize=(12, 12), layout="constrained")
    plan_ax, across_ax, along_ax, stream_ax = fig.subplots(4, 1, height_ratios=[1.2, 1, 1, 1])

    extent = (record.x[0], record.x[-1], record.y[0], record.y[-1])
    image = plan_ax.imshow(record.z, origin="lower", extent=extent, cmap="cividis", aspect="equal")
    plan_ax.axhline(section.axis_y, color="w", lw=0.8, ls="--")
    middle = 0.5 * (section.axis_x[0] + section.axis_x[1])
    plan_ax.axvline(middle, color="w", lw=0.8, ls=":")
    plan_ax.set_title(f"the pile from above [m above the yard floor]: {metrics['pile_t']:,.0f} t, crest "
                      f"{metrics['crest_height_m']:.2f} m (target {metrics['target_height_m']:.2f} m); dashed: "
                      "the axis, dotted: the section across")
    plan_ax.set_xlabel("X, along the rail [m]")
    plan_ax.set_ylabel("Y [m]")
    fig.colorbar(image, ax=plan_ax, label="height [m]")

    ix = int(np.argmin(np.abs(record.x - middle)))
    iy = int(np.argmin(np.abs(record.y - section.axis_y)))
    top = float(record.z.max())
    for ax, columns, lines, label in (
            (across_ax, np.s_[:, ix], record.y, f"across the pile at X = {record.x[ix]:.1f} m"),
            (along_ax, np.s_[iy, :], record.x, f"along its axis at Y = {record.y[iy]:.1f} m")):
        mesh = _section(ax, record.thickness[columns], record.layer_grade[columns], record.count[columns], lines,
                        top, limits)
        ax.set_title(f"its layers {label}, coloured by the grade each was laid at")
        ax.set_ylabel("height [m]")
        ax.set_xlabel(("Y" if ax is across_ax else "X") + " [m]")
        fig.colorbar(mesh, ax=ax, label=name)

    stream_ax.step(record.t, record.grade, where="post", lw=0.6, color="C0", label="grade in, each deposit")
    if section.grade.band is not None:
        low, high = section.grade.band
        stream_ax.axhspan(low, high, color="C2", alpha=0.12, label=f"band {low:g}-{high:g} {name}")
    stream_ax.set_title(f"the grade that came in: mean {mean:.3f}, sd {metrics['grade_in_sd']:.3f} {name}; the "
                        f"pile holds {metrics['pile_grade_mean']:.3f} {name}")
    stream_ax.set_xlabel("time [s]")
    stream_ax.set_ylabel(name)
    stream_ax.grid(alpha=0.3)
    stream_ax.legend(loc="upper right")
    fig.suptitle(f"The stacked pile: {section.pattern}, {section.layers} layers at {section.rate:,.0f} t/h\n{subtitle}")
    fit_titles(fig)
    return fig


def _section(ax: Axes, thickness: np.ndarray, grade: np.ndarray, count: np.ndarray, lines: np.ndarray,
             top: float, limits: dict):
    """Draw the columns' layers (columns, max_layers), each column a grid cell wide, as an image
    of the grade at every SECTION_STEP of height (white above the pile)."""
    levels = np.arange(0.0, top + SECTION_STEP, SECTION_STEP)
    image = np.full((len(levels), len(lines)), np.nan)
    for column in range(len(lines)):
        layers = int(count[column])
        if layers == 0:
            continue
        tops = np.cumsum(thickness[column, :layers])
        inside = levels < tops[-1]
        image[inside, column] = grade[column, np.searchsorted(tops, levels[inside], side="right")]
    spacing = float(lines[1] - lines[0])
    edges = np.concatenate([lines - spacing / 2, [lines[-1] + spacing / 2]])
    heights = np.concatenate([levels, [levels[-1] + SECTION_STEP]])
    return ax.pcolormesh(edges, heights, np.ma.masked_invalid(image), shading="flat", **limits)


def blend_figure(result: RunResult, subtitle: str) -> Figure:
    """blend.png: the grade that left a stacked pile, bucket by bucket after the belt's delay,
    against what was stacked into it and the band."""
    out, blend = result.reclaim.grade_out, result.metrics["blend"]
    name = out["name"]
    fig = Figure(figsize=(12, 5), layout="constrained")
    ax = fig.subplots()
    ax.plot(out["t"], out["grade"], ".", ms=2, color="C0", label="grade out, each bucket")
    buckets = max(round(result.machine.wheel.discharges_per_minute), 1)  # a minute's discharges
    window = np.ones(buckets)
    minute = (np.convolve(out["grade"] * out["tonnes"], window, "same")
              / np.maximum(np.convolve(out["tonnes"], window, "same"), 1e-12))
    ax.plot(out["t"], minute, "-", lw=1.0, color="C1", label=f"the same, tonne-weighted over {buckets} buckets (a minute)")
    for value, style, label in ((blend["grade_in_mean"], "k--", "stacked, mean"),
                                (blend["grade_in_mean"] - blend["grade_in_sd"], "k:", "stacked, mean ± sd"),
                                (blend["grade_in_mean"] + blend["grade_in_sd"], "k:", None)):
        ax.axhline(value, color=style[0], ls=style[1:], lw=0.8, label=label)
    if blend["band"] is not None:
        ax.axhspan(*blend["band"], color="C2", alpha=0.12, label=f"band {blend['band'][0]:g}-{blend['band'][1]:g} {name}")
    ax.set_xlabel(f"time [s], at the belt scale ({blend['belt_delay_s']:.1f} s after the discharge)")
    ax.set_ylabel(name)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", ncols=2)
    ax.set_title(f"{blend['tonnes_out_t']:,.0f} t out at {blend['grade_out_mean']:.3f} ± {blend['grade_out_sd']:.3f} "
                 f"{name}, stacked at {blend['grade_in_mean']:.3f} ± {blend['grade_in_sd']:.3f} in "
                 f"{pattern_text(blend['pattern'], blend['layers'])}: sd ratio {blend['sd_ratio']:.3f} "
                 f"({law_text(blend['equivalent_layers'])})")
    fig.suptitle(f"The blend reclaimed from the stacked pile\n{subtitle}")
    fit_titles(fig)
    return fig
