"""Where a batch's locksteps run: worker processes on this machine, or a Dask cluster.

A task is one lockstep: runs that share a `lockstep_key`, simulated together by
`execute_lockstep`. Workers only compute; the batch process alone publishes into DIR. A local
worker writes each run directory into a scratch folder inside DIR and hands back its path (a
rename publishes it); a Dask worker, perhaps on another machine, sends the files' bytes.
"""

from __future__ import annotations

import concurrent.futures
import json
import multiprocessing
import os
import queue
import shutil
import signal
import tempfile
import threading
import traceback
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bwr_twin.batch.report import Status
from bwr_twin.config.sweep import PlannedRun
from bwr_twin.errors import BwrError
from bwr_twin.ownership import mark, record_folder
from bwr_twin.results.rundir import SCENE_FILE, write_run
from bwr_twin.sim.lockstep import simulate_lockstep

ERROR_FILE = "error.txt"
CONNECT_TIMEOUT_S = 10.0  # s to reach a Dask scheduler
PARENT_POLL_S = 0.5  # s between a local worker's checks that its batch is still alive


@dataclass(frozen=True)
class Outcome:
    """What a worker sends back for one run: its run directory, or why there is none."""

    run_id: str
    status: Status  # "ok", "failed" (the run's own failure) or "not run" (its worker was lost)
    error: str  # one line
    metrics: dict | None
    folder: str | None = None  # a finished run directory on this machine, to be renamed into DIR
    files: dict[str, bytes] = field(default_factory=dict)  # or its files' contents


_progress_queue: Any = None  # in a local worker: where it reports how far its lockstep is


def execute_lockstep(runs: Sequence[PlannedRun], *, plots: bool, scratch: str | None, task: int = 0,
                     files: bool = True) -> list[Outcome]:
    """Simulate the runs of one lockstep and write their run directories. Runs in a worker.

    With `scratch` (a folder on the batch's machine) each run directory is left there and its
    path returned; without, its files come back as bytes; with `files` false, only the metrics
    come back (a tuner's candidates). A local worker reports (task, share of the path simulated)
    as it goes.
    """
    queue_ = _progress_queue
    report = None if queue_ is None else (lambda done, total: queue_.put((task, done / total)))
    try:
        results: list = simulate_lockstep([run.scene for run in runs], progress=report, nthread=1)
    except BwrError as exc:  # the path or a model: every run of the lockstep fails alike
        results = [exc] * len(runs)
    except Exception as exc:  # noqa: BLE001 - a bug, not bad input: record it with its traceback
        results = [RuntimeError(f"{type(exc).__name__}: {exc}\n\n{traceback.format_exc()}")] * len(runs)
    if not files:
        return [Outcome(run.run_id, "failed", str(result).splitlines()[0], None) if isinstance(result, Exception)
                else Outcome(run.run_id, "ok", "", result.metrics) for run, result in zip(runs, results)]
    return [_outcome_of(run, result, plots=plots, scratch=scratch) for run, result in zip(runs, results)]


def _outcome_of(run: PlannedRun, result: Any, *, plots: bool, scratch: str | None) -> Outcome:
    staging = Path(tempfile.mkdtemp(prefix=".run.partial-", dir=scratch))
    folder = staging / run.run_id
    try:
        if isinstance(result, Exception):
            report = f"{result}\n"
            folder.mkdir()
            mark(folder, "run")
            (folder / ERROR_FILE).write_text(report)
            (folder / SCENE_FILE).write_text(json.dumps(run.scene.to_dict(), indent=2) + "\n")
            record_folder(folder)
            status, error, metrics = "failed", report.splitlines()[0], None
        else:
            metrics = write_run(result, folder, plots=plots)
            status, error = "ok", ""
        if scratch is not None:
            return Outcome(run.run_id, status, error, metrics, folder=str(folder))
        files = {path.name: path.read_bytes() for path in sorted(folder.iterdir())}
        shutil.rmtree(staging)
        return Outcome(run.run_id, status, error, metrics, files=files)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def not_run(runs: Sequence[PlannedRun], exc: BaseException) -> list[Outcome]:
    """Outcomes of runs whose worker was lost: a re-run does them."""
    error = f"{type(exc).__name__}: {exc}".splitlines()[0]
    return [Outcome(run.run_id, "not run", error, None) for run in runs]


