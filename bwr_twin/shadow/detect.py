"""Fault detection and isolation on the shadow's residuals: one GLR test per fault hypothesis.

Each hypothesis (a class on an axis) says how its fault would move a residual: its signature
(bwr_twin.shadow.twin). Block by block, and for every onset within the last WINDOW blocks, the
generalised likelihood ratio of "the residual is the signature times a size since that onset"
against "the residual is noise" is (sum r s)^2 / sum s^2, the residuals and signatures divided
by the residual's noise, learned per axis from a fault-free log. Its largest value over the
onsets is the hypothesis's statistic, the onset and size that give it the alarm's onset and
size. The size a fault seems to have on the fault-free log is taken off first: a drive's force
follows the disturbances its controller fights, so a fault-free machine looks a few per cent
derated. A fault is detected when any statistic exceeds its
threshold; ISOLATE blocks later it is isolated to the hypothesis whose statistic is then the
largest (the most likely: the fault that best explains what the residuals did). Each class and
axis is raised once, and a change that began before the last alarm is the fault that alarm named.

A stuck encoder is decided without a test, by where its reading allows the axis to be. A
reading changes as the axis crosses a boundary between two counts, so from its last change on,
while it stays the same, the axis is within one count beyond that boundary in the way it
crossed it: by its drive's speed feedback, an axis that moves back across the boundary, or on
past the next one, has an encoder that no longer counts. Where the reading has not changed since
the log began (or a gap), the axis is somewhere within its count, and more than a count of
motion either way is needed. The motion is counted from the reading's last change, within a
block and across the blocks it stays unchanged through, and is allowed a margin learned from
the fault-free logs (the speed feedback's error, a coupling's play; at least STUCK_FLOOR of a
count). Off for an encoder the fault-free logs never saw step: its count is unknown.

Thresholds: a threshold for `per_hour` false alarms per hour makes one test of the WINDOW onsets
each block as unlikely to exceed it as the hours ask (Bonferroni over the tests of an hour, on
the GLR's chi-squared law with one degree of freedom), and at least MARGIN times the largest the
fault-free logs themselves gave: what the law misses of the real residuals (slow biases of the
model at places of the machine's work), the logs show, and the more of the machine's usual work
they hold, the more of it they show.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from bwr_twin.errors import BwrError
from bwr_twin.shadow.twin import BLOCK, UNIT_MASS, Blocks

AXES = ("travel", "slew", "luff")
SOURCES = (*AXES, "wheel end")  # what an alarm names: an axis, or the wheel end (a mass change)
UNITS = ("m", "rad", "rad")
WINDOW = 120  # blocks: the longest a fault's onset is looked back for
# The GLR's drop from its best onset that still leaves an onset possible: chi-squared with one
# degree of freedom at 95 %, the likelihood set of the change time with the size at its best.
ONSET_DROP = float(chi2.ppf(0.95, 1))
# How close another hypothesis's statistic may come to the best one's and still be named beside
# it: the same 95 % of a chi-squared with one degree of freedom, each with its size at its best.
ALTERNATIVE_DROP = ONSET_DROP
MARGIN = 1.5  # a threshold is at least this times the largest statistic of the fault-free log
ISOLATE = 5  # blocks between a fault's detection and its isolation
RATE_TOLERANCE = 1.25  # the watched samples' period may be this much shorter or longer than the learned one
STUCK_FLOOR = 0.1  # of an encoder count: the least margin beyond its count an unchanged reading allows
# The classes, what each means for maintenance (docs/shadow.md), and which way its size goes.
CLASSES = {
    "friction_rise": "a bearing, gearbox or bogie seizing: inspect and lubricate the axis",
    "drive_derate": "the drive delivers less than it says: check the motor, the converter and the brake",
    "mass_change": "material caked at the wheel end: clean the wheel and the boom",
    "encoder_drift": "the position encoder slips or drifts against the drive's speed: re-reference it",
    "stuck_encoder": "the position encoder reads no motion while the axis moves: replace it or its coupling",
}


@dataclass(frozen=True)
class Thresholds:
    """What a fault-free log taught: per axis the noise of the force residual (N, N m) and of
    the drift residual (m/s, rad/s), their means, the encoder counts and the margin beyond them
    the stuck test allows (m, rad; None for an encoder the log never saw step: its stuck test is
    off), the GLR threshold of each hypothesis, for `per_hour` false alarms an hour, and the
    period of the samples learned on (s): a block's noise depends on how many samples it holds."""

    per_hour: float
    force_mean: list[float]
    force_sigma: list[float]
    drift_mean: list[float]
    drift_sigma: list[float]
    counts: list[float | None]
    stuck_margin: list[float | None]
    thresholds: dict[str, float]
    bias: dict[str, float]
    sample_s: float
    block_s: float = BLOCK
    window_blocks: int = WINDOW

    def write(self, path: Path) -> None:
        path.write_text(json.dumps(asdict(self), indent=1) + "\n")

    @classmethod
    def read(cls, path: Path) -> Thresholds:
        try:
            data = json.loads(path.read_text())
            thresholds = cls(**data)
        except (OSError, ValueError, TypeError) as exc:
            raise BwrError(f"{path}: not a shadow's thresholds file, or one an earlier version learned ({exc}): "
                           "learn them again with --baseline") from None
        _check_values(path, thresholds)
        if thresholds.block_s != BLOCK or thresholds.window_blocks != WINDOW:
            raise BwrError(f"{path}: thresholds learned with blocks of {thresholds.block_s} s and a window of "
                           f"{thresholds.window_blocks}, this shadow uses {BLOCK} s and {WINDOW}: learn them again")
        return thresholds


