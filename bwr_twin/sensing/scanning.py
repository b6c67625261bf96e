"""Each run's scanners in the loop: a scan when its period has passed, on the control period grid.

A scanner's n-th scan is due at n / rate s; it is made at the first control period at or after
that time (a scanner faster than the control rate scans once a control period). A scan casts
the fan from the site's world pose for the run's true joint values at the period's start
(bwr_twin.model.scanner), against the pile as that run has dug it until then
(bwr_twin.sensing.raycast). A ray that meets nothing within the scanner's range is a miss; one
that does has Gaussian range noise of standard deviation `constant + share x range` added, or is
dropped with the dropout probability (bwr_twin.sensing.noise). Hits are world metres; a missed
or dropped ray is NaN. The hits fill the run's scanned pile (bwr_twin.sensing.survey).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError, SceneError
from bwr_twin.model.machine import Machine
from bwr_twin.model.mount import site_pose
from bwr_twin.model.scanner import Scanner, read_scanners
from bwr_twin.model.spec import compile_model
from bwr_twin.pile.ground import YARD_FLOOR
from bwr_twin.pile.surface import Surface
from bwr_twin.sensing.faults import Faults
from bwr_twin.sensing.noise import ScanNoise
from bwr_twin.sensing.outputs import KnownPile, ScanLog, ScanRecord
from bwr_twin.sensing.raycast import grid_of, ray_distance
from bwr_twin.sensing.survey import Survey
from bwr_twin.textfile import version

_DUE = 1e-9  # s: a scan due within this of a period's time is due at that period (rounding of n / rate)
_VERTICAL = 1e-12  # the largest upward part of a fan plane's normal for which the plane counts as upright
_BACK_OFF = 1e-6  # m a ray's walk begins short of the last hit's reach: rounding may put both in one cell


def active_scanners(scene: Scene, machine: Machine) -> tuple[Scanner, ...]:
    """The scanners a scene's runs scan with: the machine's, if the scene has a stockpile and its
    [sensing] does not turn them off. Raises SceneError if it turns them on for a machine without."""
    wanted = scene.sensing.scanners
    if scene.stockpile is None or wanted is False:
        return ()
    if wanted and not machine.scanners:
        raise SceneError(f"{scene.path}: 'sensing.scanners' is true, but {machine.path} has no scanner site "
                         "(a <site> named 'scanner...' with its custom numerics, docs/sensing.md)")
    return machine.scanners


def pile_model(scene: Scene, scanners: Sequence[Scanner]) -> str:
    """The pile a bench reclaim's benches are planned on: "scanned" or "exact" ([sensing]
    pile_model; by default "scanned" when the runs scan). SceneError if the scanned pile is asked
    for without scanners, or without a [reclaim.survey] to scan the pile before the plan."""
    wanted = scene.sensing.pile_model
    if scene.reclaim is None:
        return "exact"
    if wanted == "scanned" and not scanners:
        raise SceneError(f"{scene.path}: 'sensing.pile_model' is \"scanned\", but the runs do not scan: "
                         f"{scene.machine.mjcf.name} has no scanner site (docs/sensing.md)")
    model = wanted or ("scanned" if scanners else "exact")
    if model == "scanned" and scene.reclaim.survey is None:
        default = "" if wanted else " (the default when the machine scans)"
        raise SceneError(f"{scene.path}: the benches are planned on the scanned pile{default}, which needs a "
                         "[reclaim.survey] to scan it first: give its 'waypoints' [travel m, slew deg, luff deg], "
                         "or set 'sensing.pile_model' = \"exact\" to plan on the true pile")
    return model


def planned_scanners(scene: Scene) -> tuple[Scanner, ...]:
    """The scanners a scene's runs will scan with, read from its MJCF without the run's other
    edits (for estimates); () if the file cannot be read: the run itself will say why."""
    if scene.stockpile is None or scene.sensing.scanners is False:
        return ()
    try:
        return _file_scanners(scene.machine.mjcf, version(scene.machine.mjcf))
    except BwrError:
        return ()


@functools.lru_cache(maxsize=8)
def _file_scanners(mjcf, stamp: tuple) -> tuple[Scanner, ...]:
    """The file's scanners, read once per version of it (`stamp`: a sweep estimates many runs)."""
    return read_scanners(compile_model(mjcf), mjcf)


