"""Run every scene of a sweep file in locksteps, on local worker processes or a Dask cluster,
resumably.

    python -m bwr_twin.batch sweeps/paper_monte_carlo --out out/mc
    python -m bwr_twin.batch SWEEP --out DIR [--workers N | --scheduler tcp://HOST:PORT]
                             [--chunk RUNS] [--plots] [--retry-failed] [--force]

SWEEP is a sweep file, or the name of a shipped one (scenes/sweeps/).

Runs that share a machine, path, rule base and timing advance together in locksteps of up to
`--chunk` runs (default: the runs spread evenly over the workers, at most 128 a lockstep, which
keeps a lockstep's records of a 700 s reclaim within about 300 MB). A run's results do not
depend on the lockstep it ran in.

DIR/<run id>/ holds exactly what `python -m bwr_twin.run` writes (with `--plots`, its figures
too), or error.txt and scene.json for a run that failed. DIR/summary.csv has one row per run:
the varied values, the status, the error and the metrics. DIR/plots/ has the error distributions
and, for a 2-D grid, heat maps (bwr_twin.batch.report, as is the spread printed at the end).

Nothing is lost. Workers only compute; this process alone publishes into DIR, under a lock, and
every run directory and file appears complete or not at all (written under a temporary name,
then renamed). Re-running the same command skips the runs already done and first removes what
an interrupted batch left behind. Exit status: 0 every run succeeded, 1 some failed or could not
run, 2 bad input or DIR in use (nothing run), 130 interrupted.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import shutil
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bwr_twin.arguments import CommandParser
from bwr_twin.batch.engines import ERROR_FILE, DaskCluster, LocalPool, Outcome
from bwr_twin.batch.report import PLOTS_DIR, SUMMARY_FILE, RunRecord, spread_table, write_plots, write_summary
from bwr_twin.config.sweep import MAX_RUNS, PlannedRun, Sweep, load_sweep
from bwr_twin.errors import BwrError
from bwr_twin.ownership import BATCH_LOCK_FILE, check_output, check_resumed, mark, marker
from bwr_twin.results.rundir import METRICS_FILE, SCENE_FILE, publish_directory, staged_directory
from bwr_twin.shipped import find_scene
from bwr_twin.sim.budget import FORCE_HELP, check_estimate, estimate
from bwr_twin.sim.lockstep import lockstep_key

STAGING_PATTERNS = (".*.partial-*", ".*.old-*")  # temporary names; staged_directory's too
SUMMARY_EVERY_S = 2.0  # s between rewrites of summary.csv while runs complete
MAX_CHUNK = 128  # runs a lockstep by default: 700 s records of 128 runs take about 300 MB
REPAIRS = (METRICS_FILE,)  # a run directory's file whose damage a batch repairs by running it again


class BatchLock:
    """An exclusive flock on DIR/.lock for the batch's life; the kernel drops it if we die."""

    def __init__(self, out_dir: Path):
        self.path = out_dir / BATCH_LOCK_FILE

    def __enter__(self) -> BatchLock:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise BwrError(f"{self.path.parent}: cannot create it: {exc.strerror}") from None
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.read(fd, 32).decode(errors="replace").strip() or "unknown"
                os.close(fd)
                raise BwrError(f"{self.path.parent} is in use by another batch (pid {holder})") from None
            # A batch that just finished unlinks the file; a lock on its old inode guards nothing.
            try:
                if os.stat(self.path).st_ino == os.fstat(fd).st_ino:
                    break
            except FileNotFoundError:
                pass
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._fd = fd
        return self

    def __exit__(self, *_: object) -> None:
        self.path.unlink(missing_ok=True)  # while still holding it, so no one locks a doomed file
        os.close(self._fd)


def plan_locksteps(runs: Sequence[PlannedRun], *, workers: int, chunk: int | None) -> list[list[PlannedRun]]:
    """Group runs by lockstep key, in sweep order, and cut each group into locksteps of at most
    `chunk` runs (None: spread evenly over `workers`, at most MAX_CHUNK)."""
    groups: dict[tuple, list[PlannedRun]] = {}
    for run in runs:
        groups.setdefault(lockstep_key(run.scene), []).append(run)
    locksteps = []
    for group in groups.values():
        size = chunk or min(MAX_CHUNK, math.ceil(len(group) / workers))
        count = math.ceil(len(group) / size)
        size = math.ceil(len(group) / count)  # even locksteps: 100 runs in 128s make one, in 60s two of 50
        locksteps += [group[i : i + size] for i in range(0, len(group), size)]
    return locksteps


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt  # `kill` stops a batch as cleanly as Ctrl-C


def remove_debris(out_dir: Path) -> None:
    """Remove what an interrupted batch left: staging directories and half-written files."""
    for folder in (out_dir, out_dir / PLOTS_DIR):
        for pattern in STAGING_PATTERNS:
            for path in folder.glob(pattern):
                if path.is_dir():
                    shutil.rmtree(path)
                else:
                    path.unlink()


