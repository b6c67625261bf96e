"""Mamdani inference as MATLAB's evalfis does it, vectorised over many input rows.

The steps, each over all rows at once:
1. clip every input to its range (a FisWarning says so: MATLAB's evalfis warns about such
   inputs too, but evaluates its membership functions at the unclipped value; the clip matches
   the project's controller, which saturates e and ec at the universe ends);
2. fuzzify: each rule's antecedent memberships, 1 - mu for a negative (NOT) index, and for a 0
   (don't care) the neutral value of the rule's connection: 1 for AND, 0 for OR;
3. combine them with the AND method (min | prod) or the OR method (max | probor), times the
   rule's weight: the firing strength;
4. imply (min | prod) each rule's consequent set, sampled at `points` evenly spaced values of
   the output range (101 by default, as evalfis), a negative index taking 1 - mu;
5. aggregate the rules (max | sum | probor) and defuzzify the sampled set (centroid | bisector
   | mom | som | lom, MATLAB's discrete definitions, see `defuzzify`).

An output whose aggregated set is zero everywhere (no rule fired, or too few samples to catch
the sets) is the middle of its range, as in MATLAB; a FisWarning says so.
"""

from __future__ import annotations

import warnings

import numpy as np

from bwr_twin.fis.membership import evaluate_mf
from bwr_twin.fis.system import AND, FuzzySystem, Variable

DEFAULT_POINTS = 101  # MATLAB evalfis' default number of output samples (evalfisOptions.NumSamplePoints)


_BLOCK_VALUES = 2_000_000  # samples of an aggregated set held at once (16 MB of float64)


class FisWarning(UserWarning):
    """An input clipped to its range, or an output set to the middle of its range."""


