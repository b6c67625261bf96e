"""The blend against the number of layers, on piles the twin stacks and reclaims (docs/blending.md):
heavy_chevron_stack with N layers, then heavy_stack_and_reclaim on that pile, for several seeds.

    python tools/blend_layers.py [--layers 16 32 64 128] [--seeds 1 2 3 4] [--out out/blend_layers]

The tonnes and the axis stay the scene's; the rate falls as N grows (10,000 t/h x 32 / N) so that
the passes keep the same speed, within the travel's rating. Per N, pooled over the seeds, the
spread of the grade, as a ratio to the stream's: in full-face slices of the stacked pile (each
grid column across it, cut to the floor), bucket by bucket as reclaimed, and in lots of a
minute's buckets. Each is given about the stream's own mean (the AR(1)'s `mean`: the law's
sense, sigma over an endless pile) and, for the slices and lots, about the sample's own mean as
metrics.json gives it, which a pile or a reclaim a few correlation lengths long underestimates.
Prints a markdown table, writes the numbers of every run to --out's blend_layers.json and draws
the ratios against N beside the ideal pile (bwr_twin.stockpile.blending) into blend_layers.png.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter, ScalarFormatter

from bwr_twin.config.scene import load_scene
from bwr_twin.results.rundir import PILE_FILE, write_run
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate
from bwr_twin.stockpile import blending
from bwr_twin.stockpile.grade import lots, rms_from, tonne_weighted

REFERENCE_LAYERS = 32  # heavy_chevron_stack's: its rate keeps their passes within the rated travel speed
FULL_SLICE = 0.5  # a slice holding at least this share of the fullest one's tonnes: the pile's body


def study_parser(description: str, seeds: list[int], out: str) -> argparse.ArgumentParser:
    """The options the blend studies share: the seeds, the output folder and --redraw."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--seeds", type=int, nargs="+", default=seeds)
    parser.add_argument("--out", type=Path, default=Path(out))
    parser.add_argument("--redraw", action="store_true", help="the table and figure again from the numbers in "
                        "--out, without running")
    return parser


def saved_numbers(args: argparse.Namespace, name: str) -> tuple[Path, dict | None]:
    """The study's numbers file in --out, and what it holds if --redraw asks for it."""
    numbers = args.out / name
    return numbers, json.loads(numbers.read_text()) if args.redraw else None


