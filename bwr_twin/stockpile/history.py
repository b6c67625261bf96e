"""A run's pile as it was dug: the heights at the start and the cells each frame changed.

Kept every few simulated seconds when a replay asks for it (`simulate(pile_frame_period=...)`),
written into the run's pile.npz beside z_start and z_end, and read back by the replay. A pile of
layers of grade (a stacking's, a reclaim of a stacked pile) keeps the grade of each cell's top
layer beside its height, so that the replay can colour the surface by the grade exposed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.arrays import TEXT, Member, check_index, check_real, check_within, load_npz
from bwr_twin.errors import BwrError
from bwr_twin.stockpile.layers import top_grade

_LINE, _GRID = Member(shape=(None,)), Member(shape=(None, None))
_FRAME, _FRAME_INDICES = Member(shape=(None,), required=False), Member("iu", (None,), required=False)
# What the replay takes from a run's pile.npz (the output contract, docs/contracts.md).
SPEC = {"x": _LINE, "y": _LINE, "z_start": _GRID, "z_end": _GRID, "frame_time": _FRAME,
        "frame_offsets": _FRAME_INDICES, "frame_cells": _FRAME_INDICES, "frame_heights": _FRAME,
        "grade_start": Member(shape=(None, None), required=False), "frame_grades": _FRAME,
        "grade_name": Member("U", (), TEXT.max_bytes, required=False),
        "grade_band": Member(shape=(2,), required=False),
        "layer_grade": Member(shape=(None, None, None), required=False),
        "layer_count": Member("iu", (None, None), required=False)}


@dataclass(frozen=True)
class PileHistory:
    """A run's pile at its start, and the cells it changed, frame by frame.

    Frame i, at time `frame_time[i]` (s), set the flat cells `cells[offsets[i]:offsets[i + 1]]`
    of the (ny, nx) height grid to `heights[...]` (m). A pile with grade also has the grade of the
    top layer at its start, `grade_start` (ny, nx, NaN on bare ground), and at each frame's cells,
    `grades[...]`; its grade is `grade_name` ("Fe %"), and `grade_band` the one its customer
    accepts, if given."""

    x: np.ndarray
    y: np.ndarray
    z_start: np.ndarray
    frame_time: np.ndarray
    offsets: np.ndarray
    cells: np.ndarray
    heights: np.ndarray
    grade_start: np.ndarray | None = None
    grades: np.ndarray | None = None
    grade_name: str = ""
    grade_band: tuple[float, float] | None = None

    @classmethod
    def from_frames(cls, x, y, z_start, frames: list[tuple], grade_start: np.ndarray | None = None,
                    grade_name: str = "", grade_band: tuple[float, float] | None = None) -> PileHistory:
        """From the run's list of (time s, flat cells, heights m), each with the cells' top grades
        when the pile has `grade_start`."""
        sizes = [len(frame[1]) for frame in frames]
        grades = None
        if grade_start is not None:
            grades = np.concatenate([f[3] for f in frames]) if frames else np.zeros(0, np.float32)
        return cls(x, y, z_start, np.array([f[0] for f in frames], dtype=float),
                   np.concatenate([[0], np.cumsum(sizes, dtype=np.int64)]),
                   np.concatenate([f[1] for f in frames]) if frames else np.zeros(0, np.int32),
                   np.concatenate([f[2] for f in frames]) if frames else np.zeros(0, np.float32),
                   grade_start, grades, grade_name, grade_band)

    @classmethod
    def start_and_end(cls, x, y, z_start, z_end, end_time: float, grade_end: np.ndarray | None = None,
                      grade_name: str = "", grade_band: tuple[float, float] | None = None) -> PileHistory:
        """A run kept without its history: the pile whole until `end_time` (s), then as it ended;
        with the top grade at its end, `grade_end`, a pile grown from the bare yard (a stacking's)."""
        if grade_end is None:
            return cls.from_frames(x, y, z_start, [(end_time, np.arange(z_end.size), z_end.ravel())])
        return cls.from_frames(x, y, z_start, [(end_time, np.arange(z_end.size), z_end.ravel(),
                                                grade_end.ravel().astype(np.float32))],
                               np.full(z_start.shape, np.nan, np.float32), grade_name, grade_band)

    @classmethod
    def read(cls, path: Path, end_time: float) -> PileHistory:
        """From a run's pile.npz; one written without its history ends at `end_time` (s)."""
        arrays = load_npz(path, SPEC, what=str(path))
        _check(arrays, str(path))
        name = str(arrays["grade_name"]) if "grade_name" in arrays else ""
        band = tuple(float(v) for v in arrays["grade_band"]) if "grade_band" in arrays else None
        if "frame_time" not in arrays:
            grade_end = None
            if "layer_grade" in arrays:  # a stacking's, kept without its frames: its top grade at the end
                grade_end = top_grade(arrays["layer_grade"], arrays["layer_count"])
            return cls.start_and_end(arrays["x"], arrays["y"], arrays["z_start"], arrays["z_end"], end_time,
                                     grade_end, name, band)
        return cls(arrays["x"], arrays["y"], arrays["z_start"], arrays["frame_time"], arrays["frame_offsets"],
                   arrays["frame_cells"], arrays["frame_heights"], arrays.get("grade_start"),
                   arrays.get("frame_grades"), name if "grade_start" in arrays else "",
                   band if "grade_start" in arrays else None)

    def arrays(self) -> dict[str, np.ndarray]:
        """The history as pile.npz keeps it, beside x, y, z_start and z_end; with grade, also the
        grade's name and band (a stacking's pile.npz holds the same)."""
        arrays = {"frame_time": self.frame_time, "frame_offsets": self.offsets, "frame_cells": self.cells,
                  "frame_heights": self.heights}
        if self.grade_start is not None:
            arrays.update(grade_start=self.grade_start, frame_grades=self.grades, grade_name=self.grade_name)
            if self.grade_band is not None:
                arrays["grade_band"] = np.array(self.grade_band)
        return arrays


def _check(arrays: dict[str, np.ndarray], what: str) -> None:
    """BwrError, naming the array and the limit, unless a pile.npz's arrays agree with its grid:
    the heights (ny, nx) and finite, each frame's cells within the grid and the offsets that
    slice them rising from 0 to their count, the layers' counts within the layers held."""
    grid = (len(arrays["y"]), len(arrays["x"]))
    for key in ("x", "y", "z_start", "z_end"):
        check_real(what, key, arrays[key])
    for key in ("z_start", "z_end", "grade_start", "layer_count"):
        if key in arrays and arrays[key].shape != grid:
            raise BwrError(f"{what}: array '{key}' has the shape {arrays[key].shape}; the grid lines x, y make it "
                           f"{grid}")
    if "frame_time" in arrays:
        frames = ("frame_offsets", "frame_cells", "frame_heights")
        frames += ("frame_grades",) if "grade_start" in arrays else ()
        absent = [key for key in frames if key not in arrays]
        if absent:
            raise BwrError(f"{what}: has 'frame_time' but no array '{absent[0]}'")
        check_real(what, "frame_time", arrays["frame_time"])
        offsets, cells = arrays["frame_offsets"], arrays["frame_cells"]
        if len(offsets) != len(arrays["frame_time"]) + 1 or offsets[0] != 0 or np.any(np.diff(offsets) < 0):
            raise BwrError(f"{what}: array 'frame_offsets' must rise from 0, one more than the "
                           f"{len(arrays['frame_time'])} frames of 'frame_time'")
        for key in frames[1:]:
            if len(arrays[key]) != offsets[-1]:
                raise BwrError(f"{what}: array '{key}' holds {len(arrays[key]):,} values, and 'frame_offsets' "
                               f"ends at {offsets[-1]:,}")
        check_index(what, "frame_cells", cells, grid[0] * grid[1], "cells of the grid", BwrError)
    elif "layer_grade" in arrays:
        grade = arrays["layer_grade"]
        if "layer_count" not in arrays or grade.shape[:2] != grid:
            raise BwrError(f"{what}: array 'layer_grade' {grade.shape} needs 'layer_count', both on the grid {grid}")
        check_within(what, "layer_count", arrays["layer_count"], 0, grade.shape[2],
                     f"a column holds 0 to the {grade.shape[2]} layers of 'layer_grade'")


class PileFrames:
    """Every run's frames while its pile changes (a reclaim's cut, a stacking's deposits): the
    cells changed since the last frame, with their heights, and on a pile of grade their top
    layer's grade."""

    def __init__(self, start: np.ndarray, grade_start: np.ndarray | None = None):
        """`start`: (runs, ny, nx) the piles' heights as they begin; `grade_start`: (runs, ny, nx)
        their top layers' grades then (NaN on bare ground), for a pile of grade."""
        self._framed = np.array(start, dtype=float)
        self._frames: list[list] = [[] for _ in range(len(self._framed))]
        self._grade_start = None if grade_start is None else np.array(grade_start, dtype=np.float32)
        self._graded = None if grade_start is None else self._grade_start.copy()

    def keep(self, time: float, heights, grades=None) -> None:
        """A frame at `time` (s) of each run's (ny, nx) heights, `heights[run]`, and, on a pile of
        grade, its top layers' grades `grades[run]`. A cell whose top grade changed but not its
        height (a slump that swapped equal thicknesses) is a changed cell too."""
        for run, framed in enumerate(self._framed):
            z = np.asarray(heights[run])
            differs = z != framed
            if self._graded is not None:
                g, graded = np.asarray(grades[run], dtype=np.float32), self._graded[run]
                differs |= ~((g == graded) | (np.isnan(g) & np.isnan(graded)))
            changed = np.flatnonzero(differs)
            if changed.size:
                values = z.ravel()[changed]
                framed.ravel()[changed] = values
                frame = (time, changed.astype(np.int32), values.astype(np.float32))
                if self._graded is not None:
                    top = g.ravel()[changed]
                    self._graded[run].ravel()[changed] = top
                    frame += (top,)
                self._frames[run].append(frame)

    def history(self, run: int, x: np.ndarray, y: np.ndarray, z_start: np.ndarray, grade_name: str = "",
                grade_band: tuple[float, float] | None = None) -> PileHistory:
        grade_start = None if self._grade_start is None else self._grade_start[run]
        return PileHistory.from_frames(x, y, z_start, self._frames[run], grade_start, grade_name, grade_band)