def evaluate(
    system: FuzzySystem, inputs: object, *, points: int = DEFAULT_POINTS, warn: bool = True
) -> np.ndarray:
    """The crisp outputs, (n, n_outputs), for input rows (n, n_inputs); a 1-D input is one row.

    `points` samples each output range (an integer >= 2; MATLAB's default 101). A row with a NaN
    input gives NaN outputs. With `warn`, inputs outside their range and outputs with nothing
    fired raise a FisWarning each (one per variable and call, not one per row).
    """
    if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 2:
        raise ValueError(f"points must be an integer >= 2 (samples of each output range), got {points!r}")
    x = _rows(system, inputs)
    clipped = _clip(system, x, warn)  # once, so that each input warns once however many blocks
    n_outputs = len(system.outputs)
    result = np.empty((x.shape[0], n_outputs))
    # Rows go through in blocks so that what each step holds, the memberships (rows, rules,
    # inputs) and the sampled sets (rows, points), stays a few MB however many rows there are.
    block = max(1, _BLOCK_VALUES // max(points, len(system.rules) * len(system.inputs)))
    for start in range(0, x.shape[0], block):
        strengths = firing_strengths(system, clipped[start : start + block], warn=False)
        for o in range(n_outputs):
            result[start : start + block, o] = defuzzify(
                *aggregate(system, strengths, o, points), system.defuzz_method
            )
    for o, variable in enumerate(system.outputs):
        crisp = result[:, o]
        empty = np.isnan(crisp)
        middle = 0.5 * (variable.range[0] + variable.range[1])
        crisp[empty] = middle
        if warn and empty.any():
            warnings.warn(
                f"output {o + 1} {variable.name!r}: no rule fired for {int(empty.sum())} of {len(crisp)} "
                f"input rows; the output is the middle of its range, {middle:g} (as in MATLAB's evalfis)",
                FisWarning,
                stacklevel=2,
            )
    result[np.isnan(x).any(axis=1)] = np.nan
    return result


def firing_strengths(system: FuzzySystem, inputs: object, *, warn: bool = True) -> np.ndarray:
    """Each rule's firing strength (weight included) for each input row: (n, n_rules).

    Inputs are clipped to their ranges first; NaN inputs are evaluated at the middle of the
    range (evaluate() turns their outputs into NaN).
    """
    x = _clip(system, _rows(system, inputs), warn)
    n, rules = x.shape[0], system.rules
    if not rules:
        return np.zeros((n, 0))
    is_and = np.array([rule.connection == AND for rule in rules])
    columns = []
    for j, variable in enumerate(system.inputs):
        mu = memberships(variable, x[:, j])  # (n, K)
        k = mu.shape[1]
        # One table per input, so that every rule picks its column with one fancy index:
        # the K sets, their K complements (NOT), then 1 and 0 for don't care under AND and OR.
        table = np.concatenate([mu, 1.0 - mu, np.ones((n, 1)), np.zeros((n, 1))], axis=1)
        index = np.array([rule.antecedent[j] for rule in rules])
        column = np.where(
            index > 0, index - 1, np.where(index < 0, k - index - 1, np.where(is_and, 2 * k, 2 * k + 1))
        )
        columns.append(table[:, column])
    values = np.stack(columns, axis=2)  # (n, rules, inputs)
    if system.and_method == "min":
        joined_and = values.min(axis=2)
    else:  # prod
        joined_and = values.prod(axis=2)
    if system.or_method == "max":
        joined_or = values.max(axis=2)
    else:  # probor: a + b - ab, folded over the inputs in order, as MATLAB's probor does
        joined_or = values[:, :, 0].copy()
        for j in range(1, values.shape[2]):
            joined_or = joined_or + values[:, :, j] - joined_or * values[:, :, j]
    weights = np.array([float(rule.weight) for rule in rules])
    return np.where(is_and, joined_and, joined_or) * weights


def memberships(variable: Variable, x: np.ndarray) -> np.ndarray:
    """Membership of each value in each of the variable's sets: (len(x), n_sets)."""
    return np.stack([evaluate_mf(mf.type, mf.params, x) for mf in variable.mfs], axis=-1)


def aggregate(
    system: FuzzySystem, strengths: np.ndarray, output: int, points: int = DEFAULT_POINTS
) -> tuple[np.ndarray, np.ndarray]:
    """The output universe's samples y (points,) and the aggregated set on them (n, points).

    `strengths` are firing_strengths(); `output` is 0-based. Rules whose consequent for this
    output is 0 do not take part. The loop runs over rules, each step vectorised over rows.
    """
    variable = system.outputs[output]
    y = np.linspace(variable.range[0], variable.range[1], points)
    sets = memberships(variable, y).T  # (K, points)
    aggregated = np.zeros((strengths.shape[0], points))
    for r, rule in enumerate(system.rules):
        index = rule.consequent[output]
        if index == 0:
            continue
        shape = sets[index - 1] if index > 0 else 1.0 - sets[-index - 1]
        strength = strengths[:, r : r + 1]
        implied = np.minimum(strength, shape) if system.imp_method == "min" else strength * shape
        if system.agg_method == "max":
            np.maximum(aggregated, implied, out=aggregated)
        elif system.agg_method == "sum":
            aggregated += implied
        else:  # probor, (a + b) - ab in MATLAB's order of operations
            aggregated = aggregated + implied - aggregated * implied
    return y, aggregated


def defuzzify(y: np.ndarray, aggregated: np.ndarray, method: str) -> np.ndarray:
    """Crisp values (n,) of sampled sets (n, len(y)) by MATLAB's discrete definitions.

    centroid: sum(mu y) / sum(mu); bisector: the first sample where the running sum of mu reaches
    half the total; mom: the mean of the samples at the maximum; som / lom: of the samples at
    the maximum, the one smallest / largest in absolute value (the first such on a tie), as in
    MATLAB's defuzz (its documented example gives som -2 and lom -8 for a plateau on [-8, -2]).
    A set that is zero everywhere gives NaN.
    """
    aggregated = np.atleast_2d(aggregated)
    total = aggregated.sum(axis=1)
    empty = ~(total > 0)
    # Sums along each row (not a matrix product, whose BLAS kernel adds in an order that depends
    # on the number of rows): a row's value is the same alone and among any others.
    if method == "centroid":
        with np.errstate(invalid="ignore", divide="ignore"):
            crisp = (aggregated * y).sum(axis=1) / total
    elif method == "bisector":
        running = np.cumsum(aggregated, axis=1)
        crisp = y[np.argmax(running >= 0.5 * running[:, -1:], axis=1)]
    elif method in ("mom", "som", "lom"):
        at_max = aggregated == aggregated.max(axis=1, keepdims=True)
        if method == "mom":
            crisp = np.where(at_max, y, 0.0).sum(axis=1) / at_max.sum(axis=1)
        elif method == "som":
            crisp = y[np.argmin(np.where(at_max, np.abs(y), np.inf), axis=1)]
        else:
            crisp = y[np.argmax(np.where(at_max, np.abs(y), -np.inf), axis=1)]
    else:
        raise ValueError(
            f"unknown defuzzification method {method!r} (known: centroid, bisector, mom, som, lom)"
        )
    crisp = np.array(crisp, dtype=float)
    crisp[empty] = np.nan
    return crisp


def _rows(system: FuzzySystem, inputs: object) -> np.ndarray:
    x = np.asarray(inputs, dtype=float)
    if x.ndim == 1:
        x = x.reshape(1, -1)
    n_inputs = len(system.inputs)
    if x.ndim != 2 or x.shape[1] != n_inputs:
        raise ValueError(f"inputs must be rows of {n_inputs} values (one per input), got shape {x.shape}")
    return x


def _clip(system: FuzzySystem, x: np.ndarray, warn: bool) -> np.ndarray:
    clipped = np.empty_like(x)
    for j, variable in enumerate(system.inputs):
        low, high = variable.range
        column = x[:, j]
        outside = (column < low) | (column > high)
        if warn and outside.any():
            values = column[outside]
            warnings.warn(
                f"input {j + 1} {variable.name!r}: {int(outside.sum())} of {len(column)} values outside "
                "its range "
                f"[{low:g}, {high:g}] (from {values.min():g} to {values.max():g}) were clipped to it "
                "(MATLAB's evalfis warns too)",
                FisWarning,
                stacklevel=3,  # the caller of evaluate() or firing_strengths()
            )
        clipped[:, j] = np.where(np.isnan(column), 0.5 * (low + high), np.clip(column, low, high))
    return clipped
