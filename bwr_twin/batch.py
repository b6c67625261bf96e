"""Run every scene of a sweep file, on a local process pool or a Dask cluster, resumably.

    python -m bwr_twin.batch scenes/sweeps/paper_monte_carlo.toml --out out/mc
    python -m bwr_twin.batch SWEEP --out DIR [--workers N | --scheduler tcp://HOST:PORT]
                             [--no-plots] [--retry-failed]

DIR/<run id>/ holds exactly what `python -m bwr_twin.run` writes, or error.txt and scene.json
for a run that failed. DIR/summary.csv has one row per run: the varied values, the status, the
error and the metrics. DIR/plots/ has the error distributions and, for a 2-D grid, heat maps
(both from bwr_twin.batch_report, as is the spread of the errors printed at the end).

Nothing is lost. Workers only compute; this process alone writes into DIR, under a lock, and
every run directory and file appears complete or not at all (written under a temporary name,
then renamed). Re-running the same command skips the runs already done and first removes what
an interrupted batch left behind. Exit status: 0 every run succeeded, 1 some failed or could not
run, 2 bad input or DIR in use (nothing run), 130 interrupted.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import fcntl
import json
import multiprocessing
import os
import shutil
import signal
import sys
import tempfile
import time
import traceback
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

from bwr_twin.batch_report import (
    PLOTS_DIR,
    SUMMARY_FILE,
    RunRecord,
    Status,
    spread_table,
    write_plots,
    write_summary,
)
from bwr_twin.errors import BwrError
from bwr_twin.results import METRICS_FILE, SCENE_FILE, staged_directory, write_run
from bwr_twin.simulate import simulate
from bwr_twin.sweep import PlannedRun, Sweep, load_sweep

ERROR_FILE = "error.txt"
LOCK_FILE = ".lock"
STAGING_PATTERNS = (".*.partial-*", ".*.old-*")  # temporary names; staged_directory's too
SUMMARY_EVERY_S = 2.0  # s between rewrites of summary.csv while runs complete
CONNECT_TIMEOUT_S = 10.0  # s to reach a Dask scheduler


@dataclass(frozen=True)
class Outcome:
    """What a worker sends back: the run directory's files, or why there are none."""

    run_id: str
    status: Status  # "ok", "failed" (the run's own failure) or "not run" (its worker was lost)
    error: str  # one line
    files: dict[str, bytes]  # name -> content of the run directory; empty if not run
    metrics: dict | None


def execute_run(run: PlannedRun, *, plots: bool, scratch: str | None) -> Outcome:
    """Simulate one run and return its files. Runs in a worker; never touches the batch's DIR."""
    try:
        result = simulate(run.scene)
        with tempfile.TemporaryDirectory(prefix=".run.partial-", dir=scratch) as tmp:
            folder = Path(tmp) / run.run_id
            metrics = write_run(result, folder, plots=plots)
            files = {path.name: path.read_bytes() for path in sorted(folder.iterdir())}
        return Outcome(run.run_id, "ok", "", files, metrics)
    except BwrError as exc:
        error, report = str(exc), f"{exc}\n"
    except Exception as exc:  # noqa: BLE001 - a bug, not bad input: record it with its traceback
        error = f"{type(exc).__name__}: {exc}"
        report = f"{error}\n\n{traceback.format_exc()}"
    scene = json.dumps(run.scene.to_dict(), indent=2) + "\n"
    files = {ERROR_FILE: report.encode(), SCENE_FILE: scene.encode()}
    return Outcome(run.run_id, "failed", error.splitlines()[0] if error else "", files, None)


class BatchLock:
    """An exclusive flock on DIR/.lock for the batch's life; the kernel drops it if we die."""

    def __init__(self, out_dir: Path):
        self.path = out_dir / LOCK_FILE

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


class LocalPool:
    """Worker processes on this machine, started once and kept for every run (spawned, not
    forked: MuJoCo and threads do not survive a fork reliably)."""

    def __init__(self, workers: int, out_dir: Path):
        self._workers = workers
        self._out_dir = out_dir

    def __enter__(self) -> LocalPool:
        # Workers stage their files in DIR, so that a killed batch's debris is found and removed.
        self._scratch = tempfile.mkdtemp(prefix=".scratch.partial-", dir=self._out_dir)
        self._pool = concurrent.futures.ProcessPoolExecutor(
            self._workers, mp_context=multiprocessing.get_context("spawn"), initializer=_ignore_interrupts
        )
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        if exc_type is not None:  # interrupted: stop the runs in progress rather than wait
            for child in multiprocessing.active_children():  # the pool's workers: the batch has no others
                child.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)
        shutil.rmtree(self._scratch, ignore_errors=True)

    def outcomes(self, runs: list[PlannedRun], *, plots: bool) -> Iterator[Outcome]:
        futures = {
            self._pool.submit(execute_run, run, plots=plots, scratch=self._scratch): run for run in runs
        }
        for future in concurrent.futures.as_completed(futures):
            yield _outcome(future, futures.pop(future))


