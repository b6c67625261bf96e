"""Compile the loop's kernels once, so that no first run waits for them.

    python -m bwr_twin.sim.warm

The per-period hot spots are compiled with numba on first use (some 10 s on this 2-core
machine) and cached on disk. `make setup` runs this: a second of each kind of shipped scene (the
fuzzy controller on the paper's path, a PID digging a pile, two machines under an interlock that
quick-stops them, a bench reclaim under its rate loop, a stacker laying a pile) and a lockstep
of two runs (whose rows are views of the batch's arrays, another signature) call every kernel
once, and every later run, the replay's and a batch's included, starts compiled.
"""

from __future__ import annotations

import time

from bwr_twin.config.scene import load_scene
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import simulate, simulate_lockstep


def _first_second(name: str) -> dict:
    """Overrides that end a shipped path scene after its first second, on its own first via point."""
    first = load_scene(find_scene(name)).trajectory.via_points[0]
    return {"path.via_points": [{"t": 0.0, "p": list(first.p)}, {"t": 1.0, "p": list(first.p)}]}


def main() -> None:
    started = time.perf_counter()
    for name, overrides in (("paper_individual_gains", _first_second("paper_individual_gains")),
                            ("heavy_dig_pile", _first_second("heavy_dig_pile")),
                            # an encoder that drops out: the interlock quick-stops the drives
                            ("heavy_two_machines_interlocked", {**_first_second("heavy_two_machines_interlocked"),
                                                                "faults": [{"kind": "encoder_dropout", "axis": "travel",
                                                                            "start": 0.5}]}),
                            ("heavy_bench_reclaim", {"reclaim.stop": {"time": 1.0}}),
                            # a stacker laying 200 t on a 20 m axis: deposits, relaxation, layers
                            ("heavy_chevron_stack", {"stacking.tonnes": 200.0, "stacking.layers": 1,
                                                     "stacking.axis_x": [-10.0, 10.0]})):
        simulate(load_scene(find_scene(name), overrides))
    paper = _first_second("paper_individual_gains")
    simulate_lockstep([load_scene(find_scene("paper_individual_gains"), {**paper, "simulation.seed": seed})
                       for seed in (1, 2)])
    print(f"compiled the loop's kernels in {time.perf_counter() - started:.1f} s (cached for every later run)")


if __name__ == "__main__":
    main()
