"""A run's pile as it was dug: the heights at the start and the cells each frame changed.

Kept every few simulated seconds when a replay asks for it (`simulate(pile_frame_period=...)`),
written into the run's pile.npz beside z_start and z_end, and read back by the replay.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class PileHistory:
    """A run's pile at its start, and the cells it changed, frame by frame.

    Frame i, at time `frame_time[i]` (s), set the flat cells `cells[offsets[i]:offsets[i + 1]]`
    of the (ny, nx) height grid to `heights[...]` (m)."""

    x: np.ndarray
    y: np.ndarray
    z_start: np.ndarray
    frame_time: np.ndarray
    offsets: np.ndarray
    cells: np.ndarray
    heights: np.ndarray

    @classmethod
    def from_frames(cls, x, y, z_start, frames: list[tuple[float, np.ndarray, np.ndarray]]) -> PileHistory:
        """From the run's list of (time s, flat cells, heights m)."""
        sizes = [len(cells) for _, cells, _ in frames]
        return cls(x, y, z_start, np.array([t for t, _, _ in frames], dtype=float),
                   np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]),
                   np.concatenate([c for _, c, _ in frames]) if frames else np.zeros(0, np.int32),
                   np.concatenate([h for _, _, h in frames]) if frames else np.zeros(0, np.float32))

    @classmethod
    def start_and_end(cls, x, y, z_start, z_end, end_time: float) -> PileHistory:
        """A run kept without its history: the pile whole until `end_time` (s), then as it ended."""
        return cls.from_frames(x, y, z_start, [(end_time, np.arange(z_end.size), z_end.ravel())])

    @classmethod
    def read(cls, path: Path, end_time: float) -> PileHistory:
        """From a run's pile.npz; one written without its history ends at `end_time` (s)."""
        with np.load(path) as data:
            arrays = {key: data[key] for key in data.files}
        if "frame_time" not in arrays:
            return cls.start_and_end(arrays["x"], arrays["y"], arrays["z_start"], arrays["z_end"], end_time)
        return cls(arrays["x"], arrays["y"], arrays["z_start"], arrays["frame_time"], arrays["frame_offsets"],
                   arrays["frame_cells"], arrays["frame_heights"])

    def arrays(self) -> dict[str, np.ndarray]:
        """The history as pile.npz keeps it, beside x, y, z_start and z_end."""
        return {"frame_time": self.frame_time, "frame_offsets": self.offsets, "frame_cells": self.cells,
                "frame_heights": self.heights}


class PileFrames:
    """Every run's frames while its pile changes (a reclaim's cut, a stacking's deposits): the
    cells changed since the last frame, with their heights."""

    def __init__(self, start: np.ndarray):
        """`start`: (runs, ny, nx) the piles' heights as they begin."""
        self._framed = np.array(start, dtype=float)
        self._frames: list[list] = [[] for _ in range(len(self._framed))]

    def keep(self, time: float, heights) -> None:
        """A frame at `time` (s) of each run's (ny, nx) heights, `heights[run]`."""
        for run, framed in enumerate(self._framed):
            z = np.asarray(heights[run])
            changed = np.flatnonzero(z != framed)
            if changed.size:
                values = z.ravel()[changed]
                framed.ravel()[changed] = values
                self._frames[run].append((time, changed.astype(np.int32), values.astype(np.float32)))

    def history(self, run: int, x: np.ndarray, y: np.ndarray, z_start: np.ndarray) -> PileHistory:
        return PileHistory.from_frames(x, y, z_start, self._frames[run])
