"""The shadow's targets (docs/shadow.md): detection delay, isolation and false alarms per fault
class, over seeds, on the heavy machine of scenes/heavy_shadow.toml; and its speed over a log.

    python tools/shadow_study.py [--seeds 20] [--fault-free-hours 50] [--learn-hours 1] [--out out/shadow_study]

Thresholds are learned from --learn-hours of fault-free logs (seeds 1000 on). Per class and seed
the machine runs with the fault at an onset drawn from the seed (60 to 240 s), and the shadow
watches its log:
the delay is the first alarm's time less the onset, isolated when that alarm names the fault's
class and axis ("or beside": first, or as a fault not told apart from the first,
`Alarm.alternatives`). The sizes are the issue's: slew friction +20 %, 5 % of the wheel end's
mass (the bucket wheel and its load) caked at the CP, the travel drive derated 15 %, the travel
encoder drifting 0.1 m over a minute, the slew encoder stuck. Fault-free logs of other seeds,
--fault-free-hours of them, count the false alarms. Every run directory goes under --out.

Every log has its own weather, drawn from its seed: a mean wind of 0 to 20 m/s (about the
in-service limit of large stockyard machines, scenes/heavy_wind.toml) from any heading, gusting
by up to 5 m/s. The shadow reads the wind from the log's anemometer column; --ignore-wind
watches as a shadow without an anemometer would.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import mujoco
import numpy as np

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.results.run_files import read_timeseries
from bwr_twin.results.rundir import write_run
from bwr_twin.shadow.detect import beyond_readings
from bwr_twin.shadow.twin import BLOCK, ShadowTwin
from bwr_twin.shadow.watch import learn_from, watch
from bwr_twin.sim.lockstep import simulate

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "heavy_shadow.toml"
MJCF = ROOT / "mjcf" / "bwr_heavy.xml"
LOG_S = 300.0  # s, the scene's path
MAX_WIND, MAX_GUST = 20.0, 5.0  # m/s: the weather a log's seed draws from (the module's docstring)


def wheel_end_mass() -> float:
    """kg of the body holding the CP and its children: the bucket wheel and its load."""
    machine = Machine(MJCF)
    model, body = machine.model, int(machine.model.site_bodyid[machine.cp_site])
    return float(sum(model.body_mass[b] for b in range(model.nbody)
                     if b == body or _descends(model, b, body)))


def _descends(model: mujoco.MjModel, b: int, ancestor: int) -> bool:
    while b > 0:
        b = int(model.body_parentid[b])
        if b == ancestor:
            return True
    return False


def classes() -> dict[str, tuple[str, str, str, float | None]]:
    """class -> ([[faults]] table without start, expected class, axis, delay target s)."""
    five_percent = 0.05 * wheel_end_mass()
    return {
        "friction +20 %": ('kind = "friction_rise"\naxis = "slew"\npercent = 20.0', "friction_rise", "slew", 60.0),
        f"mass +{five_percent / 1000:.1f} t": (f'kind = "mass_change"\nmass = {five_percent:.0f}.0', "mass_change",
                                               "wheel end", 60.0),
        "derate 15 %": ('kind = "drive_derate"\naxis = "travel"\npercent = 15.0', "drive_derate", "travel", 60.0),
        "drift 0.1 m/min": ('kind = "encoder_drift"\naxis = "travel"\nrate = 0.0016667', "encoder_drift", "travel",
                            60.0),
        "stuck encoder": ('kind = "encoder_stuck"\naxis = "slew"', "stuck_encoder", "slew", 2.0),
    }


def seen_from(folder: Path, onset: float, thresholds) -> float:
    """s: when the slew, stuck since `onset`, first stood in another count of its encoder than
    the one it reads (the log's true position): the earliest any detector can tell a stuck
    encoder from a still axis."""
    series = read_timeseries(folder / "timeseries.csv")
    count = thresholds.counts[1]
    after = np.asarray(series.time) >= onset
    true, read = np.asarray(series.signals["q"])[after, 1], np.asarray(series.signals["q_measured"])[after, 1]
    apart = np.flatnonzero(np.abs(np.rint(true / count) * count - read) > 0.5 * count)
    return float(np.asarray(series.time)[after][apart[0]]) if len(apart) else float("nan")


def weather(seed: int) -> str:
    """The [plant] table of a log's wind, drawn from its seed."""
    wind, gust, heading = np.random.default_rng([seed, 1]).uniform((0.0, 0.0, 0.0), (MAX_WIND, MAX_GUST, 360.0))
    return f"[plant]\nwind_speed = {wind:.2f}\ngust_amplitude = {gust:.2f}\nwind_direction = {heading:.1f}\n"


def run(out: Path, name: str, seed: int, table: str = "", scene: Path = SCENE) -> Path:
    """The run directory of `scene` with `seed`, its weather and `table`; one kept from an
    earlier study of the same scene is used again."""
    folder, scene_file = out / name, out / f"{name}.toml"
    text = f'extends = "{scene}"\n[simulation]\nseed = {seed}\n{weather(seed)}{table}\n'
    if (folder / "timeseries.csv").is_file() and scene_file.is_file() and scene_file.read_text() == text:
        return folder
    scene_file.write_text(text)
    write_run(simulate(load_scene(scene_file), nthread=1), folder, plots=False, overwrite=folder.exists())
    return folder


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--fault-free-hours", type=float, default=50.0)
    parser.add_argument("--learn-hours", type=float, default=1.0, help="h of fault-free logs the thresholds are "
                        "learned on (default 1: an hour of the machine's usual work)")
    parser.add_argument("--ignore-wind", action="store_true", help="watch without the logs' anemometer")
    parser.add_argument("--out", type=Path, default=Path("out/shadow_study"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    twin = ShadowTwin(MJCF)
    learned_on = [run(args.out, f"baseline-{seed}", seed)
                  for seed in range(1000, 1000 + max(1, round(args.learn_hours * 3600 / LOG_S)))]
    thresholds = learn_from(twin, learned_on, 0.01, ignore_wind=args.ignore_wind)

    print("| class | seeds | median delay (s) | target | isolated (or beside) | onset within its range | sizes estimated |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    observable = []  # s from when the stuck encoder's axis first stood in another count to its alarm
    for label, (table, kind, axis, target) in classes().items():
        delays, right, beside, within, sizes = [], 0, 0, 0, []
        for seed in range(1, args.seeds + 1):
            onset = float(round(np.random.default_rng(seed).uniform(60.0, 240.0)))
            folder = run(args.out, f"{kind}-{seed}", seed, f"[[faults]]\n{table}\nstart = {onset}")
            watched = watch(twin, folder, thresholds, ignore_wind=args.ignore_wind)
            alarms = [a for a in watched.alarms if a.time_s >= onset]
            if alarms:
                delays.append(alarms[0].time_s - onset)
                if kind == "stuck_encoder":
                    observable.append(alarms[0].time_s - seen_from(folder, onset, thresholds))
                right += (alarms[0].kind, alarms[0].axis) == (kind, axis)
                beside += f"{axis} {kind}" in alarms[0].alternatives
                earliest, latest = alarms[0].onset_range_s or (alarms[0].onset_s, alarms[0].onset_s)
                within += earliest - BLOCK <= onset <= latest + BLOCK  # to the block
                sizes.append(f"{alarms[0].size:.3g} {alarms[0].unit}")
        median = f"{statistics.median(delays):.0f}" if delays else "none"
        missed = args.seeds - len(delays)
        print(f"| {label} | {args.seeds} | {median}{f' ({missed} missed)' if missed else ''} | <= {target:g} | "
              f"{100 * right / args.seeds:.0f} % ({100 * (right + beside) / args.seeds:.0f} %) | "
              f"{within} of {len(delays)} | {', '.join(sizes[:3])} |")

    if observable:
        print("\nstuck encoder, from when the slew first stood in another count than its reading: "
              f"median {statistics.median(observable):.1f} s, largest {max(observable):.1f} s")

    runs = max(1, round(args.fault_free_hours * 3600 / LOG_S))
    false_alarms, watched_s, took = 0, 0.0, 0.0
    counts = np.array([c if c is not None else np.nan for c in thresholds.counts])
    furthest = np.full(3, -np.inf)  # of a count: the stuck test's headroom on the fault-free logs
    for seed in range(2000, 2000 + runs):
        folder = run(args.out, f"fault_free-{seed}", seed)
        started = time.perf_counter()
        watched = watch(twin, folder, thresholds, ignore_wind=args.ignore_wind)
        took += time.perf_counter() - started
        false_alarms += len(watched.alarms)
        furthest = np.fmax(furthest, beyond_readings(watched.blocks, thresholds.counts) / counts)
        watched_s += float(watched.measured.time[-1] - watched.measured.time[0])
    print(f"\nfalse alarms: {false_alarms} over {watched_s / 3600:.2f} h of fault-free logs ({runs} seeds), target 0 "
          "over 50 h")
    print(f"offline speed: {watched_s:.0f} s of log in {took:.1f} s on one core = {watched_s / took:.0f}x real time "
          "(target >= 100x)")
    margins = [m / c if m is not None else np.nan for m, c in zip(thresholds.stuck_margin, counts)]
    print("stuck test: the furthest a fault-free axis went beyond where its reading allows it, "
          + ", ".join(f"{axis} {f:+.3f}" for axis, f in zip(("travel", "slew", "luff"), furthest))
          + " of a count; the margin learned, " + ", ".join(f"{m:.3f}" for m in margins))


if __name__ == "__main__":
    main()
