"""The shadow on a calibrated model against the nominal one (docs/shadow.md): on machines that are
not bwr_heavy.xml, each fitted from its own calibration test, the shadow's delays, isolation and
false alarms with the nominal MJCF and with the calibrated one.

    python tools/shadow_calibrated_study.py [--variants 2] [--seeds 10] [--fault-free-hours 10] [--out out/shadow_calibrated]

Each variant is tools/calibration_study.py's (its damping, drive inertia, Coulomb friction and
counterweight moved 10-50 %, seeded), calibrated as that study does (a 10-minute planned test,
logged at 10 Hz in a gusty wind) with every parameter that study fits. Then, as tools/shadow_study.py does on bwr_heavy.xml,
the variant runs scenes/heavy_shadow.toml's path in its own weather: an hour of fault-free logs
that both shadows learn their thresholds from, --seeds runs of each fault class, and
--fault-free-hours of fault-free logs for the false alarms. Each log is watched twice, by the
shadow on the nominal MJCF and by the shadow on the calibrated one.
"""

from __future__ import annotations

import argparse
import statistics
from collections import Counter
from pathlib import Path

import numpy as np
from calibration_study import HEAVY, PARAMS, PLANT, imperfect, log_of, variant
from shadow_study import LOG_S, SCENE, classes, run

from bwr_twin.calibrate.cli import calibrated_xml
from bwr_twin.calibrate.fit import Problem, fit
from bwr_twin.calibrate.parameters import catalogue
from bwr_twin.calibrate.plan import scene_text
from bwr_twin.model.machine import Machine
from bwr_twin.shadow.twin import ShadowTwin
from bwr_twin.shadow.watch import learn_from, watch

def calibrate(folder: Path, rng: np.random.Generator) -> tuple[Path, Path]:
    """A variant machine and its MJCF calibrated from the nominal one on its test's log; also the
    variant's shadow scene (heavy_shadow.toml on it, with its Coulomb friction)."""
    mjcf, _, friction = variant(folder, rng)
    machine = Machine(mjcf)
    plant = PLANT.format(friction=", ".join(f"{f:.6g}" for f in friction))
    test = folder / "test.toml"
    test.write_text(imperfect(scene_text(machine, mjcf, test, 10.0), 1.0) + plant)
    nominal = Machine(HEAVY)
    result = fit(Problem(nominal, catalogue(nominal, PARAMS), [log_of(test, rng)]))
    calibrated = folder / "calibrated.xml"
    calibrated.write_text(calibrated_xml(HEAVY, [test], result))
    shadow_scene = folder / "shadow.toml"
    shadow_scene.write_text(f'extends = "{SCENE}"\n[machine]\nmjcf = "{mjcf}"\n'
                            f'[plant]\nfrictionloss = [{", ".join(f"{f:.6g}" for f in friction)}]\n')
    return calibrated, shadow_scene


def study(folder: Path, scene: Path, twins: dict[str, ShadowTwin], seeds: int, hours: float) -> dict[str, dict]:
    """Per twin: per class (median delay s, missed, isolated share, the share isolated or named
    beside the first as a fault not told apart from it, what the others were named), and the
    false alarms over the fault-free hours."""
    learned_on = [run(folder, f"baseline-{seed}", seed, scene=scene) for seed in range(1000, 1000 + round(3600 / LOG_S))]
    thresholds = {name: learn_from(twin, learned_on, 0.01) for name, twin in twins.items()}
    found: dict[str, dict] = {name: {} for name in twins}
    for label, (table, kind, axis, _) in classes().items():
        delays: dict[str, list[float]] = {name: [] for name in twins}
        named: dict[str, Counter] = {name: Counter() for name in twins}  # what each first alarm said
        beside = dict.fromkeys(twins, 0)  # first alarms that named the fault as not told apart from theirs
        for seed in range(1, seeds + 1):
            onset = float(round(np.random.default_rng(seed).uniform(60.0, 240.0)))
            log = run(folder, f"{kind}-{seed}", seed, f"[[faults]]\n{table}\nstart = {onset}", scene=scene)
            for name, twin in twins.items():
                alarms = [a for a in watch(twin, log, thresholds[name]).alarms if a.time_s >= onset]
                if alarms:
                    delays[name].append(alarms[0].time_s - onset)
                    named[name][f"{alarms[0].axis} {alarms[0].kind}"] += 1
                    beside[name] += f"{axis} {kind}" in alarms[0].alternatives
        for name in twins:
            median = statistics.median(delays[name]) if delays[name] else float("nan")
            named_else = named[name].copy()
            right = named_else.pop(f"{axis} {kind}", 0)
            found[name][label] = (median, seeds - len(delays[name]), right / seeds, (right + beside[name]) / seeds,
                                  named_else)
    false = dict.fromkeys(twins, 0)
    runs = max(1, round(hours * 3600 / LOG_S))
    for seed in range(2000, 2000 + runs):
        log = run(folder, f"fault_free-{seed}", seed, scene=scene)
        for name, twin in twins.items():
            false[name] += len(watch(twin, log, thresholds[name]).alarms)
    for name in twins:
        found[name]["false alarms"] = (false[name], runs * LOG_S / 3600)
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--variants", type=int, default=2)
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--fault-free-hours", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/shadow_calibrated"))
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    nominal = ShadowTwin(HEAVY)
    cell = "median delay (s), missed, isolated (or beside; else named)"
    print(f"| variant | class | nominal: {cell} | calibrated: {cell} |")
    print("| --- | --- | --- | --- |")
    for v in range(1, args.variants + 1):
        folder = args.out / f"variant_{v:02d}"
        folder.mkdir(parents=True, exist_ok=True)
        calibrated, scene = calibrate(folder, rng)
        found = study(folder, scene, {"nominal": nominal, "calibrated": ShadowTwin(calibrated)}, args.seeds,
                      args.fault_free_hours)
        for label in found["nominal"]:
            cells = []
            for name in ("nominal", "calibrated"):
                if label == "false alarms":
                    count, hours = found[name][label]
                    cells.append(f"{count} over {hours:.1f} h")
                else:
                    median, missed, isolated, or_beside, named_else = found[name][label]
                    otherwise = "; ".join(f"{n} {what}" for what, n in named_else.most_common())
                    cells.append(f"{median:.0f}, {missed}, {100 * isolated:.0f} %"
                                 + (f" ({100 * or_beside:.0f} %)" if or_beside > isolated else "")
                                 + (f" (else {otherwise})" if otherwise else ""))
            print(f"| {v} | {label} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main()
