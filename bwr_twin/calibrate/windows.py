"""A long log cut into windows, each started from the measured state (multiple shooting): an
open-loop prediction drifts, and a window short enough keeps the drift below what the parameters
explain. A window never spans a gap in the log; a gap longer than a window is refused."""

from __future__ import annotations

import numpy as np

from bwr_twin.calibrate.log import MachineLog
from bwr_twin.errors import BwrError

GAP_FACTOR = 3.0  # a step longer than this many median steps is a gap (jitter is less)


def stretches(log: MachineLog) -> list[tuple[int, int]]:
    """(first, stop) row indices of each stretch of the log without a gap, stop exclusive."""
    steps = np.diff(log.time)
    bounds = np.r_[0, np.flatnonzero(steps > GAP_FACTOR * np.median(steps)) + 1, len(log.time)]
    return [(int(first), int(stop)) for first, stop in zip(bounds[:-1], bounds[1:], strict=True)]


def cut(log: MachineLog, length: float) -> list[tuple[int, int]]:
    """(first, last) row indices of each window: from a sample to the first sample at least
    `length` s later, within a stretch without a gap (what is left at a stretch's end, shorter
    than a window, is left out). Raises BwrError naming the row of a gap longer than `length`."""
    steps = np.diff(log.time)
    if length <= 0:
        raise BwrError(f"--window: {length:g} s; a window lasts longer than 0 s")
    if steps.size and steps.max() > length:
        row = int(np.argmax(steps)) + 2
        raise BwrError(f"{log.path}: row {row}: a gap of {steps.max():g} s after {log.time[row - 2]:g} s, longer "
                       f"than a window of {length:g} s; cut the log there or give a longer --window")
    windows = []
    for start, stop in stretches(log):
        while True:
            end = int(np.searchsorted(log.time, log.time[start] + length - 1e-9, side="left"))
            if end >= stop:
                break
            windows.append((start, end))
            start = end
    if not windows:
        raise BwrError(f"{log.path}: no stretch without a gap lasts a window of {length:g} s; give a shorter "
                       "--window")
    return windows