def _check_values(path: Path, t: Thresholds) -> None:
    """BwrError naming the key of a thresholds file whose value is not what the shadow learns:
    three finite numbers per axis (None where an encoder's count is unknown), finite numbers by
    hypothesis, a positive rate."""
    def number(value, nullable: bool = False) -> bool:
        return (value is None and nullable) or (isinstance(value, (int, float)) and not isinstance(value, bool)
                                                and math.isfinite(value))

    for key in ("force_mean", "force_sigma", "drift_mean", "drift_sigma", "counts", "stuck_margin"):
        value = getattr(t, key)
        if not (isinstance(value, list) and len(value) == 3
                and all(number(v, key in ("counts", "stuck_margin")) for v in value)):
            raise BwrError(f"{path}: {key} must be three finite numbers, one per axis, got {value!r}")
    for key in ("thresholds", "bias"):
        value = getattr(t, key)
        if not (isinstance(value, dict) and all(number(v) for v in value.values())):
            raise BwrError(f"{path}: {key} must map each hypothesis to a finite number, got {value!r}")
    for key in ("per_hour", "sample_s"):
        if not (number(getattr(t, key)) and getattr(t, key) > 0):
            raise BwrError(f"{path}: {key} must be a number > 0, got {getattr(t, key)!r}")


@dataclass(frozen=True)
class Alarm:
    """A fault found: its class and axis ("wheel end" for a mass change), the time it was raised,
    its estimated onset and size (`size` in `unit`; a stuck encoder's, how far the axis moved
    unseen when it was raised), and the statistic against its threshold (a stuck encoder's: how
    far the axis went beyond where the reading allows it, against the learned margin, m or rad).

    Of a fault found by its GLR test, `onset_range_s`: the earliest and the latest onset (s) the
    residuals leave possible at 95 % (ONSET_DROP). While the fault's axis does nothing that shows
    it (a derate while its drive barely pushes), the range spans that time. None for a stuck
    encoder, which is seen, not estimated.

    `alternatives`: the other faults ("travel drive_derate") that explain the residuals nearly as
    well when it is raised (ALTERNATIVE_DROP): where two signatures run alike (a drive that
    delivers less, and friction that takes more, while the axis moves steadily) the data cannot
    yet tell them apart, and the alarm says so rather than guess."""

    kind: str
    axis: str
    time_s: float
    onset_s: float
    size: float
    unit: str
    statistic: float
    threshold: float
    onset_range_s: tuple[float, float] | None = None
    alternatives: tuple[str, ...] = ()

    def estimate(self) -> str:
        """'+35 % since 102.0 s (possibly 98.0 to 104.0 s)': the size and the onset, with the
        onsets possible where there is more than one."""
        since = f"since {self.onset_s:.1f} s"
        if self.onset_range_s is not None and self.onset_range_s[0] < self.onset_range_s[1]:
            since += f" (possibly {self.onset_range_s[0]:.1f} to {self.onset_range_s[1]:.1f} s)"
        return f"{self.size:+.3g} {self.unit} {since}"

    def undecided(self) -> str:
        """' (or slew drive_derate: not told apart yet)', or '' where the alarm has no alternative."""
        return f" (or {' or '.join(self.alternatives)}: not told apart yet)" if self.alternatives else ""

    def describe(self) -> str:
        """'slew friction_rise +35 % since 102.0 s (possibly 98.0 to 104.0 s) (raised at 140.0 s): ...'."""
        return (f"{self.axis} {self.kind} {self.estimate()}{self.undecided()} (raised at {self.time_s:.1f} s): "
                f"{CLASSES[self.kind]}")

    def event(self) -> dict:
        return {"event": "alarm", **asdict(self), "meaning": CLASSES[self.kind]}


