"""A run's laser scans as the replay draws them: the fan of the latest scan, the hits of the last
second, and the pile the automation knew from its scans at any time.

A run that scanned keeps every scan in scans.npz (docs/sensing.md): its time, its origin and its
hits, NaN where a ray returned nothing. The replay reads them once, memory-mapped where the file
is stored uncompressed (as the twin writes it), and precomputes what a frame needs:

- each scan's site rotation, from the machine's kinematics at the recorded joint values, so the
  rays that returned nothing can be drawn short and faint along their own direction;
- the scanned pile as a `PileHistory` on the true pile's grid, rebuilt from the scans by the
  survey's own code (`bwr_twin.sensing.survey.Survey`): per control period each cell the mean of
  its hits, a later period replacing it, a cell no hit reached unknown (NaN). It is kept in
  frames of whole `period`s, so the pile shown at time t is the one the automation knew as the
  last whole period began, from the scans before it. It equals survey.npz's z_plan at the
  plan's start and its z at the end.

A frame then slices these arrays: the fan is one scan's rays, the cloud the hits of the scans of
the last HIT_WINDOW seconds, at most a given count, evenly thinned.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from bwr_twin.arrays import SCALAR, Member, check_real, load_npz
from bwr_twin.errors import BwrError
from bwr_twin.stockpile.history import PileHistory

if TYPE_CHECKING:
    from bwr_twin.model.machine import Machine
    from bwr_twin.sensing.outputs import ScanRecord

SCANS_FILE = "scans.npz"  # bwr_twin.sensing.outputs, the output contract (docs/contracts.md)
SURVEY_FILE = "survey.npz"
HIT_WINDOW = 1.0  # s of hits the cloud shows, up to the current time
MISS_SHARE = 0.1  # of the scanner's range: how long a ray that returned nothing is drawn
KNOWN_FRAME_PERIOD = 1.0  # s between the live replay's frames of the scanned pile
_TIE = 1e-9  # s: a time within this of a scan's counts as at or after it (times are sums of periods)
# What the replay reads of scans.npz and survey.npz (bwr_twin.sensing.outputs). The hits are
# memory-mapped where stored uncompressed, as the twin writes them; read, they may take 4 GiB.
SCANS_SPEC = {"t": Member(shape=(None,)), "origin": Member(shape=(None, 3)),
              "hits": Member("f", (None, None, 3), max_bytes=4 << 30),
              "scanner": Member("U", (None,), required=False)}
SURVEY_SPEC = {"x": Member(shape=(None,)), "y": Member(shape=(None,)), "t_end": SCALAR,
               "t_plan": Member(shape=(), required=False)}


@dataclass(frozen=True)
class Fan:
    """One frame's fan: segments (n, 2, 3) world m from the scanners' origins to the hits of their
    latest scans (`hits`), and short segments along the rays that returned nothing (`misses`)."""

    hits: np.ndarray
    misses: np.ndarray
    scans: tuple[int, ...]  # the scans drawn, by index: one per scanner


@dataclass(eq=False)
class Scans:
    """A run's scans (scans.npz), the grid of its scanned pile and what survey.npz says of it.

    `time` (n,) s, `origin` (n, 3) and `hits` (n, rays, 3) world m (NaN: nothing returned),
    `scanner` (n,) names with several scanners, else None. `x`, `y`: the pile's grid lines (m).
    `plan_time`: when a survey's benches were planned on the scanned pile (s), else None;
    `end_time`: the run's end (s), when the scanned pile was as survey.npz's z says.
    """

    time: np.ndarray
    origin: np.ndarray
    hits: np.ndarray
    scanner: np.ndarray | None
    x: np.ndarray
    y: np.ndarray
    plan_time: float | None = None
    end_time: float | None = None
    _known: dict[float, PileHistory] = field(default_factory=dict, repr=False)
    _rays: tuple | None = field(default=None, repr=False)
    _by_scanner: list[np.ndarray] | None = field(default=None, repr=False)

    @property
    def count(self) -> int:
        return len(self.time)

    @classmethod
    def read(cls, run_dir: Path, x: np.ndarray | None = None, y: np.ndarray | None = None) -> Scans | None:
        """The scans of a run directory, or None if it holds none. The grid is survey.npz's, or
        `x`, `y` (the true pile's, on which the survey is kept) without one."""
        path = run_dir / SCANS_FILE
        if not path.is_file():
            return None
        survey = run_dir / SURVEY_FILE
        arrays = load_npz(path, SCANS_SPEC, what=str(path), mmap=True)
        t, origin, hits = arrays["t"], arrays["origin"], arrays["hits"]
        plan_time = end_time = None
        if survey.is_file():
            known = load_npz(survey, SURVEY_SPEC, what=str(survey))
            x, y, end_time = known["x"], known["y"], float(known["t_end"])
            plan_time = float(known["t_plan"]) if "t_plan" in known else None
            for key in ("x", "y"):
                check_real(str(survey), key, known[key])
        if x is None or y is None or len(t) == 0:
            return None
        scanner = arrays.get("scanner")
        if origin.shape != (len(t), 3) or len(hits) != len(t) or (scanner is not None and len(scanner) != len(t)):
            raise BwrError(f"{path}: hits {hits.shape}, origin {origin.shape} and scanner for {len(t)} scans; "
                           "the twin writes (n, rays, 3), (n, 3) and (n,)")
        check_real(str(path), "t", t)
        return cls(np.asarray(t, dtype=float), np.asarray(origin, dtype=float), hits, arrays.get("scanner"),
                   np.asarray(x, dtype=float), np.asarray(y, dtype=float), plan_time, end_time)

    @classmethod
    def of(cls, record: ScanRecord | None) -> Scans | None:
        """A RunResult's scans (`result.scan`), or None."""
        if record is None or len(record.t) == 0:
            return None
        plan = record.plan_start
        return cls(np.asarray(record.t, dtype=float), np.asarray(record.origin, dtype=float), record.hits,
                   record.scanner, np.asarray(record.x, dtype=float), np.asarray(record.y, dtype=float),
                   float(plan.time) if plan is not None else None,
                   float(record.t_end) if np.isfinite(record.t_end) else None)

    # -- the fan -----------------------------------------------------------------------------

    def attach(self, machine: Machine, time: np.ndarray, q_actual: np.ndarray) -> None:
        """Each scan's rays in world directions, from the machine's scanners posed at the run's
        joint values `q_actual` (n, 3) recorded at `time` (n,) s, interpolated to the scan's time.
        Without it, or for a scanner the machine lacks, the rays that returned nothing are not drawn."""
        by_name = {s.name: s for s in machine.scanners}
        names = self.scanner if self.scanner is not None else np.full(self.count, machine.scanners[0].name
                                                                      if machine.scanners else "")
        q = np.column_stack([np.interp(self.time, time, q_actual[:, j]) for j in range(q_actual.shape[1])])
        rotation = np.full((self.count, 3, 3), np.nan)
        ranges = np.zeros(self.count)
        directions = {}
        for name in np.unique(names):
            scanner = by_name.get(str(name))
            if scanner is None:
                continue
            rows = np.flatnonzero(names == name)
            rotation[rows] = scanner.mount.poses(q[rows])[1]
            ranges[rows] = scanner.max_range
            directions[str(name)] = scanner.directions
        self._rays = (names, rotation, ranges, directions)

    def latest(self, t: float) -> tuple[int, ...]:
        """The latest scan of each scanner at or before time t (s), by index; () before the first."""
        last = int(np.searchsorted(self.time, t + _TIE, side="right")) - 1
        if last < 0:
            return ()
        if self.scanner is None:
            return (last,)
        if self._by_scanner is None:
            self._by_scanner = [np.flatnonzero(self.scanner == name) for name in np.unique(self.scanner)]
        found = []
        for rows in self._by_scanner:
            i = int(np.searchsorted(rows, last, side="right")) - 1
            if i >= 0:
                found.append(int(rows[i]))
        return tuple(sorted(found))

    def fan(self, t: float, every: int = 1) -> Fan | None:
        """The fan at time t (s): the latest scans' rays (every `every`-th of each), or None before
        the first scan."""
        scans = self.latest(t)
        if not scans:
            return None
        hits, misses = [], []
        for k in scans:
            origin = self.origin[k]
            rays = self.hits[k][::every].astype(float)
            returned = ~np.isnan(rays[:, 0])
            hits.append(np.stack([np.broadcast_to(origin, rays[returned].shape), rays[returned]], axis=1))
            if self._rays is not None:
                names, rotation, ranges, directions = self._rays
                local = directions.get(str(names[k]))
                if local is not None and np.isfinite(rotation[k]).all():
                    lost = ~returned[: len(local[::every])]
                    ends = origin + (local[::every][lost] @ rotation[k].T) * (MISS_SHARE * ranges[k])
                    misses.append(np.stack([np.broadcast_to(origin, ends.shape), ends], axis=1))
        return Fan(np.concatenate(hits), np.concatenate(misses) if misses else np.zeros((0, 2, 3)), scans)

    def window(self, t: float, window: float = HIT_WINDOW) -> tuple[int, int]:
        """The scans [begin, end), by index, made in the `window` s up to time t: after t - window,
        at or before t."""
        return (int(np.searchsorted(self.time, t - window + _TIE, side="right")),
                int(np.searchsorted(self.time, t + _TIE, side="right")))

    def cloud(self, t: float, most: int, window: float = HIT_WINDOW) -> np.ndarray:
        """The hits (m, 3) world m of the scans in the `window` s up to time t, at most `most`,
        evenly thinned."""
        begin, end = self.window(t, window)
        points = np.asarray(self.hits[begin:end]).reshape(-1, 3)
        points = points[~np.isnan(points[:, 0])]
        if len(points) > most:
            points = points[:: math.ceil(len(points) / most)]
        return points

    # -- the scanned pile ----------------------------------------------------------------------

    def known(self, period: float = KNOWN_FRAME_PERIOD) -> PileHistory:
        """The scanned pile in frames of `period` s (the module's docstring), built once."""
        if period not in self._known:
            self._known[period] = known_history(self.time, self.hits, self.x, self.y, period, self.end_time)
        return self._known[period]


def known_history(time: np.ndarray, hits: np.ndarray, x: np.ndarray, y: np.ndarray, period: float,
                  end: float | None = None) -> PileHistory:
    """The pile known from scans at `time` (n,) s with `hits` (n, rays, 3) on the grid `x`, `y`, as
    frames at whole multiples of `period` s: the frame at time T sets the cells the scans in
    [T - period, T) last set, to the heights they left, so that it holds what was known as T
    began (a plan made at T was made on it). The last frame stands at the run's `end` (s) if that
    comes first. Starts unknown (NaN) everywhere."""
    from bwr_twin.pile.surface import Surface
    from bwr_twin.sensing.survey import Survey

    z_start = np.full((len(y), len(x)), np.nan)
    # Scans of one control period share a time: the survey takes their hits together.
    starts = np.flatnonzero(np.r_[True, time[1:] != time[:-1]])
    ends = np.r_[starts[1:], len(time)]
    survey = Survey(Surface(x, y, z_start), 1, hits.shape[1] * int((ends - starts).max()))
    runs = np.zeros(1, dtype=np.int64)
    frame_of = np.floor((time[starts] + _TIE) / period).astype(np.int64) + 1  # the first boundary after a period
    frames: list[tuple[float, np.ndarray, np.ndarray]] = []
    z = survey.z[0].reshape(-1)
    bounds = np.flatnonzero(np.r_[True, frame_of[1:] != frame_of[:-1], True])  # periods of each frame
    for first, stop in itertools.pairwise(bounds):
        scans = np.asarray(hits[starts[first]:ends[stop - 1]], dtype=np.float32)
        for s, e in zip(starts[first:stop], ends[first:stop]):
            survey.add(float(time[s]), scans[s - starts[first]:e - starts[first]].reshape(1, -1, 3), runs)
        cells = _cells(scans.reshape(-1, 3), x, y)  # those the frame's hits set, as the survey finds them
        at = float(frame_of[first] * period)
        frames.append((min(at, end) if end is not None else at, cells, z[cells].copy()))
    return PileHistory.from_frames(x, y, z_start, frames)


def _cells(points: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The flat grid cells (sorted, unique) whose grid point is nearest to the points (m, 3), as
    `bwr_twin.sensing.survey` finds a hit's cell; points off the grid or NaN have none."""
    points = points[~np.isnan(points[:, 0])].astype(float)
    spacing = float(x[1] - x[0])
    ix = np.floor((points[:, 0] - x[0]) / spacing + 0.5)
    iy = np.floor((points[:, 1] - y[0]) / spacing + 0.5)
    inside = (ix >= 0) & (ix < len(x)) & (iy >= 0) & (iy < len(y))
    return np.unique(iy[inside].astype(np.int64) * len(x) + ix[inside].astype(np.int64))

