"""Scheduled faults in the loop: what a failing sensor or drive does to every run of a lockstep.

The runs of a lockstep share the scene's fault schedule (bwr_twin.config.faults) and differ in
their seeds. A fault acts in control period k (time k x period) when start <= k x period <
start + duration, to within 1e-9 of a period (the rounding of k x period, as
bwr_twin.sim.disturbances allows); each fault's first and last period are worked out once, so a
period in which no fault acts costs a few integer comparisons. A scene without faults builds an
inactive `Faults`, and the loop then calls none of it: such scenes run as before, to the bit.

The encoder faults act on the readings in the scene's order, travel in m and slew and luff in
rad (the scene's degrees converted here); late inputs then replace the readings with those of
earlier periods, kept in a ring buffer no longer than the longest delay. Noise comes from each
run's own stream (bwr_twin.streams: Stream.FAULT), one grandchild per fault, one standard normal per period the
fault acts, so a run's numbers depend on its seed alone and not on the runs beside it.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence

import numpy as np

from bwr_twin.config.faults import FAULT_AXES, FaultSection
from bwr_twin.sensing.noise import PeriodNormals
from bwr_twin.streams import Stream

_TOLERANCE = 1e-9  # of a period: k x period within it of a boundary is on it
_NEVER = sys.maxsize  # the last period of a fault that lasts to the run's end
_ENCODER_KINDS = ("encoder_stuck", "encoder_dropout", "encoder_drift", "encoder_noise")
# Per axis, what one unit of the scene's rate or sigma is in the twin's units: m; deg -> rad.
_TO_TWIN = np.array([1.0 if axis == "travel" else math.radians(1.0) for axis in FAULT_AXES])


def fault_periods(fault: FaultSection, period: float) -> tuple[int, int]:
    """The first and last control period (inclusive) in which the fault acts; the last is
    sys.maxsize for a fault without a duration, and below the first for one that never acts."""
    first = max(0, math.ceil(fault.start / period - _TOLERANCE))
    if fault.duration is None:
        return first, _NEVER
    return first, math.ceil((fault.start + fault.duration) / period - _TOLERANCE) - 1


def ramp_periods(fault: FaultSection, period: float) -> int:
    """The control periods a plant fault takes to reach its full size; 0: a step."""
    return max(0, round((fault.ramp or 0.0) / period))


def grown(periods_in: int, ramp: int) -> float:
    """The share of its full size a plant fault has `periods_in` periods after its first."""
    return 1.0 if periods_in >= ramp else (periods_in + 1) / ramp


class _EncoderFault:
    """An encoder fault, scheduled: its axis's column and its rate or sigma in m or rad."""

    def __init__(self, fault: FaultSection, index: int, period: float, seeds: Sequence[int]):
        self.kind = fault.kind
        self.start = fault.start  # s
        self.first, self.last = fault_periods(fault, period)
        self.axis = FAULT_AXES.index(fault.axis)
        self.rate = (fault.rate or 0.0) * _TO_TWIN[self.axis]  # m/s or rad/s
        self.sigma = (fault.sigma or 0.0) * _TO_TWIN[self.axis]  # m or rad
        self.held: np.ndarray | None = None  # (runs,) the stuck position, from the first period it acts
        # a draw a period it acts, the first its 0th: the same whenever it starts
        self.noise = PeriodNormals(seeds, Stream.FAULT, index) if fault.kind == "encoder_noise" else None

    def apply(self, k: int, period: float, q: np.ndarray, qd: np.ndarray) -> None:
        j = self.axis
        if self.kind == "encoder_stuck":
            if self.held is None:
                self.held = q[:, j].copy()
            q[:, j] = self.held
            qd[:, j] = 0.0
        elif self.kind == "encoder_dropout":
            q[:, j] = 0.0
            qd[:, j] = 0.0
        elif self.kind == "encoder_drift":
            q[:, j] += self.rate * (k * period - self.start)
            qd[:, j] += self.rate
        else:
            q[:, j] += self.sigma * self.noise.at(k - self.first)