@dataclass(frozen=True)
class _Hypothesis:
    kind: str
    axis: int  # -1: every axis (a mass change)
    sided: bool  # True: only a positive size is this fault

    @property
    def source(self) -> str:
        """What its alarm names: the axis, or the wheel end (SOURCES)."""
        return SOURCES[self.axis]


HYPOTHESES = tuple([_Hypothesis(kind, j, sided) for j in range(3)
                    for kind, sided in (("friction_rise", True), ("drive_derate", True), ("encoder_drift", False))]
                   + [_Hypothesis("mass_change", -1, False)])


def _name(h: _Hypothesis) -> str:
    return f"{h.kind}:{h.source.replace(' ', '_')}"


def _whitened(blocks: Blocks, t: Thresholds, h: _Hypothesis) -> tuple[np.ndarray, np.ndarray]:
    """(residual, signature) of a hypothesis, each (blocks,) in units of the noise, the
    fault-free machine's share (of `_raw`'s third) taken off the residual."""
    r, s, biased = _raw(blocks, t, h)
    return r - t.bias.get(_name(h), 0.0) * biased, s


def _raw(blocks: Blocks, t: Thresholds, h: _Hypothesis) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(residual, signature, what the fault-free machine's bias is a share of) of a hypothesis,
    each (blocks,) (or (blocks x 3,) for every axis) in units of the noise. A drive's bias is a
    share of the force that moves its axis, the drive's and the wind's together: the force it
    spends holding against a wind adds no bias, and counted in would dilute a share learned in
    wind and overstate one learned in still air."""
    if h.kind == "encoder_drift":
        j = h.axis
        sigma = t.drift_sigma[j]
        s = np.full(len(blocks.start), 1.0 / sigma)
        return (blocks.drift[:, j] - t.drift_mean[j]) / sigma, s, s
    sigma, mean = np.asarray(t.force_sigma), np.asarray(t.force_mean)
    r = (blocks.force - mean) / sigma
    s = {"friction_rise": blocks.friction, "drive_derate": blocks.derate, "mass_change": blocks.mass}[h.kind] / sigma
    biased = s
    if h.kind == "drive_derate" and blocks.wind is not None:
        biased = (blocks.derate - blocks.wind) / sigma  # -(drive force + wind force)
    if h.axis >= 0:
        return r[:, h.axis], s[:, h.axis], biased[:, h.axis]
    return r.ravel(), s.ravel(), biased.ravel()  # every axis: (blocks x 3,), summed by block below


def glr(r: np.ndarray, s: np.ndarray, per: int, sided: bool, start: int = 0) -> tuple[np.ndarray, np.ndarray,
                                                                                   np.ndarray]:
    """The GLR statistic, its onset (block index) and size after each block from block `start` on.

    r, s: (blocks x per,) whitened residuals and signatures, `per` entries a block. For block n,
    onsets m = n - WINDOW + 1 .. n: g = max (sum_{m..n} r s)^2 / sum s^2, over sizes > 0 if `sided`."""
    return _glr(*_sums(r, s, per), sided, start)


def _glr(crs: np.ndarray, css: np.ndarray, sided: bool, start: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`glr` from the running sums of r s and s^2 (`_sums`)."""
    n = len(crs) - 1
    g, onset, size = np.zeros(n - start), np.zeros(n - start, dtype=np.int64), np.zeros(n - start)
    for k in range(start, n):
        m, stat, theta = _profile(crs, css, k, sided)
        best = int(np.argmax(stat))
        g[k - start], onset[k - start], size[k - start] = stat[best], m[best], theta[best]
    return g, onset, size


def _sums(r: np.ndarray, s: np.ndarray, per: int) -> tuple[np.ndarray, np.ndarray]:
    """The running sums of r s and of s^2 by block, from 0."""
    rs = (r * s).reshape(-1, per).sum(axis=1)
    ss = (s * s).reshape(-1, per).sum(axis=1)
    return np.concatenate([[0.0], np.cumsum(rs)]), np.concatenate([[0.0], np.cumsum(ss)])


def _profile(crs: np.ndarray, css: np.ndarray, k: int, sided: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """At block k, per onset m within WINDOW: (m, the statistic, the size)."""
    m = np.arange(max(0, k - WINDOW + 1), k + 1)
    num, den = crs[k + 1] - crs[m], css[k + 1] - css[m]
    with np.errstate(divide="ignore", invalid="ignore"):
        theta = np.where(den > 0, num / den, 0.0)
        stat = np.where(den > 0, num * theta, 0.0)
    if sided:
        stat = np.where(theta > 0, stat, 0.0)
    return m, stat, theta


def learn(logs: Sequence[Blocks], counts: np.ndarray, per_hour: float) -> Thresholds:
    """Thresholds from the blocks of fault-free logs of one machine, whose encoders count in
    `counts` (3,) (m, rad), for `per_hour` false alarms per hour. Each log's statistics are its
    own (no onset window spans two logs); the noise and the biases are the logs' together."""
    blocks = _joined(logs)
    if len(blocks.start) < 30:
        raise BwrError(f"a fault-free log of {len(blocks.start)} whole blocks of {BLOCK:g} s: the noise needs 30 "
                       "at least")
    if not (per_hour > 0):
        raise BwrError(f"--false-alarms-per-hour must be > 0, got {per_hour}")
    counts = [float(c) if np.isfinite(c) else None for c in counts]  # None: never seen to step
    stuck_margin = [None if c is None else max(STUCK_FLOOR * c, MARGIN * float(b))
                    for c, b in zip(counts, beyond_readings(blocks, counts))]
    base = Thresholds(per_hour, blocks.force.mean(0).tolist(), _sigma(blocks.force), blocks.drift.mean(0).tolist(),
                      _sigma(blocks.drift, floor=_known(counts) / BLOCK / math.sqrt(6)), counts, stuck_margin, {}, {},
                      sample_period(blocks))
    bias = {}
    for h in HYPOTHESES:  # the size each fault seems to have on the fault-free machine: its controller's share
        r, _, biased = _raw(blocks, base, h)
        bias[_name(h)] = float((r * biased).sum() / max((biased * biased).sum(), 1e-300))
    base = Thresholds(**{**asdict(base), "bias": bias})
    tests_per_hour = 3600.0 / BLOCK * WINDOW * len(HYPOTHESES)
    law = float(chi2.isf(per_hour / tests_per_hour, 1))
    thresholds = {}
    for h in HYPOTHESES:
        largest = max(glr(*_whitened(log, base, h), 3 if h.axis < 0 else 1, h.sided)[0].max(initial=0.0)
                      for log in logs)
        thresholds[_name(h)] = max(law, MARGIN * float(largest))
    return Thresholds(**{**asdict(base), "thresholds": thresholds})


def _joined(logs: Sequence[Blocks]) -> Blocks:
    """The blocks of several logs as one series (for their noise and biases)."""
    if len(logs) == 1:
        return logs[0]

    def joined(name: str):
        parts = [getattr(log, name) for log in logs]
        return None if any(part is None for part in parts) else np.concatenate(parts)

    return Blocks(**{f.name: joined(f.name) for f in fields(Blocks)})


def _known(counts: list[float | None]) -> np.ndarray:
    """The counts as an array, 0 where unknown."""
    return np.array([c or 0.0 for c in counts])


def _sigma(values: np.ndarray, floor: np.ndarray | None = None) -> list[float]:
    sigma = values.std(axis=0)
    sigma = np.maximum(sigma, 1e-12 if floor is None else np.maximum(floor, 1e-12))
    return sigma.tolist()


def detect(blocks: Blocks, t: Thresholds) -> list[Alarm]:
    """The alarms over the log's blocks, each class and axis raised once, in time order."""
    return assess(blocks, t)[0]


def assess(blocks: Blocks, t: Thresholds, known: list | None = None, *, complete: bool = True,
           earlier: Sequence[Alarm] = ()) -> tuple[list[Alarm], dict[str, float]]:
    """The alarms over the log's blocks (as `detect`) and the health of each of SOURCES after the
    newest block, in %: 100 less 100 times the largest statistic of its hypotheses against its
    threshold, 0 at a threshold and below; 0 once an alarm named it.

    `known`: a list kept between calls over a growing series of blocks (live), which holds the
    statistics of the blocks seen so far, so that each call computes only the new blocks'.
    `complete`: the blocks are the whole log; False (live), a fault detected fewer than ISOLATE
    blocks ago is not isolated yet, so that live and offline name it on the same evidence.
    `earlier`: the alarms already raised (live, where the older blocks are no longer kept): none
    is raised again, a change that began before the last is the fault it named, a stuck
    encoder's axis stays blind, and the health of what they named stays 0."""
    if not len(blocks.start):
        return [], dict.fromkeys(SOURCES, 100.0)
    _check_rate(blocks, t)
    alarms = _stuck(blocks, t)
    # After an encoder sticks its axis's residuals, and the wheel end's, say only that it is stuck.
    blind: dict[int, float] = {}
    for a in [*earlier, *alarms]:
        if a.kind == "stuck_encoder":
            blind[AXES.index(a.axis)] = min(blind.get(AXES.index(a.axis), math.inf), a.time_s)
    ratios, found, sums = [], [], []
    for i, h in enumerate(HYPOTHESES):
        sums.append(_sums(*_whitened(blocks, t, h), 3 if h.axis < 0 else 1))
        before = known[i] if known else (np.zeros(0), np.zeros(0, dtype=np.int64), np.zeros(0))
        new = _glr(*sums[-1], h.sided, start=len(before[0]))
        g, onset, size = (np.concatenate([a, b]) for a, b in zip(before, new))
        ratios.append(g / t.thresholds[_name(h)])
        found.append((g, onset, size))
    if known is not None:
        known[:] = found
    ratios = np.array(ratios)  # (hypotheses, blocks)
    stats = np.array([g for g, _, _ in found])
    # s: the last alarm's time; a change that began before it is the fault it named
    raised_at = max((a.time_s for a in earlier), default=-math.inf)
    raised = {f"{a.kind}:{a.axis.replace(' ', '_')}" for a in earlier}  # each class and axis is raised once
    last = len(blocks.start) - 1
    for k in np.flatnonzero(ratios.max(axis=0) > 1):
        k = _isolated_at(int(k), last, complete)
        if k is None:
            break  # live: isolated once the blocks it waits for have come
        best = int(np.argmax(stats[:, k]))
        h = HYPOTHESES[best]
        g, onset, size = (a[k] for a in found[best])
        after_stuck = min((blind[j] for j in ([h.axis] if h.axis >= 0 else blind) if j in blind), default=math.inf)
        if blocks.start[onset] > raised_at and _name(h) not in raised and blocks.end[k] < after_stuck:
            raised_at = float(blocks.end[k])
            raised.add(_name(h))
            alternatives = tuple(f"{other.source} {other.kind}" for i, other in enumerate(HYPOTHESES) if i != best
                                 and stats[i, k] >= g - ALTERNATIVE_DROP and ratios[i, k] > 1)
            alarms.append(_alarm(blocks, t, h, sums[best], k, int(onset), float(size), float(g), alternatives))
    health = {}
    for j, source in enumerate(SOURCES):
        worst = max(ratios[i, -1] for i, h in enumerate(HYPOTHESES) if h.axis == (j if j < 3 else -1))
        named = any(a.axis == source for a in [*earlier, *alarms])
        health[source] = 0.0 if named else 100.0 * max(0.0, 1.0 - float(worst))
    return sorted(alarms, key=lambda a: a.time_s), health


def sample_period(blocks: Blocks) -> float:
    """s: the period of the samples the blocks are made of (their median)."""
    return float(np.median((blocks.end - blocks.start) / blocks.samples))


def _check_rate(blocks: Blocks, t: Thresholds) -> None:
    """BwrError if the blocks' samples come at another rate than the thresholds were learned at:
    fewer samples a block make its residuals noisier than the thresholds allow for, more make
    the thresholds blunt."""
    period = sample_period(blocks)
    if not t.sample_s / RATE_TOLERANCE <= period <= t.sample_s * RATE_TOLERANCE:
        raise BwrError(f"the samples come every {period * 1e3:.4g} ms, and the thresholds' sample_s says they were "
                       f"learned on samples every {t.sample_s * 1e3:.4g} ms: learn them from fault-free logs at the "
                       "rate the shadow watches (--baseline)")


def _isolated_at(detected: int, last: int, complete: bool) -> int | None:
    """The block a fault detected at block `detected` is isolated at: ISOLATE blocks on, or the
    last block of a complete log; None (live) if that block has not come yet."""
    if detected + ISOLATE <= last:
        return detected + ISOLATE
    return last if complete else None


def _alarm(blocks: Blocks, t: Thresholds, h: _Hypothesis, sums: tuple[np.ndarray, np.ndarray], k: int, onset: int,
           size: float, g: float, alternatives: tuple[str, ...]) -> Alarm:
    """The alarm of hypothesis h (its `_sums`) raised at block k: its size and onset, and the
    onsets whose statistic at block k is within ONSET_DROP of the best."""
    m, stat, _ = _profile(*sums, k, h.sided)
    possible = m[stat >= g - ONSET_DROP]
    if h.kind == "mass_change":
        scale, unit = UNIT_MASS, "kg"
    elif h.kind == "encoder_drift":
        scale, unit = (1.0 if h.axis == 0 else math.degrees(1.0)), ("m/s", "deg/s", "deg/s")[h.axis]
    else:
        scale, unit = 100.0, "%"
    return Alarm(h.kind, h.source, float(blocks.end[k]), float(blocks.start[onset]), size * scale, unit, g,
                 t.thresholds[_name(h)], (float(blocks.start[possible.min()]), float(blocks.start[possible.max()])),
                 alternatives)


def _stuck(blocks: Blocks, t: Thresholds) -> list[Alarm]:
    """An encoder whose reading has not changed while the axis, by its speed feedback, went
    further than the reading allows it (the module's docstring) by more than the learned margin."""
    alarms = []
    for j in range(3):
        if t.counts[j] is None:  # an encoder never seen to step: how far is "moved" unknown
            continue
        beyond, run, first = _unseen_runs(blocks, j, t.counts[j])
        stuck = beyond > t.stuck_margin[j]
        if stuck.any():
            k = int(np.argmax(stuck))
            alarms.append(Alarm("stuck_encoder", AXES[j], float(blocks.end[k]), float(blocks.start[first[k]]),
                                float(run[k] * (1.0 if j == 0 else math.degrees(1.0))),
                                ("m", "deg", "deg")[j], float(beyond[k]), float(t.stuck_margin[j])))
    return alarms


def beyond_readings(blocks: Blocks, counts: Sequence[float | None]) -> np.ndarray:
    """(3,) per axis the furthest it went beyond where its unchanged reading allows it over the
    blocks (m, rad; negative: it stayed that far inside; NaN for an encoder whose count is
    unknown): on fault-free logs, what the stuck test's margin is learned from."""
    return np.array([math.nan if c is None or not len(blocks.start) else float(_unseen_runs(blocks, j, c)[0].max())
                     for j, c in enumerate(counts)])


def _unseen_runs(blocks: Blocks, j: int, count: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(blocks,) of axis j: how far beyond where its unchanged reading allows it the axis went
    at most within each block (m, rad; negative: that much short of it); how far it moved since
    the reading's last change, up to the block's end; and the block that change was in. The
    motion is summed over the blocks the reading stays unchanged through and no gap precedes."""
    n = len(blocks.start)
    # A block that starts where the one before ended; not after a gap, nor at another log's start
    joined = np.concatenate([[False], np.abs(blocks.start[1:] - blocks.end[:-1]) <= 1e-9])
    stepped, unseen = blocks.stepped[:, j], blocks.unseen[:, j]
    began = (stepped != 0) | ~joined  # a new reading, or none known after a gap
    first = np.maximum.accumulate(np.where(began, np.arange(n), 0))
    summed = np.cumsum(unseen)
    before = summed - unseen - (summed - unseen)[first]  # moved since the change, to the block's start
    low, high = before + blocks.unseen_bounds[:, j, 0], before + blocks.unseen_bounds[:, j, 1]
    way = stepped[first]
    # Within one count past the boundary it crossed, the way it crossed it; or anywhere within it.
    beyond = np.where(way > 0, np.maximum(high - count, -low),
                      np.where(way < 0, np.maximum(-low - count, high), np.maximum(high, -low) - count))
    return beyond, before + unseen, first
