"""The heavy reclaimer and the measured effect of each unmodelled force, as the table of
docs/heavy_machine.md.

    python tools/heavy_effects.py [--seed N]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bwr_twin.results import compute_metrics  # noqa: E402
from bwr_twin.scene import load_scene  # noqa: E402
from bwr_twin.simulate import simulate  # noqa: E402

SCENES = ("heavy_reclaim", "heavy_coulomb_friction", "heavy_wind", "heavy_model_mismatch")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    print("| scene | travel error max | slew error max | luff error max | travel RMS | slew drive RMS | luff drive max | time at drive limit (travel, slew, luff) |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for name in SCENES:
        m = compute_metrics(simulate(load_scene(ROOT / "scenes" / f"{name}.toml", {"simulation.seed": args.seed})))
        saturation = ", ".join(f"{100 * m[a]['saturation_fraction']:.1f} %" for a in ("travel", "slew", "luff"))
        print(
            f"| `{name}` | {m['travel']['position_error_max']:+.3f} m at {m['travel']['position_error_max_time']:.0f} s "
            f"| {np.degrees(m['slew']['position_error_max']):+.3f}° | {np.degrees(m['luff']['position_error_max']):+.3f}° "
            f"| {m['travel']['position_error_rms']:.3f} m | {m['slew']['drive_force_rms'] / 1e6:.2f} MN m "
            f"| {m['luff']['drive_force_max'] / 1e6:.1f} MN m | {saturation} |"
        )


if __name__ == "__main__":
    main()