class DaskCluster:
    """The workers of a running Dask scheduler. They need bwr_twin installed and the scene's
    files at the same paths; results come back to this process, so DIR may be local."""

    def __init__(self, address: str):
        self._address = address
        self._futures: list = []

    def __enter__(self) -> DaskCluster:
        from distributed import Client

        try:
            self._client = Client(self._address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise BwrError(f"cannot reach the Dask scheduler at {self._address}: {exc}") from None
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        if exc_type is not None and self._futures:
            self._client.cancel(self._futures)  # runs already started finish on their worker, unused
        self._client.close()

    def outcomes(self, runs: list[PlannedRun], *, plots: bool) -> Iterator[Outcome]:
        from distributed import as_completed

        batch = uuid.uuid4().hex[:8]  # keys must not collide with an earlier batch's on the scheduler
        futures = {}
        for run in runs:
            key = f"bwr_twin-{run.run_id}-{batch}"
            futures[self._client.submit(execute_run, run, plots=plots, scratch=None, key=key)] = run
        self._futures = list(futures)
        for future in as_completed(futures):
            yield _outcome(future, futures.pop(future))
            future.release()


def _outcome(future: Any, run: PlannedRun) -> Outcome:
    """The worker's outcome, or "not run" if the machinery failed (a worker died, say)."""
    try:
        return future.result()
    except Exception as exc:  # noqa: BLE001 - any failure of the machinery leaves the run to a re-run
        return Outcome(run.run_id, "not run", f"{type(exc).__name__}: {exc}".splitlines()[0], {}, None)


def _ignore_interrupts() -> None:
    """Workers leave Ctrl-C to the batch process, which stops them itself."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


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
    if (folder / METRICS_FILE).is_file():
        return RunRecord("ok", metrics=json.loads((folder / METRICS_FILE).read_text()))
    lines = (folder / ERROR_FILE).read_text().splitlines() if (folder / ERROR_FILE).is_file() else []
    return RunRecord("failed", lines[0] if lines else "no error recorded")


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
              retry_failed: bool) -> int:
    """Run what is not done yet and summarise; the caller holds the lock. Returns the exit status."""
    started = time.perf_counter()
    remove_debris(out_dir)
    records = {run.run_id: existing_record(out_dir, run) or RunRecord("pending") for run in sweep.runs}
    todo = [run for run in sweep.runs if records[run.run_id].status == "pending"
            or (retry_failed and records[run.run_id].status == "failed")]
    _note_foreign_runs(out_dir, sweep)
    write_summary(out_dir, sweep, records)
    local_workers = min(workers or os.cpu_count() or 1, max(1, len(todo)))  # no more workers than runs
    engine = DaskCluster(scheduler) if scheduler else LocalPool(local_workers, out_dir)
    last_summary = time.monotonic()
    try:
        if todo:
            with engine, _progress_bar(len(todo), sweep) as bar:
                for outcome in engine.outcomes(todo, plots=plots):
                    if outcome.files:
                        _publish(out_dir, outcome, replace=retry_failed)
                    records[outcome.run_id] = RunRecord(outcome.status, outcome.error, outcome.metrics)
                    if outcome.status != "ok":
                        bar.write(f"{outcome.status}: {outcome.run_id}: {outcome.error}", file=sys.stderr)
                    bar.update()
                    if time.monotonic() - last_summary >= SUMMARY_EVERY_S:
                        write_summary(out_dir, sweep, records)
                        last_summary = time.monotonic()
    except KeyboardInterrupt:
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
    print(f"{sweep.path.name}: {len(sweep.runs)} runs, {counts['ok']} ok, {counts['failed']} failed, "
          f"{counts['not run']} not run ({len(sweep.runs) - len(todo)} already done, skipped) in "
          f"{time.perf_counter() - started:.1f} s; summary in {out_dir / SUMMARY_FILE}")
    return 0 if counts["ok"] == len(sweep.runs) else 1


def _publish(out_dir: Path, outcome: Outcome, *, replace: bool) -> None:
    with staged_directory(out_dir / outcome.run_id, overwrite=replace) as staging:
        for name, content in outcome.files.items():
            (staging / name).write_bytes(content)


def _note_foreign_runs(out_dir: Path, sweep: Sweep) -> None:
    planned = {run.run_id for run in sweep.runs}
    foreign = [p for p in out_dir.iterdir() if p.is_dir() and p.name[:1].isdigit() and p.name not in planned]
    if foreign:
        print(f"note: {len(foreign)} run directories in {out_dir} are not in this sweep; "
              "left alone, not summarised", file=sys.stderr)


def _progress_bar(total: int, sweep: Sweep) -> tqdm:
    """Runs done and time left, on a terminal only."""
    return tqdm(total=total, desc=sweep.path.stem, unit="run", file=sys.stderr,
                disable=not sys.stderr.isatty())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bwr_twin.batch", description=__doc__.split("\n\n")[0])
    parser.add_argument("sweep", help="sweep TOML file, e.g. scenes/sweeps/paper_monte_carlo.toml")
    parser.add_argument("--out", required=True, type=Path, help="output directory; re-running resumes it")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    engine.add_argument("--scheduler", help="run on a Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--no-plots", action="store_true",
                        help="skip each run's PNG figures (the batch's own plots stay)")
    parser.add_argument("--retry-failed", action="store_true", help="run the runs that failed before again")
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error("--workers must be at least 1")
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        sweep = load_sweep(args.sweep)
        with BatchLock(args.out):
            return run_batch(sweep, args.out, workers=args.workers, scheduler=args.scheduler,
                             plots=not args.no_plots, retry_failed=args.retry_failed)
    except (BwrError, OSError) as exc:  # OSError: DIR unwritable or full
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: run the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    # Through the package, not as __main__, so workers can import what they are sent by name.
    from bwr_twin.batch import main as package_main

    sys.exit(package_main())