class Scanning:
    """The scanners of a lockstep's runs, their scans so far and the piles the runs know from them.

    Attributes:
        scanners: the machine's scanners the runs scan with.
        survey: each run's scanned pile.
        scans, rays, hits, dropped: (runs,) scans made, rays cast, rays that returned a hit and
            rays that met the pile but were dropped, so far.
    """

    def __init__(self, scanners: Sequence[Scanner], surface: Surface, seeds: Sequence[int], period: float, *,
                 keep_scans: bool = True, faults: Faults | None = None):
        """`seeds`: each run's; `keep_scans=False` keeps only the latest scan
        (a lockstep that keeps no results: its memory stays bounded); `faults`: the scene's, of
        which dust blinds a scanner (bwr_twin.sensing.faults)."""
        self._faults = faults
        runs = len(seeds)
        self.scanners, self.surface, self.period = tuple(scanners), surface, period
        self.survey = Survey(surface, runs, sum(s.rays for s in scanners))
        # Heights only fall: the top a ray must consider is the pile's first.
        self._grid = grid_of(surface.x, surface.y, surface.z, YARD_FLOOR, float(surface.z.max()))
        self._fans = [Fan.of(s, ScanNoise(seeds, i, s.rays)) for i, s in enumerate(scanners)]
        self.logs = [ScanLog(runs, s.rays, keep_scans) for s in scanners]
        self._schedule = ScanSchedule([s.rate for s in scanners], period)
        # Per run: scans made, rays cast, rays that hit, rays that met the pile but were dropped.
        self._counts = np.zeros((runs, 4), dtype=np.int64)
        self._all = np.arange(runs)

    @property
    def scans(self) -> np.ndarray:
        return self._counts[:, 0]

    @property
    def rays(self) -> np.ndarray:
        return self._counts[:, 1]

    @property
    def hits(self) -> np.ndarray:
        return self._counts[:, 2]

    @property
    def dropped(self) -> np.ndarray:
        return self._counts[:, 3]

    def step(self, k: int, q: np.ndarray, heights: np.ndarray, runs: np.ndarray | None) -> bool:
        """Scan with every scanner due at control period k, the runs' true joint values q (runs, 3)
        at its start, against their piles' heights (runs, ny, nx) m; only the `runs` given (None:
        all). Returns whether any scanned."""
        schedule = self._schedule
        if k < schedule.soonest:
            return False
        order = self._all if runs is None else runs
        time = k * self.period
        made = []
        for i, scanner in enumerate(self.scanners):
            if not schedule.due(i, k):
                continue
            log, mount, fan = self.logs[i], scanner.mount, self._fans[i]
            normal, uniform = fan.noise.at(log.count)
            origin, hits = log.next_scan(time)
            settings = fan.settings
            if self._faults is not None and self._faults.active and self._faults.scanner_blinded(k, scanner.name):
                settings = settings.copy()
                settings[3] = 1.0  # blinded by dust: every ray that meets the pile returns nothing
            _scan(heights, self._grid, order, q, mount.position, mount.rotation, mount.joints, mount.anchor,
                  mount.axis, fan.directions, settings, normal, uniform, origin, hits, self._counts)
            made.append(hits)
            schedule.made(i, time)
        if made:
            self.survey.add(time, made[0] if len(made) == 1 else np.concatenate(made, axis=1), order)
        return bool(made)

    def metrics(self, run: int, heights: np.ndarray, density: float) -> dict:
        """The scans' share of metrics.json's `scan` object of `run`, whose pile now stands at
        heights (ny, nx) m, of `density` kg/m^3."""
        rays = int(self.rays[run])
        return {
            "scanners": [s.name for s in self.scanners],
            "scans": int(self.scans[run]),
            "rays": rays,
            "hit_share": int(self.hits[run]) / rays if rays else None,
            "dropped_share": int(self.dropped[run]) / met if (met := int(self.hits[run] + self.dropped[run])) else None,
            **self.survey.tonnes(run, heights, density),
        }

    def known(self, run: int, time: float) -> KnownPile:
        """Run `run`'s scanned pile as it stands, at `time` s."""
        survey = self.survey
        return KnownPile(time, survey.z[run].copy(), survey.seen[run].copy(), survey.last_seen[run].copy())

    def record(self, run: int, time: float = math.nan, at_plan: KnownPile | None = None) -> ScanRecord:
        """Run `run`'s scans, its scanned pile at the end, `time` s, and at the plan's start."""
        return ScanRecord.of(self.scanners, [log.share(run) for log in self.logs], self.surface.x, self.surface.y,
                             self.known(run, time), at_plan)


@dataclass(frozen=True)
class Fan:
    """What the compiled scan reads of one scanner: its rays' directions in the site's frame,
    its settings (range m, noise constant m and share, dropout probability) and its noise stream."""

    directions: np.ndarray  # (rays, 3), contiguous
    settings: np.ndarray  # (4,) max_range, noise constant, noise share, dropout
    noise: ScanNoise

    @classmethod
    def of(cls, scanner: Scanner, noise: ScanNoise) -> Fan:
        return cls(np.ascontiguousarray(scanner.directions),
                   np.array([scanner.max_range, scanner.noise[0], scanner.noise[1], scanner.dropout]), noise)


