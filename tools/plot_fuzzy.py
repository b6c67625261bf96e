"""Plot a fuzzy rule base: membership functions (like MATLAB's plotmf) and the control surface
in 3D and as a heat map (like gensurf), as PNG files.

    python tools/plot_fuzzy.py [--rules PATH] [--out DIR]

The surface is the compiled one the simulation uses (bwr_twin.control.fuzzy.FuzzySurface), so the first
run for a rule base computes it with skfuzzy (about 15 s) and later runs read the cache.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; the machines have no display
import matplotlib.pyplot as plt
import numpy as np

from bwr_twin.control.fuzzy import FuzzySurface, build_control_system
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.errors import BwrError
from bwr_twin.shipped import RULE_BASES

TITLE_INPUTS = {"e": "position error e (scaled)", "ec": "velocity error ec (scaled)", "u": "output u"}


def plot_memberships(rule_base: RuleBase, path: Path) -> None:
    """One panel per variable: every set's membership over the universe, as skfuzzy defines it."""
    _, e, ec, u = build_control_system(rule_base)
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), constrained_layout=True)
    colours = plt.cm.coolwarm(np.linspace(0.0, 1.0, len(rule_base.sets)))
    for ax, var in zip(axes, (e, ec, u)):
        for colour, name in zip(colours, rule_base.sets):
            ax.plot(var.universe, var[name].mf, color=colour, lw=2, label=name)
            peak = var.universe[np.argmax(var[name].mf)]
            ax.annotate(name, (peak, 1.02), ha="center", va="bottom", fontsize=9)
        ax.set_xlim(var.universe[0], var.universe[-1])
        ax.set_ylim(0.0, 1.15)
        ax.set_xlabel(TITLE_INPUTS[var.label])
        ax.set_ylabel("degree of membership")
        ax.set_title(f"Membership functions of {var.label}")
        ax.grid(alpha=0.3)
    axes[0].legend(ncol=len(rule_base.sets), loc="upper center", bbox_to_anchor=(0.5, 1.45), frameon=False)
    fig.suptitle(f"Fuzzy sets ({rule_base.shape}), {_source(rule_base)}")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_surface_3d(surface: FuzzySurface, path: Path) -> None:
    rb = surface.rule_base
    e, ec = np.meshgrid(surface.grid_e, surface.grid_ec, indexing="ij")
    fig = plt.figure(figsize=(9, 7), constrained_layout=True)
    ax = fig.add_subplot(projection="3d")
    mesh = ax.plot_surface(e, ec, surface.values, cmap="viridis", rstride=2, cstride=2, lw=0.1, edgecolor="k")
    ax.set_xlabel("e (position error)")
    ax.set_ylabel("ec (velocity error)")
    ax.set_zlabel("u (fuzzy output)")
    ax.set_zlim(*rb.output_range)
    ax.view_init(elev=28, azim=-130)
    fig.colorbar(mesh, ax=ax, shrink=0.6, label="u")
    ax.set_title(f"Control surface u = FLC(e, ec): {_inference(rb)}\n{_source(rb)}")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_surface_heatmap(surface: FuzzySurface, path: Path) -> None:
    rb = surface.rule_base
    fig, ax = plt.subplots(figsize=(8, 6.8), constrained_layout=True)
    extent = (*rb.ec_range, *rb.e_range)
    image = ax.imshow(surface.values, origin="lower", extent=extent, aspect="auto", cmap="RdBu_r",
                      vmin=rb.output_range[0], vmax=rb.output_range[1])
    levels = np.linspace(*rb.output_range, 13)
    lines = ax.contour(surface.grid_ec, surface.grid_e, surface.values, levels=levels, colors="k",
                       linewidths=0.6)
    ax.clabel(lines, fmt="%.2f", fontsize=7)
    # The rule table on top: each rule's output set at its (e, ec) peak pair.
    peaks_e = rb.term_peaks(*rb.e_range)
    peaks_ec = rb.term_peaks(*rb.ec_range)
    for i, row in enumerate(rb.rules):
        for j, name in enumerate(row):
            ax.text(peaks_ec[j], peaks_e[i], name, ha="center", va="center", fontsize=7, clip_on=False,
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7})
    ax.set_xticks(peaks_ec, [f"{p:g}" for p in peaks_ec])
    ax.set_yticks(peaks_e, [f"{p:g}" for p in peaks_e])
    ax.tick_params(pad=10)  # room for the rule labels that overhang the edges
    ax.set_xlabel("ec (velocity error)")
    ax.set_ylabel("e (position error)")
    fig.colorbar(image, ax=ax, label="u (fuzzy output)")
    ax.set_title(f"Control surface, top view, with the rule table: {_inference(rb)}\n{_source(rb)}")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def _source(rb: RuleBase) -> str:
    return rb.path.name if rb.path is not None else "rule base"


def _inference(rb: RuleBase) -> str:
    return f"AND={rb.and_method}, aggregation={rb.aggregation}, {rb.defuzzify}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rules", type=Path, default=RULE_BASES / "paper_table2.toml",
                        help="rule base TOML (default: the paper's)")
    parser.add_argument("--out", type=Path, default=Path("out/fuzzy"),
                        help="output folder (default: out/fuzzy)")
    args = parser.parse_args(argv)
    try:
        rule_base = RuleBase.from_toml(args.rules)
        surface = FuzzySurface.load(rule_base)
    except BwrError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    written = []
    for name, plot, subject in (
        ("membership_functions.png", plot_memberships, rule_base),
        ("control_surface_3d.png", plot_surface_3d, surface),
        ("control_surface_heatmap.png", plot_surface_heatmap, surface),
    ):
        path = args.out / name
        plot(subject, path)
        written.append(path)
    for path in written:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
