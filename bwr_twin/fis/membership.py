"""The membership functions of MATLAB's Fuzzy Logic Toolbox, with its parameter order and its
behaviour at degenerate parameters, vectorised with numpy.

Each function takes `x` (any shape) and `params` (a sequence in MATLAB's order) and returns
memberships in [0, 1] of x's shape. Where MATLAB's toolbox defines an edge case, so do these:
trimf with a == b (or b == c) is a shoulder, 1 at x == b; trapmf with a == b (or c == d) is a
shoulder and with b > c a flat-topped triangle below 1; gauss2mf with c1 > c2 multiplies the two
halves; smf and zmf with a >= b are steps at (a + b) / 2. Parameter conditions that MATLAB
refuses (a zero width, trimf's a > b) are reported by `param_problem`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = [
    "MF_FUNCTIONS",
    "MF_PARAMS",
    "evaluate_mf",
    "gauss2mf",
    "gaussmf",
    "gbellmf",
    "param_problem",
    "pimf",
    "sigmf",
    "smf",
    "trapmf",
    "trimf",
    "zmf",
]


def _split(x: object, params: Sequence[float], n: int) -> tuple[np.ndarray, tuple[float, ...]]:
    values = tuple(float(p) for p in params)
    if len(values) != n:
        raise ValueError(f"needs {n} parameters, got {len(values)}")
    return np.asarray(x, dtype=float), values


# Far from a narrow Gaussian's or bell's centre its exponent overflows to infinity (a zero base
# to a negative power is infinite too), and the membership is its limit, 0, as it should be: no
# warning. The check of a system (bwr_twin.fis.system) keeps widths and values where nothing else
# overflows, and no 0/0 is left: a width is at least 1e-100, its square no 0.
def _far() -> np.errstate:
    return np.errstate(over="ignore", divide="ignore", under="ignore")


def trimf(x: object, params: Sequence[float]) -> np.ndarray:
    """Triangle [a b c]: 0 outside (a, c), rising on (a, b), 1 at b, falling on (b, c)."""
    x, (a, b, c) = _split(x, params, 3)
    y = np.zeros_like(x)
    # Each side is computed only where it is not degenerate, so a == b gives a left shoulder
    # (no division by zero) and x == b is 1 whatever the widths.
    if a != b:
        m = (a < x) & (x < b)
        y[m] = (x[m] - a) / (b - a)
    if b != c:
        m = (b < x) & (x < c)
        y[m] = (c - x[m]) / (c - b)
    y[x == b] = 1.0
    return y


def trapmf(x: object, params: Sequence[float]) -> np.ndarray:
    """Trapezoid [a b c d]: the minimum of a rising ramp (a to b) and a falling ramp (c to d).

    As in MATLAB, a == b or c == d gives a vertical side (a shoulder at the universe end) and
    b > c a triangle whose top stays below 1.
    """
    x, (a, b, c, d) = _split(x, params, 4)
    rise = np.where(x >= b, 1.0, 0.0)
    if a != b:
        m = (a <= x) & (x < b)
        rise[m] = (x[m] - a) / (b - a)
    fall = np.where(x <= c, 1.0, 0.0)
    if c != d:
        m = (c < x) & (x <= d)
        fall[m] = (d - x[m]) / (d - c)
    return np.minimum(rise, fall)


def gaussmf(x: object, params: Sequence[float]) -> np.ndarray:
    """Gaussian [sigma c]: exp(-(x - c)^2 / (2 sigma^2)); note MATLAB's order, width first."""
    x, (sigma, c) = _split(x, params, 2)
    with _far():
        return np.exp(-((x - c) ** 2) / (2.0 * sigma**2))


def gauss2mf(x: object, params: Sequence[float]) -> np.ndarray:
    """Two-sided Gaussian [sig1 c1 sig2 c2]: the left Gaussian below c1, the right above c2.

    Between c1 and c2 it is 1; if c1 > c2 the halves overlap there and, as in MATLAB, multiply,
    so the top stays below 1.
    """
    x, (s1, c1, s2, c2) = _split(x, params, 4)
    with _far():
        left = np.where(x <= c1, np.exp(-((x - c1) ** 2) / (2.0 * s1**2)), 1.0)
        right = np.where(x >= c2, np.exp(-((x - c2) ** 2) / (2.0 * s2**2)), 1.0)
    return left * right


def gbellmf(x: object, params: Sequence[float]) -> np.ndarray:
    """Generalised bell [a b c]: 1 / (1 + |(x - c) / a|^(2b)); a the half width, c the centre."""
    x, (a, b, c) = _split(x, params, 3)
    with _far():
        return 1.0 / (1.0 + np.abs((x - c) / a) ** (2.0 * b))


def sigmf(x: object, params: Sequence[float]) -> np.ndarray:
    """Sigmoid [a c]: 1 / (1 + exp(-a (x - c))); a the slope (its sign the open side), c the centre."""
    x, (a, c) = _split(x, params, 2)
    with np.errstate(over="ignore"):  # exp overflowing to inf is the right limit, 0
        return 1.0 / (1.0 + np.exp(-a * (x - c)))


