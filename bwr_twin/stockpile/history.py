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
    def read(cls, path: Path) -> PileHistory:
        with np.load(path) as data:
            arrays = {key: data[key] for key in data.files}
        if "frame_time" not in arrays:  # a run written without its history: start and end only
            return cls(arrays["x"], arrays["y"], arrays["z_start"], np.array([0.0]), np.array([0, arrays["z_end"].size]),
                       np.arange(arrays["z_end"].size), arrays["z_end"].ravel())
        return cls(arrays["x"], arrays["y"], arrays["z_start"], arrays["frame_time"], arrays["frame_offsets"],
                   arrays["frame_cells"], arrays["frame_heights"])

    def arrays(self) -> dict[str, np.ndarray]:
        """The history as pile.npz keeps it, beside x, y, z_start and z_end."""
        return {"frame_time": self.frame_time, "frame_offsets": self.offsets, "frame_cells": self.cells,
                "frame_heights": self.heights}
