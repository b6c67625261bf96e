"""What a run keeps of its scans, and the two files of a run directory that hold them.

    scans.npz   t (n,) s, origin (n, 3) and hits (n, rays, 3) world m, NaN where a ray was
                dropped or met nothing; with several scanners, `scanner` (n,) names which, and
                a scanner with fewer rays than another has its rows padded with NaN
    survey.npz  the pile known from the scans at the end: x, y (grid lines, m), z (ny, nx) m
                (NaN: unknown), seen (hits each cell took), last_seen (s, NaN: never), t_end
                (s); after a [reclaim.survey], the same at the plan's start: z_plan,
                seen_plan, last_seen_plan and t_plan

Hits are kept as float32: 8 um at 100 m from the origin, far below a scanner's noise, and half
the memory and disk of float64.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

SCANS_FILE = "scans.npz"
SURVEY_FILE = "survey.npz"
HIT_BYTES = 3 * 4  # a hit of scans.npz, float32 x, y, z
SCAN_BYTES = 8 + 3 * 8  # a scan's time and origin, float64
SURVEY_CELL_BYTES = 8 + 4 + 8  # a cell of survey.npz: z, seen, last_seen, before compression
LOG_BLOCK = 256  # scans a log allocates at once: 10 s at 25 Hz


class ScanLog:
    """One scanner's scans of every run of a lockstep, in blocks of LOG_BLOCK scans; with
    `keep=False` only the latest (a lockstep that keeps no results)."""

    def __init__(self, runs: int, rays: int, keep: bool = True):
        self.runs, self.rays, self.keep = runs, rays, keep
        self.count = 0  # scans so far
        self._times: list[float] = []
        self._origins: list[np.ndarray] = []  # (LOG_BLOCK, runs, 3) float64
        self._hits: list[np.ndarray] = []  # (LOG_BLOCK, runs, rays, 3) float32

    def next_scan(self, time: float) -> tuple[np.ndarray, np.ndarray]:
        """Keep a scan at `time` s; returns its (runs, 3) origins and (runs, rays, 3) float32 hits
        to fill, in world m (NaN until filled)."""
        if not self.keep and self._hits:
            self.count += 1
            self._times[0] = time
            self._hits[0][0].fill(np.nan)
            return self._origins[0][0], self._hits[0][0]
        slot = self.count % LOG_BLOCK
        if slot == 0:
            self._origins.append(np.full((LOG_BLOCK, self.runs, 3), np.nan))
            self._hits.append(np.full((LOG_BLOCK, self.runs, self.rays, 3), np.nan, dtype=np.float32))
        self._times.append(time)
        self.count += 1
        return self._origins[-1][slot], self._hits[-1][slot]

    def latest(self, run: int) -> tuple[float, np.ndarray, np.ndarray] | None:
        """Run `run`'s latest scan: its time (s), origin (3,) and hits (rays, 3) world m, views
        that the next scan overwrites (float32, NaN: dropped or missed); None before the first."""
        if not self.count:
            return None
        slot = (self.count - 1) % LOG_BLOCK if self.keep else 0
        return self._times[-1], self._origins[-1][slot, run], self._hits[-1][slot, run]

    def share(self, run: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Run `run`'s scans: t (n,), origin (n, 3), hits (n, rays, 3)."""
        n = self.count
        origins = np.concatenate([block[:, run] for block in self._origins])[:n] if n else np.empty((0, 3))
        hits = np.empty((n, self.rays, 3), dtype=np.float32)
        for b, block in enumerate(self._hits):
            start = b * LOG_BLOCK
            end = min(start + LOG_BLOCK, n)
            hits[start:end] = block[: end - start, run]
        return np.array(self._times), origins, hits


@dataclass
class ScanRecord:
    """One run's scans and the pile it knew from them at the end (the module's docstring)."""

    t: np.ndarray  # (n,) s
    origin: np.ndarray  # (n, 3) world m
    hits: np.ndarray  # (n, rays, 3) world m, float32, NaN: dropped or missed
    scanner: np.ndarray | None  # (n,) names, with several scanners
    x: np.ndarray  # grid lines, m
    y: np.ndarray
    z: np.ndarray  # (ny, nx) m, NaN: unknown
    seen: np.ndarray  # (ny, nx) hits
    last_seen: np.ndarray  # (ny, nx) s, NaN: never
    t_end: float = np.nan  # s: the time of z, seen and last_seen
    plan_start: KnownPile | None = None  # the pile known as the benches were planned, after a survey

    @classmethod
    def of(cls, scanners: Sequence, shares: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], x: np.ndarray,
           y: np.ndarray, end: KnownPile, plan_start: KnownPile | None = None) -> ScanRecord:
        """From each scanner's share of a run's scans (ScanLog.share), merged in time order."""
        if len(shares) == 1:
            (t, origin, hits), names = shares[0], None
        else:
            rays = max(share[2].shape[1] for share in shares)
            t = np.concatenate([share[0] for share in shares])
            order = np.argsort(t, kind="stable")  # scans of one period in the scanners' order
            origin = np.concatenate([share[1] for share in shares])[order]
            hits = np.concatenate([np.pad(share[2], ((0, 0), (0, rays - share[2].shape[1]), (0, 0)),
                                          constant_values=np.nan) for share in shares])[order]
            names = np.concatenate([np.full(len(share[0]), s.name) for s, share in zip(scanners, shares)])[order]
            t = t[order]
        return cls(t, origin, hits, names, x, y, end.z, end.seen, end.last_seen, end.time, plan_start)

    def write(self, folder: Path) -> None:
        """scans.npz and survey.npz in `folder`."""
        scans = {"t": self.t, "origin": self.origin, "hits": self.hits}
        if self.scanner is not None:
            scans["scanner"] = self.scanner
        np.savez(folder / SCANS_FILE, **scans)  # uncompressed: noisy float32 hardly compresses, and fast
        known = {"z": self.z, "seen": self.seen, "last_seen": self.last_seen, "t_end": self.t_end}
        if self.plan_start is not None:
            p = self.plan_start
            known |= {"z_plan": p.z, "seen_plan": p.seen, "last_seen_plan": p.last_seen, "t_plan": p.time}
        np.savez_compressed(folder / SURVEY_FILE, x=self.x, y=self.y, **known)


@dataclass(frozen=True)
class KnownPile:
    """A run's scanned pile at one time: heights (ny, nx) m (NaN: unknown), hits per cell and
    each cell's last-seen time (s, NaN: never)."""

    time: float  # s
    z: np.ndarray
    seen: np.ndarray
    last_seen: np.ndarray