def smf(x: object, params: Sequence[float]) -> np.ndarray:
    """S-shaped spline [a b]: 0 up to a (the foot), 1 from b (the shoulder), quadratic between.

    With a >= b MATLAB's smf is a step: 1 where x >= (a + b) / 2.
    """
    x, (a, b) = _split(x, params, 2)
    mid = 0.5 * (a + b)
    if a >= b:
        return (x >= mid).astype(float)
    y = np.where(x >= b, 1.0, 0.0)
    m = (a < x) & (x <= mid)
    y[m] = 2.0 * ((x[m] - a) / (b - a)) ** 2
    m = (mid < x) & (x < b)
    y[m] = 1.0 - 2.0 * ((b - x[m]) / (b - a)) ** 2
    return y


def zmf(x: object, params: Sequence[float]) -> np.ndarray:
    """Z-shaped spline [a b]: 1 up to a (the shoulder), 0 from b (the foot), quadratic between.

    With a >= b MATLAB's zmf is a step: 1 where x <= (a + b) / 2.
    """
    x, (a, b) = _split(x, params, 2)
    mid = 0.5 * (a + b)
    if a >= b:
        return (x <= mid).astype(float)
    y = np.where(x <= a, 1.0, 0.0)
    m = (a < x) & (x <= mid)
    y[m] = 1.0 - 2.0 * ((x[m] - a) / (b - a)) ** 2
    m = (mid < x) & (x < b)
    y[m] = 2.0 * ((b - x[m]) / (b - a)) ** 2
    return y


def pimf(x: object, params: Sequence[float]) -> np.ndarray:
    """Pi-shaped spline [a b c d]: smf [a b] times zmf [c d], as MATLAB defines it."""
    x, (a, b, c, d) = _split(x, params, 4)
    return smf(x, (a, b)) * zmf(x, (c, d))


MF_FUNCTIONS: dict[str, Callable[[object, Sequence[float]], np.ndarray]] = {
    "trimf": trimf,
    "trapmf": trapmf,
    "gaussmf": gaussmf,
    "gauss2mf": gauss2mf,
    "gbellmf": gbellmf,
    "sigmf": sigmf,
    "zmf": zmf,
    "smf": smf,
    "pimf": pimf,
}

# Each type's parameters in MATLAB's order: their count is the length of the tuple.
MF_PARAMS: dict[str, tuple[str, ...]] = {
    "trimf": ("a", "b", "c"),
    "trapmf": ("a", "b", "c", "d"),
    "gaussmf": ("sigma", "c"),
    "gauss2mf": ("sig1", "c1", "sig2", "c2"),
    "gbellmf": ("a", "b", "c"),
    "sigmf": ("a", "c"),
    "zmf": ("a", "b"),
    "smf": ("a", "b"),
    "pimf": ("a", "b", "c", "d"),
}


def param_problem(mf_type: str, params: Sequence[float]) -> str | None:
    """What is wrong with a type and its parameters (None if nothing), as MATLAB would refuse it.

    Checks the type, the count, finiteness, and the conditions MATLAB's functions raise on:
    trimf needs a <= b <= c, trapmf a <= b and c <= d, and widths (gaussmf's sigma, gauss2mf's
    sig1 and sig2, gbellmf's a) must not be 0.
    """
    if mf_type not in MF_PARAMS:
        return f"unknown membership function type {mf_type!r} (known: {', '.join(MF_PARAMS)})"
    names = MF_PARAMS[mf_type]
    if len(params) != len(names):
        return f"{mf_type} takes {len(names)} parameters [{' '.join(names)}], got {len(params)}"
    if not all(np.isfinite(p) for p in params):
        return f"{mf_type} parameters must be finite numbers, got {_vector(params)}"
    p = dict(zip(names, params))
    if mf_type == "trimf" and not p["a"] <= p["b"] <= p["c"]:
        return f"trimf needs a <= b <= c, got {_vector(params)}"
    if mf_type == "trapmf" and not (p["a"] <= p["b"] and p["c"] <= p["d"]):
        return f"trapmf needs a <= b and c <= d, got {_vector(params)}"
    for width in ("sigma", "sig1", "sig2"):
        if p.get(width) == 0:
            return f"{mf_type} needs {width} != 0 (a zero-width Gaussian), got {_vector(params)}"
    if mf_type == "gbellmf" and p["a"] == 0:
        return f"gbellmf needs a != 0 (a zero-width bell), got {_vector(params)}"
    return None


def evaluate_mf(mf_type: str, params: Sequence[float], x: object) -> np.ndarray:
    """Memberships of x in a set of the named type (ValueError for an unknown type)."""
    try:
        function = MF_FUNCTIONS[mf_type]
    except KeyError:
        raise ValueError(
            f"unknown membership function type {mf_type!r} (known: {', '.join(MF_PARAMS)})"
        ) from None
    return function(x, params)


def _vector(params: Sequence[float]) -> str:
    return "[" + " ".join(f"{float(p):g}" for p in params) + "]"