def main() -> None:
    parser = study_parser(__doc__.splitlines()[0], [1, 2, 3, 4], "out/blend_layers")
    parser.add_argument("--layers", type=int, nargs="+", default=[16, 32, 64, 128])
    args = parser.parse_args()
    numbers, saved = saved_numbers(args, "blend_layers.json")
    if saved is not None:
        mean, runs = saved["stream_mean"], saved["runs"]
    else:
        stacking = load_scene(find_scene("heavy_chevron_stack"))
        mean = stacking.stacking.grade.mean  # the stream's own mean
        runs, start = [], time.perf_counter()
        for layers in args.layers:
            for seed in args.seeds:
                rate = stacking.stacking.rate * REFERENCE_LAYERS / layers
                runs.append({"layers": layers, "rate": rate, **stack_and_reclaim(
                    {"stacking.layers": layers, "stacking.rate": rate}, seed, args.out / f"stack_{layers}_seed_{seed}")})
                print(f"N = {layers}, seed {seed}: done, {time.perf_counter() - start:.0f} s", flush=True)
        args.out.mkdir(parents=True, exist_ok=True)
        numbers.write_text(json.dumps({"stream_mean": mean, "runs": runs}, indent=1))
    counts = sorted({run["layers"] for run in runs})
    rows = [{"layers": n, "rate": next(run["rate"] for run in runs if run["layers"] == n),
             **pooled([run for run in runs if run["layers"] == n], mean)} for n in counts]
    print(f"\n{len(rows[0]['seeds'])} seeds a row; ratios to the stream's spread per deposit, about the stream's "
          f"mean {mean:g} (± the standard error over the seeds) and (own) about the sample's own mean\n")
    print("| N | rate t/h | slices | slices (own) | buckets | minute lots | minute lots (own) | 1/sqrt(N) "
          "| t reclaimed a run |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for row in rows:
        print(f"| {row['layers']} | {row['rate']:,.0f} | {pm(row, 'slices')} | {row['slices_own']:.3f} | "
              f"{pm(row, 'buckets')} | {pm(row, 'lots')} | {row['lots_own']:.3f} | "
              f"{1 / math.sqrt(row['layers']):.3f} | {row['tonnes_out']:,.0f} |")
    ideal = [blending.blend(n).ratio for n in counts]
    _figure(rows, ideal).savefig(args.out / "blend_layers.png", dpi=110)
    print(f"\nfigure: {args.out / 'blend_layers.png'}; numbers: {numbers}")


def pm(row: dict, key: str) -> str:
    """A row's ratio and its standard error over the seeds."""
    return f"{row[key]:.3f} ± {row[key + '_se']:.3f}"


def stack_and_reclaim(overrides: dict, seed: int, pile_dir: Path) -> dict:
    """heavy_chevron_stack with `overrides` from the stream of `seed`, written to `pile_dir`, then
    reclaimed as heavy_stack_and_reclaim: the deposits', the pile's full-face slices' and the
    discharges' and minute lots' tonnes and grades, and the law's N for the passes laid."""
    stacked = simulate(load_scene(find_scene("heavy_chevron_stack"), {**overrides, "simulation.seed": seed}))
    write_run(stacked, pile_dir, overwrite=True, plots=False)
    reclaimed = simulate(load_scene(find_scene("heavy_stack_and_reclaim"), {
        "stockpile.surface_file": str(pile_dir / PILE_FILE), "simulation.seed": seed}))
    record, out_grade = stacked.stacking, reclaimed.reclaim.grade_out
    minute = max(round(reclaimed.machine.wheel.discharges_per_minute), 1)
    lot_tonnes, lot_grade = lots(out_grade["tonnes"], out_grade["grade"], minute)
    slice_volume = record.thickness.sum(axis=(0, 2))  # per grid column along the axis, m x cells
    slice_grade = (record.thickness * record.layer_grade).sum(axis=(0, 2)) / np.maximum(slice_volume, 1e-300)
    body = slice_volume >= FULL_SLICE * slice_volume.max()
    return {"seed": seed, "equivalent_layers": stacked.metrics["stacking"]["equivalent_layers"],
            "deposits": (record.tonnes.tolist(), record.grade.tolist()),
            "slices": (slice_volume[body].tolist(), slice_grade[body].tolist()),
            "buckets": (out_grade["tonnes"].tolist(), out_grade["grade"].tolist()),
            "lots": (lot_tonnes.tolist(), lot_grade.tolist())}


def pooled(runs: list[dict], mean: float) -> dict:
    """One row: each seed's spreads as ratios to its deposits', about the stream's `mean`, pooled
    (the root mean square of the seeds' ratios) with their standard error over the seeds; and the
    same about each sample's own mean, as metrics.json gives it."""
    def ratios(key: str, about_mean: bool = True) -> np.ndarray:
        out = []
        for run in runs:
            tonnes, grade = (np.asarray(v) for v in run[key])
            spread = rms_from(tonnes, grade, mean) if about_mean else tonne_weighted(tonnes, grade)[1]
            out.append(spread / rms_from(*(np.asarray(v) for v in run["deposits"]), mean))
        return np.array(out)

    row = {"seeds": [run["seed"] for run in runs], "equivalent_layers": runs[0]["equivalent_layers"],
           "tonnes_out": float(np.mean([np.sum(run["buckets"][0]) for run in runs]))}
    for key in ("slices", "buckets", "lots"):
        values = ratios(key)
        row[key] = float(np.sqrt(np.mean(values**2)))
        row[key + "_se"] = float(np.std(values, ddof=1) / math.sqrt(len(values))) if len(values) > 1 else float("nan")
    for key in ("slices", "lots"):
        row[key + "_own"] = float(np.sqrt(np.mean(ratios(key, about_mean=False) ** 2)))
    return row


def _figure(rows: list[dict], ideal: list[float]) -> Figure:
    """The ratios against N, on log axes where 1/sqrt(N) is a straight line; the bars are the
    standard error over the seeds."""
    layers = np.array([row["layers"] for row in rows], dtype=float)
    fig = Figure(figsize=(8.5, 6), layout="constrained")
    ax = fig.subplots()
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.plot(layers, 1.0 / np.sqrt(layers), "k--", lw=1.0, label="1/sqrt(N), the law (Gerstel; Kohlhaas and Labahn)")
    ax.plot(layers, ideal, "ks", mfc="none", label="an ideal chevron pile, full-face slices (stockpile/blending.py)")
    for key, style, colour, label in (("slices", "D-", "C2", "the stacked pile, full-face slices"),
                                      ("buckets", "o-", "C0", "bench-reclaimed, bucket by bucket"),
                                      ("lots", "^-", "C1", "bench-reclaimed, lots of a minute")):
        ax.errorbar(layers, [row[key] for row in rows], yerr=[row[key + "_se"] for row in rows], fmt=style,
                    color=colour, capsize=3, label=label)
    ax.plot(layers, [row["lots_own"] for row in rows], "^:", color="C1", mfc="none",
            label="the same lots about their own reclaim's mean, as metrics.json gives it")
    ax.set_xticks(layers, [f"{n:g}" for n in layers])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_major_formatter(ScalarFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())
    ax.set_yticks([0.05, 0.1, 0.2, 0.3, 0.5], ["0.05", "0.1", "0.2", "0.3", "0.5"])
    ax.set_xlabel("N, layers stacked (chevron)")
    ax.set_ylabel("sigma_out / sigma_in, about the stream's mean unless said")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(f"The blend against the number of layers: 20,000 t stacked, the first 30 m reclaimed in two\n"
                 f"benches, {len(rows[0]['seeds'])} seeds each (bars: the standard error over them)", fontsize=10)
    return fig


if __name__ == "__main__":
    main()