class Faults:
    """Every fault of a scene, for the runs of a lockstep.

    Attributes:
        active: False when the scene has no faults: the loop then skips every call.
    """

    def __init__(self, faults: tuple[FaultSection, ...], seeds: Sequence[int], period: float):
        """`seeds` each run's seed, `period` the control period in s."""
        self.active = bool(faults)
        self.faults = tuple(faults)
        self._windows = [fault_periods(f, period) for f in faults]
        self._period = period
        self._runs = len(seeds)
        self._encoder = [_EncoderFault(f, i, period, seeds) for i, f in enumerate(faults) if f.kind in _ENCODER_KINDS]
        self._encoder_span = _span([(e.first, e.last) for e in self._encoder])
        self._trips = [(FAULT_AXES.index(f.axis), *fault_periods(f, period)) for f in faults if f.kind == "drive_trip"]
        self._derates = [(FAULT_AXES.index(f.axis), *fault_periods(f, period), f.percent / 100.0,
                          ramp_periods(f, period)) for f in faults if f.kind == "drive_derate"]
        self._blinded = [(f.scanner, *fault_periods(f, period)) for f in faults if f.kind == "scanner_blinded"]
        self._frozen = [fault_periods(f, period) for f in faults if f.kind == "belt_scale_frozen"]
        self._late = _LateInputs([(f.periods, *fault_periods(f, period)) for f in faults if f.kind == "late_inputs"],
                                 self._runs)

    def measured(self, k: int, q_measured: np.ndarray, qd_measured: np.ndarray) -> None:
        """Apply the encoder faults and the late inputs of period k to the (runs, 3) readings
        (m, rad, rad; m/s, rad/s, rad/s), in place. Call once a period, in order."""
        first, last = self._encoder_span
        if first <= k <= last:
            for fault in self._encoder:
                if fault.first <= k <= fault.last:
                    fault.apply(k, self._period, q_measured, qd_measured)
        first, last = self._late.record_span
        if first <= k <= last:
            self._late.apply(k, q_measured, qd_measured)

    def command(self, k: int, command: np.ndarray) -> None:
        """Zero the drive force of every tripped axis in the (runs, 3) command of period k, and
        scale down every derated one's, in place: the drive delivers that share of its command."""
        for axis, first, last, share, ramp in self._derates:
            if first <= k <= last:
                command[:, axis] *= 1.0 - share * grown(k - first, ramp)
        for axis, first, last in self._trips:
            if first <= k <= last:
                command[:, axis] = 0.0

    def scanner_blinded(self, k: int, name: str) -> bool:
        """Whether dust blinds scanner `name` in period k: its rays return nothing."""
        return any(first <= k <= last and scanner in (None, name) for scanner, first, last in self._blinded)

    def acting(self, k: int) -> list[bool]:
        """Whether each fault, in the scene's order, acts in period k: its state, as a SCADA shows it."""
        return [first <= k <= last for first, last in self._windows]

    def scale_frozen(self, k: int) -> bool:
        """Whether the belt scale's reading is frozen in period k."""
        return any(first <= k <= last for first, last in self._frozen)


class _LateInputs:
    """The `late_inputs` faults: the readings of the last periods kept in a ring, and handed over late.

    Attributes:
        record_span: the first and last period whose readings are recorded: from `periods` before
            a fault's first period, to its last.
    """

    def __init__(self, late: list[tuple[int, int, int]], runs: int):
        """`late`: (periods of delay, first, last period) per fault."""
        self._late = late
        longest = max((periods for periods, _, _ in late), default=0)
        self.record_span = _span([(max(0, first - periods), last) for periods, first, last in late])
        self._ring_q = np.zeros((longest + 1, runs, 3))
        self._ring_qd = np.zeros((longest + 1, runs, 3))
        self._ring_period = np.full(longest + 1, -1, dtype=np.int64)  # the period each row holds

    def apply(self, k: int, q: np.ndarray, qd: np.ndarray) -> None:
        """Record period k's readings; if late inputs act, hand over those of the longest delay
        among them instead."""
        rows = len(self._ring_period)
        row = k % rows
        self._ring_q[row] = q
        self._ring_qd[row] = qd
        self._ring_period[row] = k
        delay = max((periods for periods, first, last in self._late if first <= k <= last), default=0)
        if not delay:
            return
        source = max(k - delay, 0)  # before period 0, period 0's readings
        if self._ring_period[source % rows] != source:
            raise RuntimeError(f"late inputs of period {k} need period {source}'s readings, which were not "
                               "recorded: call measured() every period, in order")
        q[:] = self._ring_q[source % rows]
        qd[:] = self._ring_qd[source % rows]


def _span(windows: list[tuple[int, int]]) -> tuple[int, int]:
    """The first and last period of any of the windows; (0, -1), holding none, without windows."""
    if not windows:
        return 0, -1
    return min(first for first, _ in windows), max(last for _, last in windows)
