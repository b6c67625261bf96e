"""The anti-collision interlock on random two-machine scenarios (docs/anticollision.md): the same
drawn scenarios with and without the built-in interlock, on the batch engine, and the collisions
and least clearances of each, per fault class.

    python tools/anticollision_sweep.py [--schedules 834] [--seed 1] [--out out/anticollision]
                                        [--workers N | --scheduler tcp://HOST:PORT]

834 schedules x 3 paths x 2 report delays x 2 fault classes = 10,008 scenarios a side. The
sweep files and every run's directory go under --out; running the command again resumes it.
"""

from __future__ import annotations

import argparse
import csv
import time
from collections import defaultdict
from pathlib import Path

from bwr_twin.batch.cli import main as batch
from bwr_twin.batch.report import SUMMARY_FILE
from bwr_twin.collision.scenarios import write_sweeps
from bwr_twin.config.sweep import load_sweep


def summary(out_dir: Path) -> list[dict]:
    with open(out_dir / SUMMARY_FILE, newline="") as f:
        return list(csv.DictReader(f))


def fault_class(row: dict) -> str:
    late = float(row["neighbour.report_delay"]) > 0.5
    stuck = row["faults"] != "[]"
    return {(False, False): "none", (True, False): "report 2 s late", (False, True): "slew encoder stuck 10 s",
            (True, True): "late report and stuck encoder"}[late, stuck]


def table(rows: list[dict], stop: float | None) -> None:
    groups: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        groups[fault_class(row)].append(row)
    print("| faults | scenarios | with contacts | contacts | least clearance between the machines |"
          + (" below the stop zone |" if stop else "") + "\n| --- | --- | --- | --- | --- |" + (" --- |" if stop else ""))
    for name, members in [*groups.items(), ("all", rows)]:
        done = [r for r in members if r["status"] == "ok"]
        contacts = [int(r["collision.contacts"]) for r in done]
        least = [float(r["collision.neighbour_clearance_min_m"]) for r in done]
        below = f" {sum(v < stop for v in least)} |" if stop else ""
        print(f"| {name} | {len(done)} of {len(members)} | {sum(c > 0 for c in contacts)} | {sum(contacts)} | "
              f"{min(least):.2f} m |{below}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--schedules", type=int, default=834)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", type=Path, default=Path("out/anticollision"))
    parser.add_argument("--only", choices=("with", "without"), help="run one side alone")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument("--workers", type=int)
    engine.add_argument("--scheduler")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    sweeps = write_sweeps(args.out, args.schedules, args.seed)
    engine = ["--workers", str(args.workers)] if args.workers else ["--scheduler", args.scheduler] if args.scheduler else []
    for path, side, label in zip(sweeps, ("without", "with"), ("without the interlock", "with the built-in interlock")):
        if args.only not in (None, side):
            continue
        out_dir = args.out / path.stem
        started = time.perf_counter()
        status = batch([str(path), "--out", str(out_dir), "--force", *engine])
        if status not in (0, 1):  # 1: some runs failed, which the table counts
            raise SystemExit(status)
        wall = time.perf_counter() - started
        lock = load_sweep(path, max_runs=None).runs[0].scene.interlock
        print(f"\n## {label}: {wall / 60:.1f} min wall\n")
        table(summary(out_dir), lock.stop if lock else None)


if __name__ == "__main__":
    main()
