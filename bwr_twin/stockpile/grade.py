"""The grade of the material arriving to be stacked, as it varies in time: a first-order
autoregressive (AR(1)) stream from a seed, or a recorded one read from a CSV file.

Both answer `at(t)`: the grade (a number such as Fe %) at t seconds, for a float or an array.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bwr_twin.config.bounds import GRADE_ANY
from bwr_twin.errors import SceneError, shown_text
from bwr_twin.textfile import read_text
from bwr_twin.values import reads_as_number

_BLOCK = 4096  # AR(1) values drawn at a time: the values never depend on how they were asked for


def tonne_weighted(tonnes: np.ndarray, grade: np.ndarray) -> tuple[float, float]:
    """The mean and the standard deviation of `grade`, each value weighted by its `tonnes`; NaN
    for no tonnes."""
    total = float(np.sum(tonnes))
    if not total > 0:
        return float("nan"), float("nan")
    mean = float(np.sum(tonnes * grade) / total)
    return mean, rms_from(tonnes, grade, mean)


def rms_from(tonnes: np.ndarray, grade: np.ndarray, reference: float) -> float:
    """The tonne-weighted root mean square of `grade` from `reference`: about the grade's own mean
    its spread, about another the spread and the mean's offset together; NaN for no tonnes."""
    total = float(np.sum(tonnes))
    return float(np.sqrt(np.sum(tonnes * (grade - reference) ** 2) / total)) if total > 0 else float("nan")


