"""The shadow over a recorded log, at full speed: the twin beside the machine that made it.

    python -m bwr_twin.shadow --log RUN_DIR --model MJCF --baseline FAULT_FREE_RUN_DIR --out DIR
    python -m bwr_twin.shadow --log RUN_DIR --model MJCF --thresholds thresholds.json --out DIR

RUN_DIR is a run directory (or its timeseries.csv) of the machine being watched: its encoders'
positions, its drives' speed feedback and their forces (docs/shadow.md). The thresholds are
learned from a fault-free log of the same machine (--baseline), for --false-alarms-per-hour
(default 0.01), or read from a thresholds.json an earlier shadow wrote. DIR holds events.jsonl
(the alarms: class, axis, size, onset; and the gaps), residuals.csv (per block of 1 s the force,
position, speed and drift residuals per axis) and thresholds.json. DIR appears only when
complete. Bad input exits with status 2 and one line.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, exit_status

DEFAULT_PER_HOUR = 0.01  # false alarms an hour the thresholds are set for: one in 100 h of watching


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.shadow", description=__doc__.split("\n\n")[0])
    parser.add_argument("--log", required=True, type=Path, help="run directory (or timeseries.csv) to watch")
    parser.add_argument("--model", required=True, type=Path, help="the machine's MJCF the twin runs")
    learned = parser.add_mutually_exclusive_group(required=True)
    learned.add_argument("--baseline", type=Path, help="a fault-free run directory of the machine: learn the "
                         "thresholds from it")
    learned.add_argument("--thresholds", type=Path, help="thresholds.json an earlier shadow wrote")
    parser.add_argument("--false-alarms-per-hour", type=float, default=DEFAULT_PER_HOUR,
                        help=f"the false-alarm rate the thresholds are set for (1/h, default {DEFAULT_PER_HOUR})")
    parser.add_argument("--out", required=True, type=Path, help="output directory (must not exist)")
    parser.add_argument("--overwrite", action="store_true", help="replace DIR, a shadow's output, once the new "
                        "one is complete")
    args = parser.parse_args(argv)
    return exit_status(lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    from bwr_twin.ownership import check_output
    from bwr_twin.results.rundir import staged_directory
    from bwr_twin.shadow.detect import Thresholds
    from bwr_twin.shadow.twin import ShadowTwin
    from bwr_twin.shadow.watch import learn_from, watch, write_outputs

    inputs = [p for p in (args.log, args.model, args.baseline, args.thresholds) if p is not None]
    check_output(args.out, "shadow", overwrite=args.overwrite, inputs=inputs)
    if not args.model.is_file():
        raise BwrError(f"{args.model}: MJCF file not found")
    twin = ShadowTwin(args.model)
    if args.thresholds is not None:
        thresholds = Thresholds.read(args.thresholds)
    else:
        thresholds = learn_from(twin, args.baseline, args.false_alarms_per_hour)
    started = time.perf_counter()
    watched = watch(twin, args.log, thresholds)
    took = time.perf_counter() - started
    with staged_directory(args.out, overwrite=args.overwrite, kind="shadow") as staging:
        write_outputs(staging, watched, thresholds)
    span = float(watched.measured.time[-1] - watched.measured.time[0])
    print(f"{args.log}: {span:g} s of log watched in {took:.1f} s ({span / max(took, 1e-9):.0f}x real time), "
          f"{len(watched.blocks.start)} blocks, {len(watched.gaps)} gaps, {len(watched.alarms)} alarms")
    for start, end in watched.gaps:
        print(f"gap: no samples from {start:.2f} s to {end:.2f} s (nothing concluded over it)")
    for alarm in watched.alarms:
        print(f"alarm: {alarm.describe()}")
    print(f"events in {args.out}/events.jsonl")
    return 0


if __name__ == "__main__":
    sys.exit(main())
