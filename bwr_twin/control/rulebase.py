"""The fuzzy rule base as data (paper Sec. 3, Table 2), read from a TOML file and checked.

The file under scenes/rulebases/ names the sets, the rule table and the universes, each number
with its source; `RuleBase.digest()` keys the cached control surface of bwr_twin.control.fuzzy.
A MATLAB .fis file becomes a RuleBase in bwr_twin.fis.convert, which builds on this module and
adds its reader to READERS; `load_rule_base` picks the reader by the file's suffix.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bwr_twin.errors import SceneError
from bwr_twin.tomlfile import read_toml
from bwr_twin.values import is_number

_DIGEST_SCHEMA = "bwr_twin.control.fuzzy.RuleBase/1"

_KEYS: dict[str, set[str] | None] = {
    "sets": None,
    "rules": None,
    "universe": {"e", "ec", "output"},
    "membership": {"shape", "input_points", "output_points"},
    "inference": {"and", "aggregation", "defuzzify"},
}
_REQUIRED = ("sets", "rules", "universe")
# The choices skfuzzy is set up for below; anything else would need a different definition.
_CHOICES = {
    "membership.shape": ("triangular",),
    "inference.and": ("min",),
    "inference.aggregation": ("max",),
    "inference.defuzzify": ("centroid",),
}


@dataclass(frozen=True)
class RuleBase:
    """A Mamdani rule base over two inputs, e and ec, and one output.

    Attributes:
        sets: the set names, lowest first, shared by e, ec and the output.
        rules: rules[i][j] is the output set for e in sets[i] and ec in sets[j].
        e_range, ec_range, output_range: the universes (low, high).
        input_points, output_points: samples of the universes that skfuzzy works on.
        shape, and_method, aggregation, defuzzify: the inference choices.
        path: the file it came from (not part of the digest).
    """

    sets: tuple[str, ...]
    rules: tuple[tuple[str, ...], ...]
    e_range: tuple[float, float]
    ec_range: tuple[float, float]
    output_range: tuple[float, float]
    input_points: int = 601
    output_points: int = 181
    shape: str = "triangular"
    and_method: str = "min"
    aggregation: str = "max"
    defuzzify: str = "centroid"
    path: Path | None = field(default=None, compare=False)

    @classmethod
    def from_toml(cls, path: str | Path) -> RuleBase:
        """Read and check a rule base file; every problem is a one-line SceneError."""
        path = Path(path)
        return _parse(path, read_toml(path, "rule base"))

    def digest(self) -> str:
        """sha256 of the content (not of the file or its comments): the surface cache key."""
        canonical = {
            "schema": _DIGEST_SCHEMA,
            "sets": list(self.sets),
            "rules": [list(row) for row in self.rules],
            "universe": {
                "e": [float(v) for v in self.e_range],
                "ec": [float(v) for v in self.ec_range],
                "output": [float(v) for v in self.output_range],
            },
            "points": [self.input_points, self.output_points],
            "inference": [self.shape, self.and_method, self.aggregation, self.defuzzify],
        }
        text = json.dumps(canonical, sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(text.encode()).hexdigest()

    def term_peaks(self, low: float, high: float) -> np.ndarray:
        """Peaks of the evenly spaced sets on a universe."""
        return np.linspace(low, high, len(self.sets))

    def term_abcs(self, low: float, high: float) -> list[tuple[float, float, float]]:
        """trimf parameters (a, b, c) of each set: feet at the neighbouring peaks.

        The outer sets' outer foot sits at the universe end (a == b or b == c). On the sampled
        universe this equals skfuzzy's automf, whose outer foot lies one spacing beyond the end.
        """
        peaks = self.term_peaks(low, high)
        return [
            (float(peaks[max(k - 1, 0)]), float(peaks[k]), float(peaks[min(k + 1, len(peaks) - 1)]))
            for k in range(len(peaks))
        ]


# Readers of rule bases in other formats than TOML, by lower-case file suffix: bwr_twin.fis.convert
# adds ".fis" when imported (bwr_twin.config.plugins.controller_class imports it).
READERS: dict[str, Callable[[Path], RuleBase]] = {}


def load_rule_base(path: str | Path) -> RuleBase:
    """A rule base file as the fuzzy_model controller reads it: a TOML rule base, or a file in a
    format READERS holds a reader for (by its suffix)."""
    path = Path(path)
    reader = READERS.get(path.suffix.lower())
    return RuleBase.from_toml(path) if reader is None else reader(path)


def _parse(path: Path, data: dict[str, Any]) -> RuleBase:
    def fail(key: str, what: str) -> SceneError:
        return SceneError(f"{path}: key '{key}': {what}")

    for key, value in data.items():
        if key not in _KEYS:
            raise fail(key, f"unknown key (known: {', '.join(_KEYS)})")
        allowed = _KEYS[key]
        if allowed is not None:
            if not isinstance(value, dict):
                raise fail(key, f"must be a table, got {_type(value)}")
            for sub in value:
                if sub not in allowed:
                    raise fail(f"{key}.{sub}", f"unknown key (known: {', '.join(sorted(allowed))})")
    for key in _REQUIRED:
        if key not in data:
            raise SceneError(f"{path}: missing key '{key}'")

    sets = data["sets"]
    if not isinstance(sets, list) or not sets or not all(isinstance(s, str) and s for s in sets):
        raise fail("sets", f"must be a non-empty list of names, got {sets!r}")
    if len(set(sets)) != len(sets):
        raise fail("sets", f"names must be distinct, got {sets}")
    if len(sets) < 2:
        raise fail("sets", "needs at least two sets")
    n = len(sets)

    rules = data["rules"]
    if not isinstance(rules, list) or len(rules) != n or not all(isinstance(r, list) for r in rules):
        rows = len(rules) if isinstance(rules, list) else _type(rules)
        raise fail("rules", f"must be a {n}x{n} table (one row per set of e), got {rows} rows")
    for i, row in enumerate(rules):
        if len(row) != n:
            raise fail(
                "rules", f"row {i + 1} (e = {sets[i]}) has {len(row)} entries, needs {n} (one per set of ec)"
            )
        for j, name in enumerate(row):
            if name not in sets:
                raise fail(
                    "rules",
                    f"row {i + 1} (e = {sets[i]}) column {j + 1} (ec = {sets[j]}): unknown set {name!r} "
                    f"(sets are {', '.join(sets)})",
                )

    universe = data["universe"]
    ranges = {}
    for name in ("e", "ec", "output"):
        key = f"universe.{name}"
        if name not in universe:
            raise SceneError(f"{path}: missing key '{key}'")
        value = universe[name]
        if not (isinstance(value, list) and len(value) == 2 and all(is_number(v) for v in value)):
            raise fail(key, f"must be [low, high], two numbers, got {value!r}")
        low, high = float(value[0]), float(value[1])
        if not (math.isfinite(low) and math.isfinite(high)):
            raise fail(key, f"must be finite, got [{low}, {high}]")
        if low >= high:
            raise fail(key, f"low must be below high, got [{low}, {high}]")
        ranges[name] = (low, high)

    membership = data.get("membership", {})
    inference = data.get("inference", {})
    points = {}
    for name, default in (("input_points", 601), ("output_points", 181)):
        key = f"membership.{name}"
        value = membership.get(name, default)
        if not isinstance(value, int) or isinstance(value, bool):
            raise fail(key, f"must be an integer, got {_type(value)}")
        step = 2 * (n - 1)  # puts every peak and every crossing of neighbours on a sample
        if value < step + 1 or (value - 1) % step:
            raise fail(key, f"must be k * {step} + 1 (k >= 1) so that every peak is a sample, got {value}")
        points[name] = value
    choices = {}
    for key, allowed in _CHOICES.items():
        table, name = key.split(".")
        value = (membership if table == "membership" else inference).get(name, allowed[0])
        if not isinstance(value, str):
            raise fail(key, f"must be a string, got {_type(value)}")
        if value not in allowed:
            raise fail(key, f"{value!r} is not supported (supported: {', '.join(allowed)})")
        choices[key] = value

    return RuleBase(
        sets=tuple(sets),
        rules=tuple(tuple(row) for row in rules),
        e_range=ranges["e"],
        ec_range=ranges["ec"],
        output_range=ranges["output"],
        input_points=points["input_points"],
        output_points=points["output_points"],
        shape=choices["membership.shape"],
        and_method=choices["inference.and"],
        aggregation=choices["inference.aggregation"],
        defuzzify=choices["inference.defuzzify"],
        path=path,
    )


def _type(value: Any) -> str:
    return type(value).__name__
