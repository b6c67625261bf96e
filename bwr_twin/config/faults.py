"""Scheduled faults: the `[[faults]]` tables of a scene, and the rules they must keep.

A fault is a sensor or a drive that fails for a while: an encoder that sticks, drops out, drifts
or turns noisy, a scanner blinded by dust, a belt scale that freezes, a drive that trips, or the
controller's encoder readings arriving late; or the plant itself changing: an axis's friction
rising (a seizing bearing), material caking at the wheel end (mass), a drive derated. A plant
fault grows linearly over its `ramp` s from its start to its full size (a step without one).
Each acts from `start` (s after the run's start) for `duration` s, or to the run's end without
one. Engineers write angles in degrees: an
encoder fault's `rate` is m/s on travel and deg/s on slew and luff, its `sigma` m or deg; the
twin converts them to radians itself (bwr_twin.sensing.faults). A table is refused if it
misses a key its kind needs or gives one its kind does not use: a key that is silently ignored
would make a scene say what it does not do.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from bwr_twin.errors import SceneError
from bwr_twin.values import is_integer, is_number

# qpos order, as bwr_twin.model.machine.AXES: not imported, so that a scene loads without MuJoCo.
FAULT_AXES = ("travel", "slew", "luff")

# The keys each kind reads besides kind, start and duration.
_KEYS = {
    "encoder_stuck": ("axis",),
    "encoder_dropout": ("axis",),
    "encoder_drift": ("axis", "rate"),
    "encoder_noise": ("axis", "sigma"),
    "scanner_blinded": ("scanner",),
    "belt_scale_frozen": (),
    "drive_trip": ("axis",),
    "late_inputs": ("periods",),
    "friction_rise": ("axis", "percent", "ramp"),
    "mass_change": ("mass", "ramp"),
    "drive_derate": ("axis", "percent", "ramp"),
}
FAULT_KINDS = tuple(_KEYS)
_OPTIONAL = ("axis", "scanner", "rate", "sigma", "periods", "percent", "mass", "ramp")  # keys only some kinds use
PLANT_KINDS = ("friction_rise", "mass_change", "drive_derate")  # faults of the machine, not of its sensors
_SCANNER_PREFIX = "scanner"  # a scanner is a site whose name starts with it (the model contract)

# The most [[faults]] tables a scene file may hold, counted in its text before it is parsed: 100,000
# took 15 s to read and 64 s and 1.5 GB to run. A run with more than bwr_twin.sim.scaling's
# MAX_FAULTS needs --force; none holds more than this.
MOST_FAULTS = 10_000
_TABLE = re.compile(r"^[ \t]*\[\[[ \t]*faults[ \t]*\]\]", re.MULTILINE)


def check_fault_count(path: Path, text: str) -> None:
    """SceneError naming the file and the count if its text holds more than MOST_FAULTS
    [[faults]] tables: refused before the file is parsed."""
    count = len(_TABLE.findall(text))
    if count > MOST_FAULTS:
        raise SceneError(f"{path}: 'faults' holds {count:,} [[faults]] tables, more than the {MOST_FAULTS:,} a scene "
                         f"may hold (about {count * 0.8e-3:.0f} s and {count * 16e-6:.2g} GB to read and run them)")


@dataclass(frozen=True)
class FaultSection:
    """One `[[faults]]` table: what fails, when, and how.

    `axis` is travel, slew or luff (encoder_* and drive_trip); `scanner` a scanner site's name
    (scanner_blinded; None blinds every scanner); `rate` the drift (m/s on travel, deg/s on
    slew and luff); `sigma` the noise's standard deviation (m or deg); `periods` the control
    periods late_inputs delays the readings by; `percent` a friction rise's (of the axis's
    viscous and Coulomb friction) or a drive derate's (of its force) full size; `mass` the kg
    a mass change adds at the CP (the wheel end); `ramp` the s a plant fault takes to grow
    from nothing to its full size (None: a step at its start).
    """

    kind: str
    start: float  # s after the run's start
    duration: float | None = None  # s; None: to the run's end
    axis: str | None = None
    scanner: str | None = None
    rate: float | None = None  # m/s on travel, deg/s on slew and luff
    sigma: float | None = None  # m on travel, deg on slew and luff
    periods: int | None = None  # control periods
    percent: float | None = None  # % of the nominal friction (friction_rise) or drive force (drive_derate)
    mass: float | None = None  # kg added at the CP
    ramp: float | None = None  # s from the start to the full size; None: a step

    @property
    def uses(self) -> tuple[str, ...]:
        """The keys its kind reads besides kind, start and duration."""
        return _KEYS.get(self.kind, ())


def check_faults(path: Path, faults: Sequence[FaultSection], runs_until: float | None = None) -> None:
    """Raise SceneError for the first fault that breaks a rule; `runs_until` is the run's end
    in s when the scene fixes it (via points), so that a fault that would never act is refused.

    Faults are counted from 0, as every list in a scene is (`plant.payload[0]`).
    """
    for number, fault in enumerate(faults):
        _check_fault(path, f"faults[{number}]", fault, runs_until)


def check_fault_scanners(path: Path, faults: Sequence[FaultSection], scanners: Sequence[str],
                         mjcf: Path | None = None) -> None:
    """Raise SceneError if a scanner_blinded fault names a scanner the machine lacks: the
    machine's scanners are known only once its MJCF is read, as the run starts."""
    for number, fault in enumerate(faults):
        if fault.kind == "scanner_blinded" and fault.scanner is not None and fault.scanner not in scanners:
            machine = f"{mjcf}" if mjcf is not None else "the machine"
            have = ", ".join(scanners) or "none"
            raise SceneError(f"{path}: 'faults[{number}].scanner' names {fault.scanner!r}, a scanner {machine} "
                             f"does not have (it has: {have})")


