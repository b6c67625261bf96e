"""Simulating a scene for the replay: in a child process at lower CPU priority, so that the page
is served and drawn first, with its progress reported, into a run cache.

The cache holds run directories of `bwr_twin.run` (without plots) in out/replay-cache/, keyed by
everything that decides a run (`cache_key`), so the next replay of the same scene, models and
code starts with its timeline.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import sys
import tempfile
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

from tqdm import tqdm

from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError
from bwr_twin.replay.recording import Recording, cache_key

CACHE_ROOT = Path("out") / "replay-cache"  # relative to the current folder, as `--out` paths are
SIMULATION_NICENESS = 10  # the page is drawn first; the simulation takes the CPU that is left
PILE_FRAME_PERIOD = 5.0  # s of simulated time between the pile's frames: it is seen being dug


def cached_run(scene: Scene) -> Path:
    """Where the scene's run is cached (it may not be there yet)."""
    return CACHE_ROOT / cache_key(scene)


def simulate_in_child(
    scene: Scene, *, use_cache: bool, progress: Callable[[float], None] | None = None
) -> Recording:
    """Simulate the scene in a child process at lower priority, into the cache (or a scratch
    folder), and read the run back. The share of the path simulated goes to `progress` and to a
    bar on the terminal."""
    spawn = multiprocessing.get_context("spawn")  # MuJoCo and the server's threads: no fork
    with tempfile.TemporaryDirectory() as scratch:
        run_dir = cached_run(scene) if use_cache else Path(scratch) / "run"
        reports, child_end = spawn.Pipe(duplex=False)
        child = spawn.Process(target=_simulate_into, args=(scene, str(run_dir), child_end), daemon=True)
        child.start()
        child_end.close()
        bar = tqdm(total=100, desc="simulating", unit="%", leave=False, disable=not sys.stderr.isatty())
        try:
            with contextlib.suppress(ProcessLookupError):  # a child that failed at once has gone
                os.setpriority(
                    os.PRIO_PROCESS, child.pid, os.getpriority(os.PRIO_PROCESS, 0) + SIMULATION_NICENESS
                )
            while True:
                try:
                    kind, value = reports.recv()
                except EOFError:  # it died without a word: its traceback is on stderr
                    child.join()
                    raise BwrError(f"{scene.path}: the simulation stopped (exit code {child.exitcode})") from None
                if kind == "error":
                    raise BwrError(value)
                if kind == "done":
                    break
                bar.update(round(100 * value) - bar.n)
                if progress is not None:
                    progress(value)
        finally:
            bar.close()
            if child.is_alive():
                child.terminate()
            child.join()
        return Recording.from_run_dir(run_dir)


def _simulate_into(scene: Scene, run_dir: str, reports: Connection) -> None:
    """In the child process: simulate, write the run directory (no plots) and report back
    ("progress", share done), then ("done", None) or ("error", one-line message)."""
    from bwr_twin.results.rundir import write_run  # here, not at the top: the parent never simulates
    from bwr_twin.sim.lockstep import simulate

    try:
        result = simulate(scene, progress=lambda done, total: reports.send(("progress", done / total)),
                          pile_frame_period=PILE_FRAME_PERIOD)
        write_run(result, run_dir, overwrite=True, plots=False)
        reports.send(("done", None))
    except BwrError as exc:
        reports.send(("error", str(exc)))
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group; the parent reports it
        pass
