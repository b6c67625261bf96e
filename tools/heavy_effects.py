"""The heavy reclaimer and the measured effect of each unmodelled force: the table of
docs/heavy_machine.md, and a figure of the errors and the slew torque of every scene.

    python tools/heavy_effects.py [--seed N] [--figure docs/figures/heavy_effects.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from matplotlib.figure import Figure

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.shipped import SCENES
from bwr_twin.sim.lockstep import simulate

RMS_WINDOW = 10.0  # s: the slew torque switches from one record to the next; its RMS shows the load
HEAVY_SCENES = ("heavy_reclaim", "heavy_coulomb_friction", "heavy_wind", "heavy_model_mismatch")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--figure", type=Path, default=ROOT / "docs" / "figures" / "heavy_effects.png")
    args = parser.parse_args()
    results = {}
    print("| scene | travel error max | slew error max | luff error max | travel RMS | slew drive RMS | luff drive max | time at drive limit (travel, slew, luff) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in HEAVY_SCENES:
        results[name] = simulate(load_scene(SCENES / f"{name}.toml", {"simulation.seed": args.seed}))
        m = results[name].metrics
        saturation = ", ".join(f"{100 * m[a]['saturation_fraction']:.1f} %" for a in ("travel", "slew", "luff"))
        print(
            f"| `{name}` | {m['travel']['position_error_max']:+.3f} m at {m['travel']['position_error_max_time']:.0f} s "
            f"| {np.degrees(m['slew']['position_error_max']):+.3f}° | {np.degrees(m['luff']['position_error_max']):+.3f}° "
            f"| {m['travel']['position_error_rms']:.3f} m | {m['slew']['drive_force_rms'] / 1e6:.2f} MN m "
            f"| {m['luff']['drive_force_max'] / 1e6:.1f} MN m | {saturation} |"
        )

    save_figure(results, args.figure)
    print(f"figure in {args.figure}")


def save_figure(results: dict, path: Path) -> None:
    """Position error per axis of every scene, and the slew drive torque they need."""
    fig = Figure(figsize=(11, 10), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    for name, result in results.items():
        error = result.q_desired - result.q
        for j, ax in enumerate(axes[:3]):
            ax.plot(result.time, to_display(j, error[:, j]), lw=0.7, label=name)
            ax.set_ylabel(f"{AXES[j]} error [{UNITS[j]}]")
        window = max(1, round(RMS_WINDOW / result.scene.simulation.record_period))
        mean_square = np.convolve(result.drive_force[:, 1] ** 2, np.ones(window) / window, mode="same")
        axes[3].plot(result.time, np.sqrt(mean_square) / 1e6, lw=1.0, label=name)
    axes[3].set_ylabel(f"slew drive, {RMS_WINDOW:g} s RMS [MN m]")
    axes[3].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper left", ncols=2)
    fig.suptitle("The heavy reclaim and each unmodelled force: position errors (desired - actual) and slew torque")
    fig.savefig(path, dpi=100)


if __name__ == "__main__":
    main()
