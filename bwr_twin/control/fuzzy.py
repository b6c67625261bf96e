"""The fuzzy part of the controller (paper Sec. 3, Table 2): the rule base's real scikit-fuzzy
definition, and a compiled evaluator fast enough for the simulation loop.

skfuzzy's `ControlSystemSimulation.compute()` costs 30-60 ms a call; 70,000 control periods
times three axes would take hours. `FuzzySurface` therefore has skfuzzy evaluate the control
surface once, on a grid over the input universes, caches that grid on disk and interpolates.

Why the interpolation is piecewise linear on four triangles per cell rather than bilinear:
with evenly spaced triangular sets, min-AND and max aggregation, the surface is smooth except
along lines where two memberships are equal. In units of the set spacing these are the lines
e = k/2 and ec = k/2 and the diagonals e +- ec = k (k an integer). A grid with an even number of
cells per set spacing puts the first on grid lines and the diagonals on cell diagonals. Cutting
each cell along both diagonals, with the cell centre (also computed by skfuzzy) as the common
vertex, keeps every kink, and the error falls with the square of the cell size. Bilinear
interpolation rounds the diagonal kinks off: on 241 x 241 points it still misses skfuzzy by
0.011 (measured), while 145 x 145 points plus centres stay within 0.0055, in less build time.
The largest errors are plain curvature near the universe ends, where the output set PB or NB
takes over quickly.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numba
import numpy as np

from bwr_twin.arrays import Member, load_npz
from bwr_twin.control.rulebase import RuleBase
from bwr_twin.errors import BwrError

# skfuzzy is imported where it is used: its import pulls in scipy and networkx (~1 s), which
# runs that only load a cached surface never need.

TARGET_GRID_POINTS = 145  # about this many per input: for 7 sets, 24 cells per set spacing (0.0417 on [-3, 3])
CACHE_ENV = "BWR_TWIN_CACHE"
_CACHE_FORMAT = 1  # bump when what the cache file holds, or how it is computed, changes
_SMALL = 16  # evaluate() hands 1-D calls up to this size with an `out` to the scalar fast path

# -- skfuzzy definition -----------------------------------------------------------------------


def build_control_system(rule_base: RuleBase) -> tuple[Any, Any, Any, Any]:
    """The rule base as a skfuzzy Mamdani system: (ControlSystem, e, ec, u).

    e and ec are `ctrl.Antecedent`s, u the `ctrl.Consequent`, each with triangular `trimf` sets;
    one `ctrl.Rule` per table entry, `&` being min-AND (np.fmin, skfuzzy's default, passed
    explicitly), u aggregated with max (skfuzzy's default accumulation) and defuzzified by
    centroid.
    """
    import skfuzzy as fuzz
    from skfuzzy import control as ctrl

    rb = rule_base
    e = ctrl.Antecedent(np.linspace(*rb.e_range, rb.input_points), "e")
    ec = ctrl.Antecedent(np.linspace(*rb.ec_range, rb.input_points), "ec")
    u = ctrl.Consequent(np.linspace(*rb.output_range, rb.output_points), "u", defuzzify_method=rb.defuzzify)
    # u.accumulation_method stays skfuzzy's default, accumulation_max: max aggregation.
    for var, (low, high) in ((e, rb.e_range), (ec, rb.ec_range), (u, rb.output_range)):
        for name, abc in zip(rb.sets, rb.term_abcs(low, high)):
            var[name] = fuzz.trimf(var.universe, abc)
    rules = [
        ctrl.Rule(e[a] & ec[b], u[out], label=f"e={a}&ec={b}", and_func=np.fmin)
        for a, row in zip(rb.sets, rb.rules)
        for b, out in zip(rb.sets, row)
    ]
    return ctrl.ControlSystem(rules), e, ec, u


_SYSTEMS: dict[str, Any] = {}


@contextlib.contextmanager
def _quiet_skfuzzy() -> Iterator[None]:
    # skfuzzy 0.5 calls np.maximum(a, b, out) positionally, which numpy >= 2.4 deprecates (the
    # result is still right); one warning per point would swamp a grid build's output and time.
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message="Passing more than 2 positional arguments", category=DeprecationWarning
        )
        yield


def skfuzzy_compute(rule_base: RuleBase, e: Any, ec: Any) -> Any:
    """skfuzzy's own answer, the slow reference: a float for scalars, else an array.

    Arrays are broadcast and evaluated in one `compute()` call. Inputs outside the universes
    are clipped to them (skfuzzy's clip_to_bounds).
    """
    from skfuzzy import control as ctrl

    key = rule_base.digest()
    if key not in _SYSTEMS:
        _SYSTEMS[key] = build_control_system(rule_base)[0]
    sim = ctrl.ControlSystemSimulation(_SYSTEMS[key], clip_to_bounds=True)
    if np.ndim(e) == 0 and np.ndim(ec) == 0:
        sim.input["e"] = float(e)
        sim.input["ec"] = float(ec)
        with _quiet_skfuzzy():
            sim.compute()
        return float(sim.output["u"])
    # skfuzzy wants both inputs as arrays of one shape; copies, so it keeps no view of ours.
    ea, eca = (np.array(a) for a in np.broadcast_arrays(np.asarray(e, float), np.asarray(ec, float)))
    if ea.size == 0:
        return np.empty(ea.shape)
    sim.input["e"] = ea
    sim.input["ec"] = eca
    with _quiet_skfuzzy():
        sim.compute()
    return np.asarray(sim.output["u"], dtype=float).reshape(ea.shape)


# -- compiled evaluator -----------------------------------------------------------------------


def default_cache_dir() -> Path:
    """$BWR_TWIN_CACHE, else $XDG_CACHE_HOME/bwr_twin, else ~/.cache/bwr_twin."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    if os.environ.get("XDG_CACHE_HOME"):
        return Path(os.environ["XDG_CACHE_HOME"]) / "bwr_twin"
    return Path.home() / ".cache" / "bwr_twin"


def _skfuzzy_version() -> str:
    from importlib.metadata import version

    return version("scikit-fuzzy")


class FuzzySurface:
    """The control surface u = FLC(e, ec) of a rule base, computed by skfuzzy and interpolated.

    Attributes:
        rule_base: what it was computed from.
        grid_e, grid_ec: the grid lines, (n,) each.
        values: skfuzzy's output at the grid points, (n, n), values[i, j] at (grid_e[i], grid_ec[j]).
        centres: skfuzzy's output at the cell centres, (n - 1, n - 1).
        cache_path: the cache file it was loaded from or written to (None if none could be written).
        built: True if this load computed the grid, False if it came from the cache.
    """

    def __init__(self, rule_base: RuleBase, values: np.ndarray, centres: np.ndarray):
        n = values.shape[0]
        if values.shape != (n, n) or centres.shape != (n - 1, n - 1) or n < 2:
            raise ValueError(f"surface grid shapes {values.shape} and {centres.shape} do not match")
        self.rule_base = rule_base
        self.grid_e = np.linspace(*rule_base.e_range, n)
        self.grid_ec = np.linspace(*rule_base.ec_range, n)
        self.values = values
        self.centres = centres
        self.cache_path: Path | None = None
        self.built = False
        m = n - 1
        self._m = m
        self._e0 = float(rule_base.e_range[0])
        self._ec0 = float(rule_base.ec_range[0])
        # Index scale factors: grid coordinate u = (e - e0) * scale_e runs over [0, m].
        self._scale_e = m / (rule_base.e_range[1] - rule_base.e_range[0])
        self._scale_ec = m / (rule_base.ec_range[1] - rule_base.ec_range[0])
        self._coef = self._triangle_coefficients()  # (m * m * 4, 3): a, b, c of a + b s + c t
        self._coef_columns = tuple(np.ascontiguousarray(self._coef[:, k]) for k in range(3))
        # What the compiled fast path (`surface_at`) reads.
        self.kernel = (np.ascontiguousarray(self._coef), self._e0, float(self._scale_e), self._ec0,
                       float(self._scale_ec), m)

    def _triangle_coefficients(self) -> np.ndarray:
        """Affine coefficients of the four triangles of every cell.

        In a cell, s (along e) and t (along ec) run over [0, 1]; triangle q = 2 * (s < t) +
        (s + t >= 1) is 0 at the edge t = 0, 1 at s = 1, 2 at s = 0 and 3 at t = 1, and the
        surface there is a + b s + c t through the triangle's two corners and the centre.
        """
        v = self.values
        v00, v10, v01, v11 = v[:-1, :-1], v[1:, :-1], v[:-1, 1:], v[1:, 1:]
        c2 = 2.0 * self.centres
        coef = np.empty(v00.shape + (4, 3))
        coef[..., 0, :] = np.stack([v00, v10 - v00, c2 - v00 - v10], axis=-1)
        coef[..., 1, :] = np.stack([c2 - v11, v10 + v11 - c2, v11 - v10], axis=-1)
        coef[..., 2, :] = np.stack([v00, c2 - v00 - v01, v01 - v00], axis=-1)
        coef[..., 3, :] = np.stack([c2 - v11, v11 - v01, v01 + v11 - c2], axis=-1)
        return coef.reshape(-1, 3)

    # -- building and caching -----------------------------------------------------------------

    @classmethod
    def load(
        cls,
        rule_base: RuleBase,
        *,
        cache_dir: str | Path | None = None,
        grid_points: int | None = None,
    ) -> FuzzySurface:
        """The surface from the cache, or computed with skfuzzy (about 15 s) and cached.

        The cache file is keyed by rule_base.digest(), grid_points and the skfuzzy version; it
        is written to a temporary file in the same directory and renamed into place, so a
        concurrent process sees either no file or a whole one. An unwritable cache directory
        only costs the rebuild next time (a warning says so).
        """
        step = 2 * (len(rule_base.sets) - 1)
        if grid_points is None:
            grid_points = default_grid_points(rule_base)
        if grid_points < step + 1 or (grid_points - 1) % step:
            raise ValueError(
                f"grid_points must be k * {step} + 1 (k >= 1) so that the surface's kinks fall on grid "
                f"lines and cell diagonals, got {grid_points}"
            )
        directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
        version = _skfuzzy_version()
        digest = rule_base.digest()
        path = directory / f"flc_{digest[:24]}_n{grid_points}_skfuzzy-{version}_v{_CACHE_FORMAT}.npz"

        cached = _read_cache(path, digest, version, grid_points)
        if cached is not None:
            surface = cls(rule_base, *cached)
            surface.cache_path = path
            return surface

        values, centres = compute_grid(rule_base, grid_points)
        surface = cls(rule_base, values, centres)
        surface.built = True
        try:
            _write_cache(path, digest=digest, skfuzzy_version=version, values=values, centres=centres)
            surface.cache_path = path
        except OSError as exc:
            warnings.warn(f"cannot cache the fuzzy surface in {directory}: {exc}", stacklevel=2)
        return surface

    # -- evaluation -----------------------------------------------------------------------------

    def evaluate(self, e: Any, ec: Any, out: np.ndarray | None = None) -> np.ndarray:
        """FLC(e, ec) for arrays of any (broadcastable) shape; a 0-d array for scalars.

        Inputs outside the universes are clipped to them (the engineer's saturation); NaN in
        gives NaN out. With `out` (float64, the broadcast shape) nothing is allocated for small
        1-D calls, which go through `evaluate_into`.
        """
        if (
            out is not None
            and type(e) is np.ndarray
            and type(ec) is np.ndarray
            and out.ndim == 1
            and out.shape == e.shape == ec.shape
            and out.size <= _SMALL
        ):
            return self.evaluate_into(e, ec, out)
        e = np.asarray(e, dtype=float)
        ec = np.asarray(ec, dtype=float)
        shape = np.broadcast_shapes(e.shape, ec.shape)
        if out is not None and out.shape != shape:
            raise ValueError(f"out has shape {out.shape}, the inputs broadcast to {shape}")
        if e.shape != ec.shape:
            e, ec = np.broadcast_arrays(e, ec)
        m = self._m
        u = np.asarray((e - self._e0) * self._scale_e)  # asarray: 0-d inputs give numpy scalars
        v = np.asarray((ec - self._ec0) * self._scale_ec)
        # NaN in gives NaN out; a minimum is NaN if any value is, and cheaper than a mask.
        nan = np.isnan(u) | np.isnan(v) if np.isnan(u.min()) or np.isnan(v.min()) else None
        np.fmin(np.fmax(u, 0.0, out=u), m, out=u)  # saturate at the universe ends; NaN becomes 0
        np.fmin(np.fmax(v, 0.0, out=v), m, out=v)
        i = np.minimum(u.astype(np.intp), m - 1)
        j = np.minimum(v.astype(np.intp), m - 1)
        s = u - i
        t = v - j
        q = i * m
        q += j
        q *= 4
        q += 2 * (s < t)
        q += (s + t) >= 1.0
        a, b, c = self._coef_columns
        result = np.take(a, q)
        result += np.take(b, q) * s
        result += np.take(c, q) * t
        if nan is not None:
            result[nan] = np.nan
        if out is None:
            return result
        out[...] = result
        return out

    def evaluate_into(self, e: np.ndarray, ec: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The simulation loop's fast path: FLC of a few points (one per axis), written into out.

        e, ec and out are 1-D float64 arrays of equal length (no checks, no allocation). Same
        results as `evaluate`, compiled (`surface_at`).
        """
        _evaluate_points(self.kernel, e, ec, out)
        return out


def surface_error(surface: FuzzySurface, points: int, seed: int = 0, progress=None) -> tuple[float, float]:
    """The largest and the RMS difference of `surface` from skfuzzy's inference at `points` random
    inputs over the universes (in the output universe); `progress(n)` after each block."""
    rule_base = surface.rule_base
    rng = np.random.default_rng(seed)
    e, ec = rng.uniform(*rule_base.e_range, points), rng.uniform(*rule_base.ec_range, points)
    largest = squares = 0.0
    for start in range(0, points, _ERROR_BLOCK):
        part = slice(start, start + _ERROR_BLOCK)
        difference = surface.evaluate(e[part], ec[part]) - skfuzzy_compute(rule_base, e[part], ec[part])
        largest = max(largest, float(np.abs(difference).max()))
        squares += float(np.sum(difference**2))
        if progress is not None:
            progress(len(difference))
    return largest, (squares / points) ** 0.5


_ERROR_BLOCK = 5_000  # points a skfuzzy call: its memory grows with points x rules x output samples


@numba.njit(cache=True)
def surface_at(kernel, x: float, y: float) -> float:  # pragma: no cover - compiled
    """FLC(x, y) of a surface's `kernel` = (coefficients, e0, scale_e, ec0, scale_ec, cells):
    the triangle of the cell (x, y) falls in, saturated at the universe ends; NaN gives NaN."""
    coef, e0, se, ec0, sec, m = kernel
    i, s = _cell((x - e0) * se, m)
    j, t = _cell((y - ec0) * sec, m)
    if i < 0 or j < 0:
        return math.nan
    q = 4 * (i * m + j)
    if s < t:
        q += 2
    if s + t >= 1.0:
        q += 1
    return coef[q, 0] + coef[q, 1] * s + coef[q, 2] * t


@numba.njit(cache=True)
def _cell(u: float, m: int) -> tuple[int, float]:  # pragma: no cover - compiled
    """The cell of grid coordinate u on [0, m] and how far into it, saturated at the ends; -1 for NaN."""
    if 0.0 < u < m:
        i = int(u)
        return i, u - i
    if u <= 0.0:
        return 0, 0.0
    if u >= m:
        return m - 1, 1.0
    return -1, 0.0  # NaN fails every comparison


@numba.njit(cache=True)
def _evaluate_points(kernel, e, ec, out):  # pragma: no cover - compiled
    for k in range(len(out)):
        out[k] = surface_at(kernel, e[k], ec[k])


def default_grid_points(rule_base: RuleBase) -> int:
    """The grid size nearest TARGET_GRID_POINTS that puts every kink of the surface on grid lines
    and cell diagonals: k * 2 * (sets - 1) + 1 points, for any number of sets."""
    step = 2 * (len(rule_base.sets) - 1)
    return max(1, round((TARGET_GRID_POINTS - 1) / step)) * step + 1


def compute_grid(rule_base: RuleBase, grid_points: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """skfuzzy's output on the grid points and at the cell centres, in one compute() call."""
    grid_points = grid_points or default_grid_points(rule_base)
    ge = np.linspace(*rule_base.e_range, grid_points)
    gec = np.linspace(*rule_base.ec_range, grid_points)
    ce = 0.5 * (ge[:-1] + ge[1:])
    cec = 0.5 * (gec[:-1] + gec[1:])
    ne, nec = np.meshgrid(ge, gec, indexing="ij")
    me, mec = np.meshgrid(ce, cec, indexing="ij")
    flat = skfuzzy_compute(
        rule_base, np.concatenate([ne.ravel(), me.ravel()]), np.concatenate([nec.ravel(), mec.ravel()])
    )
    values = flat[: ne.size].reshape(ne.shape)
    centres = flat[ne.size :].reshape(me.shape)
    return values, centres


def _read_cache(
    path: Path, digest: str, version: str, grid_points: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """The cached (values, centres), or None if absent or not a whole, matching file."""
    n = grid_points
    text = Member("U", (), max_bytes=4096)
    try:
        data = load_npz(path, {"digest": text, "skfuzzy_version": text, "values": Member(shape=(n, n)),
                               "centres": Member(shape=(n - 1, n - 1))}, what=str(path))
    except BwrError:
        return None
    if str(data["digest"]) != digest or str(data["skfuzzy_version"]) != version:
        return None
    values, centres = np.array(data["values"], dtype=float), np.array(data["centres"], dtype=float)
    if not np.isfinite(values).all():
        return None
    return values, centres


def _write_cache(path: Path, **arrays: Any) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.stem + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **{k: np.asarray(v) for k, v in arrays.items()})
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