def _check_fault(path: Path, where: str, fault: FaultSection, runs_until: float | None) -> None:
    kind = fault.kind
    if kind not in _KEYS:
        raise SceneError(f"{path}: '{where}.kind' must be one of {', '.join(FAULT_KINDS)}, got {kind!r}")
    if not (is_number(fault.start) and fault.start >= 0):
        raise SceneError(f"{path}: '{where}.start' must be >= 0 s, got {fault.start!r}")
    if fault.duration is not None and not (is_number(fault.duration) and fault.duration > 0):
        raise SceneError(f"{path}: '{where}.duration' must be > 0 s (or left out: to the run's end), "
                         f"got {fault.duration!r}")
    if runs_until is not None and not fault.start < runs_until:
        raise SceneError(f"{path}: '{where}.start' ({fault.start} s) must come before the run's end "
                         f"({runs_until} s): the fault would never act")
    uses = _KEYS[kind]
    for key in _OPTIONAL:
        if key not in uses and getattr(fault, key) is not None:
            used = f"it uses {', '.join(uses)}" if uses else "it uses only start and duration"
            raise SceneError(f"{path}: '{where}.{key}' is not used by kind \"{kind}\" ({used})")
    if "axis" in uses:
        _check_axis(path, where, fault)
    if "rate" in uses:
        if fault.rate is None:
            raise SceneError(f"{path}: '{where}.rate' is missing: kind \"{kind}\" needs the drift rate "
                             "(m/s for travel, deg/s for slew and luff)")
        if not is_number(fault.rate):
            raise SceneError(f"{path}: '{where}.rate' must be a finite number, got {fault.rate!r}")
    if "sigma" in uses and not (is_number(fault.sigma) and fault.sigma > 0):
        if fault.sigma is None:
            raise SceneError(f"{path}: '{where}.sigma' is missing: kind \"{kind}\" needs the noise's standard "
                             "deviation (m for travel, deg for slew and luff)")
        raise SceneError(f"{path}: '{where}.sigma' must be > 0 (m for travel, deg for slew and luff) for kind "
                         f"\"{kind}\", got {fault.sigma!r}")
    if "periods" in uses and not (is_integer(fault.periods) and fault.periods >= 1):
        if fault.periods is None:
            raise SceneError(f"{path}: '{where}.periods' is missing: kind \"{kind}\" needs the control periods "
                             "the readings arrive late")
        raise SceneError(f"{path}: '{where}.periods' must be an integer >= 1 for kind \"{kind}\", "
                         f"got {fault.periods!r}")
    if "percent" in uses:
        _check_percent(path, where, fault)
    if "mass" in uses and not (is_number(fault.mass) and fault.mass > 0):
        raise SceneError(f"{path}: '{where}.mass' must be > 0 kg (the material added at the CP) for kind "
                         f"\"{kind}\", got {fault.mass!r}")
    if fault.ramp is not None and not (is_number(fault.ramp) and fault.ramp >= 0):
        raise SceneError(f"{path}: '{where}.ramp' must be >= 0 s (or left out: a step), got {fault.ramp!r}")
    if "scanner" in uses and fault.scanner is not None and not (
            isinstance(fault.scanner, str) and fault.scanner.startswith(_SCANNER_PREFIX)):
        raise SceneError(f"{path}: '{where}.scanner' must name a scanner site (its name starts with "
                         f"'{_SCANNER_PREFIX}'), or be left out to blind them all, got {fault.scanner!r}")


def _check_percent(path: Path, where: str, fault: FaultSection) -> None:
    high = 100.0 if fault.kind == "drive_derate" else 1000.0  # a drive derated by 100 % has tripped
    if not (is_number(fault.percent) and 0 < fault.percent < high):
        raise SceneError(f"{path}: '{where}.percent' must be > 0 and < {high:g} % for kind \"{fault.kind}\", "
                         f"got {fault.percent!r}")


def _check_axis(path: Path, where: str, fault: FaultSection) -> None:
    axes = ", ".join(FAULT_AXES)
    if fault.axis is None:
        raise SceneError(f"{path}: '{where}.axis' is missing: kind \"{fault.kind}\" needs one of {axes}")
    if fault.axis not in FAULT_AXES:
        raise SceneError(f"{path}: '{where}.axis' must be one of {axes} for kind \"{fault.kind}\", "
                         f"got {fault.axis!r}")