class ScanSchedule:
    """When each scanner scans on the control period grid: its n-th scan is due at n / rate s and
    made at the first period at or after that time.

    Attributes:
        soonest: the first control period at which any scanner is due.
    """

    def __init__(self, rates: Sequence[float], period: float):
        self._rates, self._period = list(rates), period
        self._due = [0] * len(rates)  # each scanner's next scan's number (due at number / rate)
        self._next = [0] * len(rates)  # the control period it is made at
        self.soonest = 0

    def due(self, i: int, k: int) -> bool:
        """Whether scanner i scans at control period k."""
        return k >= self._next[i]

    def made(self, i: int, time: float) -> None:
        """Scanner i scanned at `time` s: on to its next scan."""
        rate = self._rates[i]
        self._due[i] = math.floor(time * rate + _DUE) + 1
        self._next[i] = math.ceil((self._due[i] / rate - _DUE) / self._period)
        self.soonest = min(self._next)


@numba.njit(cache=True)
def _scan(heights, grid, runs, q, position0, rotation0, joints, anchor, axis, directions, settings, normal, uniform,
          origin, hits, counts):  # pragma: no cover - compiled
    """One scan of one scanner for each of `runs` at their joints q (runs, 3): the site's pose
    (bwr_twin.model.mount.site_pose of its mount), the rays, noise and dropouts on their ranges. Writes
    origin (runs, 3) and hits (runs, rays, 3) world m, NaN where missed or dropped, and adds to
    counts (runs, 4): scans, rays, hits, dropped.

    A fan in a vertical plane meets the pile's section along that plane, a height profile: of
    two rays on one side of the site, the one above the other meets it no nearer to the site's
    foot (until the lower one meets it, the upper one passes above it too). So each ray's walk
    begins where the last ray below it met the pile, and a scan walks the section about once,
    not once a ray. Each side's rays are taken outwards from the vertical (the fan's angles turn
    one way, so its order or the reverse); a ray not above the last hit's starts from the site."""
    max_range, constant, share, dropout = settings[0], settings[1], settings[2], settings[3]
    m = np.empty((3, 3))
    rays = directions.shape[0]
    world = np.empty((rays, 4))  # each ray's world direction, and how far out it points along the plane
    for run in runs:
        site_pose(q[run], position0, rotation0, joints, anchor, axis, origin[run], m)
        px, py, pz = origin[run, 0], origin[run, 1], origin[run, 2]
        counts[run, 0] += 1
        counts[run, 1] += rays
        vertical = abs(m[2, 1]) < _VERTICAL  # the fan's plane (its normal: the site's y axis) stands upright
        wx, wy = m[1, 1], -m[0, 1]  # a horizontal direction in that plane: the site's y x world z
        norm = math.hypot(wx, wy)
        if norm > 0.0:
            wx, wy = wx / norm, wy / norm
        for i in range(rays):
            a, b, c = directions[i, 0], directions[i, 1], directions[i, 2]
            world[i, 0] = m[0, 0] * a + m[0, 1] * b + m[0, 2] * c
            world[i, 1] = m[1, 0] * a + m[1, 1] * b + m[1, 2] * c
            world[i, 2] = m[2, 0] * a + m[2, 1] * b + m[2, 2] * c
            world[i, 3] = world[i, 0] * wx + world[i, 1] * wy
        for side in (1.0, -1.0):
            # Outwards: in the fan's order if its last ray on this side points farther out than its first.
            first, last = -1, -1
            for i in range(rays):
                if side * world[i, 3] > 0.0 or (side > 0 and world[i, 3] == 0.0):
                    last = i
                    if first < 0:
                        first = i
            if first < 0:
                continue
            outwards = _outness(world[last], side) >= _outness(world[first], side)
            last_out = last_down = reach = 0.0  # the last hit ray's direction (out, down) and its reach, m
            found = False
            for n in range(first, last + 1):
                i = n if outwards else first + last - n
                out = side * world[i, 3]  # out from the site's foot along the plane, this side
                if out < 0.0 or (out == 0.0 and side < 0):
                    continue  # the other side's (a vertical ray is the first side's)
                dx, dy, dz = world[i, 0], world[i, 1], world[i, 2]
                begin = 0.0
                if vertical and found and out > 0.0 and last_out * dz - last_down * out >= 0.0:  # above the last
                    begin = max(reach - _BACK_OFF, 0.0) / out
                distance = ray_distance(heights[run], grid, px, py, pz, dx, dy, dz, max_range, begin)
                if np.isnan(distance):
                    continue  # the hits are NaN until written
                last_out, last_down, reach, found = out, dz, distance * out, True
                if uniform[run, i] < dropout:
                    counts[run, 3] += 1
                    continue
                measured = max(distance + normal[run, i] * (constant + share * distance), 0.0)
                hits[run, i, 0] = px + measured * dx
                hits[run, i, 1] = py + measured * dy
                hits[run, i, 2] = pz + measured * dz
                counts[run, 2] += 1


@numba.njit(cache=True, inline="always")
def _outness(direction, side):  # pragma: no cover - compiled
    """How far a ray's direction (x, y, z, out along the fan's plane) turns from straight down
    towards `side` (+1 or -1) of the plane, rad."""
    return math.atan2(side * direction[3], -direction[2])
