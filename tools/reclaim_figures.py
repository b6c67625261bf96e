"""The figures and tables of docs/reclaiming.md: the bench reclaim of heavy_bench_reclaim under
each rate control, and the three benches of heavy_benches, pile before and after.

    python tools/reclaim_figures.py [--seed N] [--figures docs/figures/reclaiming] [--workers 2]

Prints the markdown tables and writes rate.png, plan.png and pile.png into --figures. Four runs of
18 to 50 simulated minutes: a few minutes on two cores.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.pile.surface import build_surface
from bwr_twin.planning.bench import plan_scene
from bwr_twin.shipped import SCENES
from bwr_twin.sim.lockstep import simulate

ROOT = Path(__file__).resolve().parents[1]
BENCH = SCENES / "heavy_bench_reclaim.toml"
BENCHES = SCENES / "heavy_benches.toml"
RATE_CONTROLS = {"open loop (1/cos law)": "open_loop", "belt scale": "belt_scale", "wheel power": "wheel_power"}


def run(scene_file: Path, overrides: dict) -> dict:
    """One run's metrics and the signals the figures need (plain arrays: they cross processes)."""
    scene = load_scene(scene_file, overrides)
    started = time.perf_counter()
    result = simulate(scene)
    return {
        "seconds": time.perf_counter() - started,
        "metrics": result.metrics,
        "time": result.time,
        "rate": result.reclaim.rate,
        "slew_speed": np.degrees(result.qd_desired[:, 1]),
        "x": result.reclaim.x, "y": result.reclaim.y,
        "z_start": result.reclaim.z_start, "z_end": result.reclaim.z_end,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures" / "reclaiming")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    seed = {"simulation.seed": args.seed}
    jobs = {label: (BENCH, {**seed, "reclaim.rate_control.type": kind}) for label, kind in RATE_CONTROLS.items()}
    jobs["heavy_benches"] = (BENCHES, seed)
    with ProcessPoolExecutor(args.workers) as pool:
        futures = {label: pool.submit(run, *job) for label, job in jobs.items()}
        runs = {label: future.result() for label, future in futures.items()}

    print("| heavy_bench_reclaim | steady rate (target 8,000 t/h) | steady reclaim rate CV (std/mean) "
          "| steady cutting time within ±10 % of the target | steady time | landing error "
          "| over-cut max | reclaimed (planned) | mean rate while carrying | took | simulated in |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for label in RATE_CONTROLS:
        print(_row(label, runs[label]))
    benches = runs["heavy_benches"]
    m = benches["metrics"]["reclaim"]
    print()
    print("| heavy_benches | bench 1 | bench 2 | bench 3 |")
    print("| --- | --- | --- | --- |")
    print("| reclaimed | " + " | ".join(f"{t:,.0f} t" for t in m["bench_t"]) + " |")
    print("| planned | " + " | ".join(f"{t:,.0f} t" for t in m["bench_planned_t"]) + " |")
    print()
    print(_row("heavy_benches, belt scale", benches))

    args.figures.mkdir(parents=True, exist_ok=True)
    _rate_figure({label: runs[label] for label in RATE_CONTROLS}, args.figures / "rate.png")
    _plan_figure(args.figures / "plan.png")
    _pile_figure(benches, args.figures / "pile.png")
    print(f"\nfigures in {args.figures}/")


def _row(label: str, r: dict) -> str:
    m = r["metrics"]["reclaim"]
    target = m["target_rate_tph"]
    return (f"| {label} | {m['steady_rate_mean_tph']:,.0f} t/h ({100 * (m['steady_rate_mean_tph'] / target - 1):+.1f} %) "
            f"| {_or_dash(m['steady_rate_cv'], '{:.3f}')} | {_or_dash(m['steady_within_10pct'], '{:.0f} %', 100)} | {m['steady_time_s']:.0f} s "
            f"| {_or_dash(m['landing_error_m'], '{:.3f} m')} | {m['overcut_max_m']:.2f} m | {m['mass_t']:,.0f} t "
            f"({sum(m['bench_planned_t']):,.0f} t) | {m['rate_mean_tph']:,.0f} t/h | {r['metrics']['run']['duration']:.0f} s "
            f"| {r['seconds']:.0f} s |")


def _or_dash(value, form: str, scale: float = 1.0) -> str:
    """A steady-state figure, or a dash where the run had no steady cutting to measure it on."""
    return "-" if value is None else form.format(scale * value)


def _rate_figure(runs: dict, path: Path) -> None:
    fig = Figure(figsize=(11, 7), layout="constrained")
    rate, speed = fig.subplots(2, 1, sharex=True)
    for i, (label, r) in enumerate(runs.items()):
        rate.plot(r["time"], r["rate"], f"C{i}-", lw=0.8, label=label)
        speed.plot(r["time"], r["slew_speed"], f"C{i}-", lw=0.8, label=label)
    rate.axhline(next(iter(runs.values()))["metrics"]["reclaim"]["target_rate_tph"], color="k", ls=":", lw=1,
                 label="target")
    rate.set_ylabel("reclaim rate [t/h]")
    rate.legend(loc="upper left", ncols=4)
    rate.grid(alpha=0.3)
    speed.set_ylabel("slew speed reference [deg/s]")
    speed.set_xlabel("time [s]")
    speed.grid(alpha=0.3)
    fig.suptitle("heavy_bench_reclaim: one bench from the windrow's end, 8,000 t/h under each rate control")
    fig.savefig(path, dpi=110)


def _plan_figure(path: Path) -> None:
    """The planned pattern of heavy_benches over the pile, in plan view: each pass's arc, by bench."""
    scene = load_scene(BENCHES)
    plan = plan_scene(scene)
    machine = Machine(scene.machine.mjcf)
    surface = build_surface(scene.stockpile, scene.path)
    fig = Figure(figsize=(11, 6.5), layout="constrained")
    ax = fig.subplots()
    contours = ax.contourf(surface.x, surface.y, surface.z, levels=np.arange(0.0, 15.1, 1.0), cmap="copper_r")
    fig.colorbar(contours, ax=ax, label="pile height at the start [m]", shrink=0.8)
    for p in plan.passes:
        slew = np.linspace(p.start, p.end, 100)
        cp = machine.fk(np.column_stack([np.full(100, p.travel), slew, np.full(100, p.luff)]))
        first = p is next(x for x in plan.passes if x.bench == p.bench)
        floor = cp[0, 2] - machine.wheel.radius
        ax.plot(cp[:, 0], cp[:, 1], f"C{p.bench}-", lw=1.2,
                label=f"bench {p.bench + 1}: floor {floor:.1f} m, {plan.bench_tonnes()[p.bench]:,.0f} t" if first else None)
    ax.plot(*plan.first_contact[:2], "r*", ms=14, label="planned first contact")
    ax.set_xlim(-45, 25)
    ax.set_ylim(0, 60)
    ax.set_aspect("equal")
    ax.set_xlabel("X, along the rail [m]")
    ax.set_ylabel("Y, from the rail [m]")
    ax.legend(loc="upper left")
    fig.suptitle(f"heavy_benches: the wheel centre's path on the {len(plan.passes)} planned slew passes "
                 f"of {plan.benches} benches")
    fig.savefig(path, dpi=110)


def _pile_figure(r: dict, path: Path) -> None:
    """The pile's end before and after heavy_benches: heights, and a section along the rail where
    the benches took the most."""
    x, y = r["x"], r["y"]
    near = (x > -25) & (x < 15)
    fig = Figure(figsize=(11, 8), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[1.3, 1])
    views = top.subplots(1, 2, sharey=True)
    cell = (x[1] - x[0]) * (y[1] - y[0])
    for ax, z, label in ((views[0], r["z_start"], "before"), (views[1], r["z_end"], "after")):
        image = ax.pcolormesh(x[near], y, z[:, near], cmap="copper_r", vmin=0, vmax=15, shading="nearest")
        ax.contour(x[near], y, z[:, near], levels=[5.0, 10.0], colors="w", linewidths=0.6)
        ax.set_aspect("equal")
        ax.set_xlabel("X [m]")
        ax.set_title(f"{label}: {np.sum(z) * cell:,.0f} m³ in the pile")
    views[0].set_ylabel("Y [m]")
    top.colorbar(image, ax=views, label="height [m]", shrink=0.8)
    section = bottom.subplots()
    row = int(np.argmax(np.sum(r["z_start"] - r["z_end"], axis=1)))  # where the benches took the most
    section.plot(x[near], r["z_start"][row, near], "k--", lw=1, label="before")
    section.plot(x[near], r["z_end"][row, near], "C0-", lw=1.5, label="after")
    section.set_xlabel("X, along the rail [m]")
    section.set_ylabel(f"height at Y = {y[row]:.1f} m [m]")
    section.set_aspect("equal")
    section.legend(loc="lower right")
    section.grid(alpha=0.3)
    fig.suptitle("heavy_benches: the windrow's end before and after three benches (white: 5 and 10 m)")
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