def existing_record(out_dir: Path, run: PlannedRun) -> RunRecord | None:
    """The record of a run already done in DIR, after checking it was done with these settings."""
    folder = out_dir / run.run_id
    if not folder.is_dir():
        return None
    try:
        recorded = json.loads((folder / SCENE_FILE).read_text())
    except (OSError, ValueError):
        raise BwrError(f"{folder}: not a run directory (no readable {SCENE_FILE}); "
                       "move it away or choose another --out") from None
    planned = json.loads(json.dumps(run.scene.to_dict()))
    if recorded != planned:
        keys = ", ".join(_differences(recorded, planned)[:3])
        raise BwrError(f"{folder}: was run with other settings ({keys}) than this sweep plans; "
                       "choose another --out")
    if (folder / ERROR_FILE).is_file():
        lines = (folder / ERROR_FILE).read_text(errors="replace").splitlines()
        return RunRecord("failed", lines[0] if lines else "no error recorded")
    try:
        metrics = json.loads((folder / METRICS_FILE).read_text())
        if not isinstance(metrics, dict):
            raise ValueError("not an object")
    except (OSError, ValueError):  # damaged after the batch wrote it: the run is done again
        return RunRecord("pending", f"{METRICS_FILE} missing or unreadable")
    return RunRecord("ok", metrics=metrics)


def _differences(recorded: Any, planned: Any, where: str = "") -> list[str]:
    """Dotted keys whose values differ between two scene dictionaries."""
    if isinstance(recorded, dict) and isinstance(planned, dict):
        differences = []
        for key in sorted(set(recorded) | set(planned)):
            dotted = f"{where}.{key}" if where else key
            differences += _differences(recorded.get(key), planned.get(key), dotted)
        return differences
    return [] if recorded == planned else [where or "scene"]


def run_batch(sweep: Sweep, out_dir: Path, *, workers: int | None, scheduler: str | None, plots: bool,
              retry_failed: bool, chunk: int | None = None, force: bool = False) -> int:
    """Run what is not done yet and summarise; the caller holds the lock. Returns the exit status."""
    started = time.perf_counter()
    records = {run.run_id: existing_record(out_dir, run) or RunRecord("pending") for run in sweep.runs}
    check_sweep_owns(out_dir, sweep)  # after the records: a run done differently is named first
    check_resumed(out_dir)
    remove_debris(out_dir)
    todo = [run for run in sweep.runs if records[run.run_id].status == "pending"
            or (retry_failed and records[run.run_id].status == "failed")]
    # Run directories to replace: failed ones retried, and damaged ones (pending with a reason).
    replace = {run.run_id for run in todo if records[run.run_id].error}
    for run_id in sorted(replace):  # each holds only what the twin wrote, before anything runs
        check_output(out_dir / run_id, "run", overwrite=True, repairs=REPAIRS)
    damaged = [run.run_id for run in todo if run.run_id in replace and records[run.run_id].status == "pending"]
    if damaged:
        print(f"note: {len(damaged)} run directories in {out_dir} have no readable {METRICS_FILE} "
              f"({damaged[0]}{', ...' if len(damaged) > 1 else ''}); running them again", file=sys.stderr)
        for run_id in damaged:
            records[run_id] = RunRecord("pending")
    local_workers = min(workers or os.cpu_count() or 1, max(1, len(todo)))  # no more workers than runs
    engine = DaskCluster(scheduler) if scheduler else LocalPool(local_workers, out_dir)
    last_summary = time.monotonic()
    try:
        if todo:
            with engine, _progress_bar(len(todo), sweep) as bar:  # nothing is written if it cannot start
                locksteps = plan_locksteps(todo, workers=engine.workers, chunk=chunk)
                cost = estimate([run.scene for run in todo], workers=engine.workers,
                                chunk=max(map(len, locksteps)), plots=plots, force=force)
                check_estimate(cost, where=sweep.path, out_dir=out_dir, force=force)
                claim(out_dir, sweep)
                write_summary(out_dir, sweep, records)
                shares = [0.0] * len(locksteps)

                def on_progress(task: int, share: float) -> None:
                    shares[task] = share
                    bar.update(sum(s * len(runs) for s, runs in zip(shares, locksteps)) - bar.n)

                for task, outcomes in engine.outcomes(locksteps, plots=plots, on_progress=on_progress):
                    for outcome in outcomes:
                        _publish(out_dir, outcome, replace=outcome.run_id in replace)
                        records[outcome.run_id] = RunRecord(outcome.status, outcome.error, outcome.metrics)
                        if outcome.status != "ok":
                            bar.write(f"{outcome.status}: {outcome.run_id}: {outcome.error}", file=sys.stderr)
                    on_progress(task, 1.0)
                    if time.monotonic() - last_summary >= SUMMARY_EVERY_S:
                        write_summary(out_dir, sweep, records)
                        last_summary = time.monotonic()
    except KeyboardInterrupt:
        if marker(out_dir) is not None:  # not before the batch has started
            write_summary(out_dir, sweep, records)
        done = sum(record.status in ("ok", "failed") for record in records.values())
        print(f"interrupted: {done} of {len(sweep.runs)} runs complete and kept; "
              "run the same command to finish", file=sys.stderr)
        return 130
    write_summary(out_dir, sweep, records)
    write_plots(out_dir, sweep, records)
    counts = {status: sum(record.status == status for record in records.values())
              for status in ("ok", "failed", "not run")}
    print(spread_table(sweep, records))
    elapsed = time.perf_counter() - started
    print(f"{sweep.path.name}: {len(sweep.runs)} runs, {counts['ok']} ok, {counts['failed']} failed, "
          f"{counts['not run']} not run ({len(sweep.runs) - len(todo)} already done, skipped) in "
          f"{elapsed:.1f} s; summary in {out_dir / SUMMARY_FILE}")
    return 0 if counts["ok"] == len(sweep.runs) else 1