class LocalPool:
    """Worker processes on this machine, started once and kept for every lockstep (spawned, not
    forked: MuJoCo and threads do not survive a fork reliably). A worker whose batch dies
    (kill -9) notices within PARENT_POLL_S and exits, so none is left behind."""

    def __init__(self, workers: int, out_dir: Path):
        self.workers = workers
        self._out_dir = out_dir

    def __enter__(self) -> LocalPool:
        # Workers stage their runs in DIR, so that a killed batch's debris is found and removed.
        self._scratch = tempfile.mkdtemp(prefix=".scratch.partial-", dir=self._out_dir)
        context = multiprocessing.get_context("spawn")
        self._progress = context.Queue()
        self._pool = concurrent.futures.ProcessPoolExecutor(
            self.workers, mp_context=context, initializer=_start_worker, initargs=(os.getpid(), self._progress)
        )
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        if exc_type is not None:  # interrupted: stop the runs in progress rather than wait
            for child in multiprocessing.active_children():  # the pool's workers: the batch has no others
                child.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)
        self._progress.close()
        shutil.rmtree(self._scratch, ignore_errors=True)

    def outcomes(self, locksteps: Sequence[Sequence[PlannedRun]], *, plots: bool,
                 on_progress: Any = None, files: bool = True) -> Iterator[tuple[int, list[Outcome]]]:
        """(index, outcomes) of each lockstep as it completes; `on_progress(index, share)` hears
        how far the running ones are. Without `files`, only metrics (execute_lockstep)."""
        futures = {
            self._pool.submit(execute_lockstep, runs, plots=plots, scratch=self._scratch, task=task,
                              files=files): task
            for task, runs in enumerate(locksteps)
        }
        pending = set(futures)
        while pending:
            done, pending = concurrent.futures.wait(pending, timeout=0.2,
                                                    return_when=concurrent.futures.FIRST_COMPLETED)
            self._drain(on_progress)
            for future in done:
                task = futures.pop(future)
                try:
                    yield task, future.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker: its runs are left to a re-run
                    yield task, not_run(locksteps[task], exc)

    def _drain(self, on_progress: Any) -> None:
        while True:
            try:
                task, share = self._progress.get_nowait()
            except (queue.Empty, OSError, ValueError):
                return
            if on_progress is not None:
                on_progress(task, share)


def _start_worker(batch_pid: int, progress: Any) -> None:
    """Leave Ctrl-C to the batch process, which stops the workers itself, report progress to
    it, and exit if it dies."""
    global _progress_queue
    _progress_queue = progress
    signal.signal(signal.SIGINT, signal.SIG_IGN)

    def watch() -> None:
        while os.getppid() == batch_pid:
            threading.Event().wait(PARENT_POLL_S)
        os._exit(1)  # orphaned: nobody will read the results

    threading.Thread(target=watch, daemon=True, name="batch-watch").start()


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
        self.workers = max(1, sum(self._client.nthreads().values()))
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *_: object) -> None:
        if exc_type is not None and self._futures:
            self._client.cancel(self._futures)  # runs already started finish on their worker, unused
        self._client.close()

    def outcomes(self, locksteps: Sequence[Sequence[PlannedRun]], *, plots: bool,
                 on_progress: Any = None, files: bool = True) -> Iterator[tuple[int, list[Outcome]]]:
        """(index, outcomes) of each lockstep as it completes. Without `files`, only metrics."""
        from distributed import as_completed

        batch = uuid.uuid4().hex[:8]  # keys must not collide with an earlier batch's on the scheduler
        futures = {}
        for task, runs in enumerate(locksteps):
            key = f"bwr_twin-{runs[0].run_id}-{len(runs)}-{batch}"
            futures[self._client.submit(execute_lockstep, runs, plots=plots, scratch=None, task=task,
                                        files=files, key=key)] = task
        self._futures = list(futures)
        for future in as_completed(futures):
            task = futures.pop(future)
            try:
                yield task, future.result()
            except Exception as exc:  # noqa: BLE001 - a lost worker: its runs are left to a re-run
                yield task, not_run(locksteps[task], exc)
            future.release()
