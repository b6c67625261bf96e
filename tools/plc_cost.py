"""What the rules block (`export plc --fuzzy rules`) costs a cycle, against the table block:
docs/plc_export.md's figures.

    python tools/plc_cost.py [SCENE] [--every N] [--random N] [--assumed-ns T]

Exports a fuzzy_model scene's controller both ways and runs each block (tests/st_python.py) on
the scene's recorded run, every N-th control period, and on random inputs across the fuzzy
universes and a fifth beyond, counting each call's LREAL arithmetic and comparisons with a
counting number: the whole block, and its loop over the axes alone (the fuzzy part, and u from
it; the model-based rest is the same in both). Prints the largest and the mean count a call, the
rules loop's bound (bwr_twin.export.blocks.rules_cost_bound, checked), the Python-translated
block's time a call, and what the largest count takes at T ns an operation: an assumed figure,
not a measured one.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from st_python import counting_real, load_block, read_global_constants  # noqa: E402

from bwr_twin.config.scene import load_scene  # noqa: E402
from bwr_twin.control.rulebase import load_rule_base  # noqa: E402
from bwr_twin.export.blocks import rules_cost_bound  # noqa: E402
from bwr_twin.export.plc import export_plc  # noqa: E402
from bwr_twin.shipped import SCENES  # noqa: E402
from bwr_twin.sim.lockstep import simulate  # noqa: E402


def recorded_inputs(scene_name: str, every: int) -> tuple[object, list[tuple[list, ...]]]:
    """The scene and its run's block inputs (q, qd, q_ref, qd_ref, qdd_ref) every `every` periods."""
    period = load_scene(SCENES / f"{scene_name}.toml").simulation.control_period
    result = simulate(load_scene(SCENES / f"{scene_name}.toml", {"simulation.record_period": period}))
    signals = (result.q_measured, result.qd_measured, result.q_desired, result.qd_desired, result.qdd_desired)
    return result.scene, [tuple(list(x[k]) for x in signals) for k in range(0, len(result.time), every)]


def random_inputs(scene, count: int, seed: int = 0) -> list[tuple[list, ...]]:
    """Errors whose scaled values fall across the e and ec universes and a fifth beyond each end."""
    settings = scene.controller.settings
    rule_base = load_rule_base(settings.rule_base)
    rng = np.random.default_rng(seed)
    zero = [0.0, 0.0, 0.0]

    def across(bounds, scale):
        low, high = bounds
        margin = 0.2 * (high - low)
        return list(rng.uniform(low - margin, high + margin, 3) / scale)

    return [(zero, zero, across(rule_base.e_range, settings.input_scale_e),
             across(rule_base.ec_range, settings.input_scale_ec), zero) for _ in range(count)]


def exported_blocks(folder: Path, number: type | None = None) -> dict[str, object]:
    """The exported block, whole and cut after its loop over the axes, as new instances."""
    constants = {}
    for global_list in sorted(folder.glob("GVL_*.st")):
        constants |= read_global_constants(global_list.read_text())
    (path,) = folder.glob("FB_*.st")
    text = path.read_text()
    loop, end, _ = text.partition("\nEND_FOR\n")  # the body's first unindented END_FOR closes the axis loop
    assert end, f"{path.name}: no loop over the axes"
    return {"whole": load_block(text, constants, number)(),
            "axis loop": load_block(loop + end + "END_FUNCTION_BLOCK\n", constants, number)()}


def counts(block, number: type, inputs) -> np.ndarray:
    """(calls, 3): each call's arithmetic operations, comparisons, and divisions (of the arithmetic)."""
    tally = np.empty((len(inputs), 3), dtype=np.int64)
    for row, arguments in enumerate(inputs):
        number.counts.update(arithmetic=0, divisions=0, comparisons=0)
        block(*arguments)
        tally[row] = number.counts["arithmetic"], number.counts["comparisons"], number.counts["divisions"]
    return tally


def seconds_a_call(block, inputs) -> float:
    started = time.perf_counter()
    for arguments in inputs:
        block(*arguments)
    return (time.perf_counter() - started) / len(inputs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default="paper_individual_gains")
    parser.add_argument("--every", type=int, default=10, help="count every N-th control period of the run")
    parser.add_argument("--random", type=int, default=5000, help="random inputs across the universes")
    parser.add_argument("--assumed-ns", type=float, default=10.0, help="assumed time an operation, ns")
    args = parser.parse_args()
    scene, run = recorded_inputs(args.scene, args.every)
    stress = random_inputs(scene, args.random)
    rule_base = load_rule_base(scene.controller.settings.rule_base)
    bound = rules_cost_bound(len(rule_base.sets), rule_base.output_points)
    print(f"{args.scene}: {len(run):,} periods of its run (every {args.every}th) and {len(stress):,} random "
          f"inputs; {len(rule_base.sets)} sets, {len(rule_base.sets) ** 2} rules, {rule_base.output_points} "
          "output samples. Counts a call (three axes): arithmetic + comparisons.")
    print("| block | part | largest (arithmetic, comparisons; divisions of the arithmetic) | mean on the run | "
          "Python a call | "
          f"largest at an assumed {args.assumed_ns:g} ns an operation |")
    print("| --- | --- | --- | --- | --- | --- |")
    with tempfile.TemporaryDirectory() as tmp:
        for fuzzy in ("table", "rules"):
            folder = Path(tmp) / fuzzy
            export_plc(scene, folder, fuzzy=fuzzy)
            number = counting_real()
            for part, block in exported_blocks(folder, number).items():
                tally = np.concatenate([counts(block, number, run), counts(block, number, stress)])
                operations = tally[:, :2].sum(axis=1)
                largest = tally[operations.argmax()]
                took = seconds_a_call(exported_blocks(folder)[part], run)
                print(f"| {fuzzy} | {part} | {operations.max():,} ({largest[0]:,}, {largest[1]:,}; {largest[2]:,}) | "
                      f"{operations[:len(run)].mean():,.0f} | {took * 1e6:,.0f} µs | "
                      f"{operations.max() * args.assumed_ns * 1e-3:,.1f} µs |")
                if (fuzzy, part) == ("rules", "axis loop"):
                    most = tally[:, :2].max(axis=0)
                    assert (most <= bound).all(), f"{most} above the bound {bound}"
    print(f"the rules block's axis loop, at most (rules_cost_bound): {sum(bound):,} ({bound[0]:,}, {bound[1]:,})")


if __name__ == "__main__":
    main()