def _publish(out_dir: Path, outcome: Outcome, *, replace: bool) -> None:
    """Move a finished run directory into DIR (a rename), or write it there from its files."""
    if outcome.folder is not None:
        target = out_dir / outcome.run_id
        if replace or not target.exists():
            publish_directory(Path(outcome.folder), target)
        return
    if outcome.files:
        with staged_directory(out_dir / outcome.run_id, overwrite=replace, repairs=REPAIRS) as staging:
            for name, content in outcome.files.items():
                (staging / name).write_bytes(content)


def check_sweep_owns(out_dir: Path, sweep: Sweep) -> None:
    """Refuse a DIR that holds another sweep's results: re-running the same sweep resumes it."""
    found = marker(out_dir)
    if found is not None and found.get("plan") != sweep.digest():
        raise BwrError(f"{out_dir}: holds the results of another sweep ({found.get('sweep')}, "
                       f"{found.get('runs')} runs) than {sweep.path.name} plans; choose another --out")


def claim(out_dir: Path, sweep: Sweep) -> None:
    """Mark DIR as this sweep's results, once, before its first result lands."""
    if marker(out_dir) is None:
        mark(out_dir, "batch", sweep=sweep.path.name, runs=len(sweep.runs), plan=sweep.digest())


def _progress_bar(total: int, sweep: Sweep) -> tqdm:
    """Runs done (fractions while a lockstep runs) and time left, on a terminal only."""
    return tqdm(total=total, desc=sweep.path.stem, unit="run", file=sys.stderr,
                bar_format="{l_bar}{bar}| {n:.1f}/{total} runs [{elapsed}<{remaining}]",
                disable=not sys.stderr.isatty())


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.batch", description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep TOML file, or a shipped sweep's name, e.g. sweeps/paper_monte_carlo")
    parser.add_argument("--out", required=True, type=Path, help="output directory; re-running resumes it")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    engine.add_argument("--scheduler", help="run on a Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--chunk", type=int, help=f"runs per lockstep (default: spread over the workers, "
                        f"at most {MAX_CHUNK})")
    plots = parser.add_mutually_exclusive_group()
    plots.add_argument("--plots", action="store_true", help="write each run's PNG figures (about 3 s a run)")
    plots.add_argument("--no-plots", action="store_true", help="no per-run figures (the default)")
    parser.add_argument("--retry-failed", action="store_true", help="run the runs that failed before again")
    parser.add_argument("--force", action="store_true", help=f"{FORCE_HELP}, or the sweep {MAX_RUNS} runs")
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error("--workers must be at least 1")
    if args.chunk is not None and args.chunk < 1:
        parser.error("--chunk must be at least 1")
    signal.signal(signal.SIGTERM, _interrupt)
    created = not args.out.exists()
    try:
        sweep = load_sweep(find_scene(args.sweep), max_runs=None if args.force else MAX_RUNS)
        inputs = {sweep.path, *(file for run in sweep.runs for file in run.scene.input_files)}
        check_output(args.out, "batch", inputs=inputs)
        with BatchLock(args.out):
            return run_batch(sweep, args.out, workers=args.workers, scheduler=args.scheduler,
                             plots=args.plots, retry_failed=args.retry_failed, chunk=args.chunk,
                             force=args.force)
    except (BwrError, OSError) as exc:  # OSError: DIR unwritable or full
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: run the same command to resume", file=sys.stderr)
        return 130
    finally:
        if created:  # a batch that wrote nothing leaves no folder behind
            with contextlib.suppress(OSError):
                args.out.rmdir()
