"""What a run leaves behind: metrics, a self-describing time series and the run's settings,
written into a directory that appears only when complete (read back by bwr_twin.results.run_files).

Layout of a run directory (the output contract of docs/contracts.md, plus more):
    metrics.json      per-axis error maxima (signed), their times, RMS, drive saturation
    timeseries.csv    every signal at the record period; units in the column names
    scene.json        the resolved scene, so the run can be replayed without its files' paths
    pile.npz          with a stockpile: x, y (grid lines, m), z_start, z_end (heights, m), and
                      for a replay the cells dug frame by frame (bwr_twin.stockpile.history),
                      on a pile of layers with their top layer's grade;
                      stacked: the pile's grade layers and every deposit too
    scans.npz         with a stockpile and a machine that scans: every scan's time, origin and
    survey.npz        hits, and the pile known from them at the end (bwr_twin.sensing.outputs)
    *.png             the paper's figures for this run (bwr_twin.results.plots)
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.model.machine import AXES
from bwr_twin.ownership import check_output, mark, record_folder, remove_stale_partials
from bwr_twin.signals import LOOP, NEIGHBOUR, RECLAIM
from bwr_twin.signals import column_name as signal_column
from bwr_twin.sim.record import RunResult

METRICS_FILE = "metrics.json"
PILE_FILE = "pile.npz"
TIMESERIES_FILE = "timeseries.csv"
SCENE_FILE = "scene.json"


def timeseries_columns(result: RunResult) -> tuple[list[str], np.ndarray]:
    """Column names (with units) and values of the recorded time series, at the record period:
    the loop's signals, the controller's (bwr_twin.signals), the CP, the wind, a stockpile's."""
    names, columns = ["time_s"], [result.time]
    for signal in LOOP + result.signal_schema:
        values = getattr(result, signal.name) if signal in LOOP else result.controller_signals[signal.name]
        for j in range(len(AXES)):
            names.append(signal_column(signal, j))
            columns.append(values[:, j])
    for label, cp in (("desired", result.cp_desired), ("actual", result.cp)):
        for c, coordinate in enumerate("xyz"):
            names.append(f"cp_{label}_{coordinate}_m")
            columns.append(cp[:, c])
    names.append("wind_speed_m/s")
    columns.append(result.wind_speed)
    reclaim = result.reclaim
    if reclaim is not None:
        for name, column, width in RECLAIM:
            values = getattr(reclaim, name)
            if width == 1:
                names.append(column)
                columns.append(values)
            else:
                for c, coordinate in enumerate("xyz"):
                    names.append(column.format(xyz=coordinate))
                    columns.append(values[:, c])
    if reclaim is not None and reclaim.grade_out is not None:  # the grade of the last discharge to pass
        out = reclaim.grade_out
        index = np.searchsorted(out["t"], result.time, side="right") - 1
        names.append(f"grade_out_{out['name']}")
        columns.append(np.where(index >= 0, out["grade"][np.clip(index, 0, None)], np.nan) if len(out["t"])
                       else np.full(len(result.time), np.nan))
    if result.stacking is not None:
        grade_in, stacked = result.stacking.series(result.time)
        names += [f"stacking_grade_in_{result.stacking.grade_name}", "stacked_t"]
        columns += [grade_in, stacked]
    if result.neighbour is not None:
        for signal in NEIGHBOUR:
            for j in range(len(AXES)):
                names.append(signal_column(signal, j))
                columns.append(result.neighbour[signal.name][:, j])
    return names, np.column_stack(columns)


def _umask() -> int:
    """The process's umask: reading it means setting it, so it is set back at once."""
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def staged_directory(out_dir: Path, *, overwrite: bool = False, kind: str = "run",
                     repairs: tuple[str, ...] = ()) -> Iterator[Path]:
    """A temporary sibling of `out_dir`, marked as the twin's `kind` of output, that is renamed
    into place, its files recorded in its marker, only if the block succeeds.

    An existing `out_dir` is replaced only if the twin wrote it, holds nothing but what its
    manifest records (but for `repairs`) and `overwrite` is given (bwr_twin.ownership), and only
    once the new one is complete. On any failure the temporary directory is removed and `out_dir`
    is untouched; what killed writers of `out_dir` left beside it is removed first.
    """
    out_dir = Path(out_dir)
    check_output(out_dir, kind, overwrite=overwrite, repairs=repairs)
    try:
        out_dir.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_partials(out_dir)
        staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.partial-{os.getpid()}-", dir=out_dir.parent))
    except OSError as exc:
        raise BwrError(f"{out_dir}: cannot create it: {exc.strerror}") from None
    try:
        staging.chmod(0o777 & ~_umask())  # mkdtemp's 0700 would make results private
        mark(staging, kind)
        yield staging
        record_folder(staging)
        if out_dir.exists():
            check_output(out_dir, kind, overwrite=overwrite, repairs=repairs)  # still the twin's, just before it goes
        publish_directory(staging, out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def publish_directory(complete: Path, target: Path) -> None:
    """Rename a complete directory to `target`, replacing a `target` that exists: the old one is
    first moved aside (a rename), so `target` is at every moment either the old or the new."""
    if not target.exists():
        os.replace(complete, target)
        return
    old = Path(tempfile.mkdtemp(prefix=f".{target.name}.old-", dir=target.parent))
    os.replace(target, old / target.name)
    os.replace(complete, target)
    shutil.rmtree(old, ignore_errors=True)


def write_run(
    result: RunResult,
    out_dir: str | Path,
    *,
    overwrite: bool = False,
    plots: bool = True,
) -> dict:
    """Write a run directory atomically; returns the metrics."""
    metrics = result.metrics
    with staged_directory(Path(out_dir), overwrite=overwrite) as staging:
        names, values = timeseries_columns(result)
        np.savetxt(staging / TIMESERIES_FILE, values, delimiter=",", header=",".join(names), comments="", fmt="%.10g")
        (staging / METRICS_FILE).write_text(json.dumps(metrics, indent=2) + "\n")
        (staging / SCENE_FILE).write_text(json.dumps(result.scene.to_dict(), indent=2) + "\n")
        if result.reclaim is not None:
            pile = result.reclaim
            history = pile.history.arrays() if pile.history is not None else {}
            np.savez_compressed(staging / PILE_FILE, x=pile.x, y=pile.y, z_start=pile.z_start, z_end=pile.z_end,
                                **history)
        if result.stacking is not None:
            np.savez_compressed(staging / PILE_FILE, **result.stacking.pile_arrays())
        if result.scan is not None:
            result.scan.write(staging)
        if plots:
            from bwr_twin.results.plots import save_run_figures

            save_run_figures(result, staging)
    return metrics