def lots(tonnes: np.ndarray, grade: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The tonnes and the tonne-weighted grade of lots of `size` discharges in a row (a minute's,
    as a sampler cuts lots); the discharges after the last whole lot are left out."""
    count = len(tonnes) // size
    mass = tonnes[:count * size].reshape(count, size).sum(axis=1)
    return mass, (tonnes * grade)[:count * size].reshape(count, size).sum(axis=1) / mass


class Ar1Grade:
    """A stationary AR(1) grade, one value a `period` s, held over it:
    g[k] = mean + phi (g[k-1] - mean) + sd sqrt(1 - phi^2) e[k], phi = exp(-period / correlation_time),
    e[k] standard normal from numpy's Generator seeded with `seed`, and g[0] = mean + sd e[0], so
    every g[k] has the given mean and standard deviation and g[k], g[k+j] correlate as phi^j: the
    correlation falls to 1/e over `correlation_time` s. A correlation time of 0 gives independent
    values (phi = 0). The same seed gives the same stream, however it is queried.
    """

    def __init__(self, mean: float, sd: float, correlation_time: float, period: float, seed: int):
        if not sd >= 0 or not correlation_time >= 0 or not period > 0:
            raise ValueError(f"an AR(1) grade needs sd >= 0, correlation_time >= 0 s and period > 0 s, got "
                             f"{sd}, {correlation_time} and {period}")
        self.mean, self.sd, self.correlation_time, self.period = mean, sd, correlation_time, period
        self.phi = math.exp(-period / correlation_time) if correlation_time > 0 else 0.0
        self._innovation = sd * math.sqrt(1.0 - self.phi**2)
        self._random = np.random.default_rng(seed)
        self._values = np.empty(_BLOCK)  # g[0] ... g[self._count - 1], then room for more
        self._count = 0
        self._deviation = math.nan  # g[self._count - 1] - mean

    def series(self, count: int) -> np.ndarray:
        """The first `count` values, g[0] ... g[count - 1]."""
        return self._first(count).copy()

    def at(self, t: float | np.ndarray) -> float | np.ndarray:
        """The grade at t s (>= 0): the value of the period t falls in."""
        index = np.floor(np.asarray(t, dtype=float) / self.period)
        if np.any(index < 0) or not np.all(np.isfinite(index)):
            raise ValueError("an AR(1) grade starts at t = 0 s: t must be finite and >= 0")
        values = self._first(int(index.max()) + 1)[index.astype(np.int64)]
        return float(values) if values.ndim == 0 else values

    def _first(self, count: int) -> np.ndarray:
        """A view of g[0] ... g[count - 1], drawing more blocks as needed."""
        while self._count < count:
            if self._count + _BLOCK > len(self._values):
                self._values = np.concatenate([self._values, np.empty(len(self._values))])
            noise = self._random.standard_normal(_BLOCK)
            deviation = self._deviation
            for k in range(_BLOCK):
                if self._count + k == 0:
                    deviation = self.sd * noise[0]  # from the stationary distribution
                else:
                    deviation = self.phi * deviation + self._innovation * noise[k]
                self._values[self._count + k] = self.mean + deviation
            self._count += _BLOCK
            self._deviation = deviation
        return self._values[:count]


class RecordedGrade:
    """A recorded grade: rows (t s, grade) of a CSV file, t strictly increasing.

    `interpolation` "step" holds each row's grade until the next row's time (an analyser's or a
    sample's value standing for the interval it starts); "linear" draws straight lines between
    rows. Outside the first and last rows' times there is no grade: ValueError.
    """

    def __init__(self, file: Path, interpolation: str = "step"):
        if interpolation not in ("step", "linear"):
            raise ValueError(f"interpolation must be 'step' or 'linear', got {interpolation!r}")
        self.file, self.interpolation = Path(file), interpolation
        self.t, self.grade = _read_rows(self.file)

    def at(self, t: float | np.ndarray) -> float | np.ndarray:
        """The grade at t s, within the record."""
        t = np.asarray(t, dtype=float)
        if np.any(~(t >= self.t[0]) | ~(t <= self.t[-1])):
            raise ValueError(f"{self.file}: records the grade from t = {self.t[0]:g} s to {self.t[-1]:g} s; "
                             f"asked at t = {float(np.min(t)):g} to {float(np.max(t)):g} s")
        if self.interpolation == "linear":
            values = np.interp(t, self.t, self.grade)
        else:
            values = self.grade[np.searchsorted(self.t, t, side="right") - 1]
        return float(values) if values.ndim == 0 else values


def _read_rows(file: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t, grade) of a CSV file of rows t,grade, a header line allowed; SceneError naming the file,
    line and column of the first bad row."""
    try:
        text = read_text(file)
    except (OSError, UnicodeDecodeError) as exc:
        raise SceneError(f"{file}: cannot read the recorded grade ({exc})") from None
    lines = [(number, line) for number, line in enumerate(text.split("\n"), start=1)
             if line.strip() and not line.lstrip().startswith("#")]
    if lines and not reads_as_number(lines[0][1].split(",")[0]):
        lines = lines[1:]  # a header line
    t, grade = [], []
    for number, line in lines:
        cells = [cell.strip() for cell in line.split(",")]
        if len(cells) != 2:
            raise SceneError(f"{file}: line {number} must be two numbers t,grade (s, grade), "
                             f"got {shown_text(line.strip())}")
        for column, (name, cell) in enumerate(zip(("t", "grade"), cells), start=1):
            if not reads_as_number(cell) or not math.isfinite(float(cell)):
                raise SceneError(f"{file}: line {number}, column {column} ({name}): {shown_text(cell)} "
                                 "is not a finite number")
        if t and not float(cells[0]) > t[-1]:
            raise SceneError(f"{file}: line {number}, column 1 (t): {cells[0]} s does not follow "
                             f"{t[-1]:g} s: t must increase")
        if abs(float(cells[1])) > GRADE_ANY[1]:
            raise SceneError(f"{file}: line {number}, column 2 (grade): {cells[1]} lies beyond +-{GRADE_ANY[1]:g}: "
                             "a grade is a content, a share, a percentage or ppm of the stream (GRADE_ANY)")
        t.append(float(cells[0]))
        grade.append(float(cells[1]))
    if not t:
        raise SceneError(f"{file}: holds no rows t,grade")
    return np.array(t), np.array(grade)
