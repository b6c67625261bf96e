"""Sane ranges of a scene's physical inputs, each with its source: physics that cannot be is refused.

A scene's types and signs are checked where it is built (bwr_twin.config.scene); this module holds
the limits beyond which an input describes no real material, atmosphere or machine: a bulk density
of 1e30 kg/m^3, a pile standing at 2 deg, a wind beyond any ever measured, a Coulomb friction
beyond the machine's own weight. Each refusal is one line naming the file, the key and the limit.
The ranges are wide on purpose: every real bulk material and yard lies well inside them, and the
numbers a typing slip makes (t/m^3 for kg/m^3, radians for degrees) lie far outside.

The limits that need the machine (friction, the wheel drive's idle power) are checked against the
plant's MJCF and its payloads. Where the pile is sampled (the grid spacing against the pile's
size) the limit is checked as the pile is built (bwr_twin.pile.surface), and a pile read
from a file has its heights checked against PILE_HEIGHT as it is read (bwr_twin.pile.surface,
bwr_twin.stockpile.stacked).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

from bwr_twin.errors import ModelError, SceneError
from bwr_twin.textfile import version

# kg/m^3, of the loose, stockpiled material. CEMA, "Belt Conveyors for Bulk Materials" (7th ed.),
# ch. 3, the table of material characteristics: bituminous coal 40-60 lb/ft^3 (0.64-0.96 t/m^3),
# iron ore 100-200 lb/ft^3 (1.6-3.2 t/m^3; 2.0-2.6 t/m^3 for the fines and lump of the ore
# ports), lead ores up to 270 lb/ft^3 (4.3 t/m^3), the heaviest; screened wood chips from
# 10 lb/ft^3 (0.16 t/m^3), the lightest solid stockpiled in the open.
BULK_DENSITY = (150.0, 5000.0)

# deg. CEMA, the same book, Table 3-1: a freely formed pile's angle of repose runs from below
# 20 deg (very free flowing: uniform, round, dry grains) to 40 deg and up (sluggish, irregular,
# sticky); the table's ores and coals stand at 30-45 deg (docs: about 37-38 deg for coal and ores).
# No free-formed pile of a bulk solid stands below 10 deg or above 60 deg; 0.65 is 37 deg in radians.
ANGLE_OF_REPOSE = (10.0, 60.0)

# m/s, the mean wind and its gusts together. The strongest surface gust ever measured: 113.3 m/s
# (408 km/h) at Barrow Island, Western Australia, in Tropical Cyclone Olivia, 10 April 1996 (World
# Meteorological Organization, Weather and Climate Extremes Archive). Reclaimers stop at about 20 m/s
# and are tied down for storms; a storm scene lies within the record, a faster wind lies nowhere.
WIND_PEAK = 113.0

# kg/m^3. ISO 2533 (the ICAO standard atmosphere): 1.225 kg/m^3 at sea level and 15 degC, 0.526 at
# 8,000 m, higher than any mine (the highest work at about 5,000-6,000 m); dry air at sea level and
# -50 degC holds 1.58 kg/m^3 (ideal gas, 101,325 Pa / (287.05 J/(kg K) x 223 K)).
AIR_DENSITY = (0.5, 1.6)

# The side force of the cut as a share of its tangential (cutting) force. Both machines' scenes
# take 0.4 (mjcf/README.md: about 100 kN of the heavy wheel's 270 kN); a side force beyond the
# cutting force itself would have the buckets cut sideways harder than they cut forwards.
LATERAL_RATIO = (0.0, 1.0)

# The largest Coulomb friction coefficient a drive train can meet: dry mild steel on mild steel
# grips at about 0.74 at rest (Marks' Standard Handbook for Mechanical Engineers, coefficients of
# friction), a wheel locked on its rail at most that. With 1, travel friction beyond the machine's
# weight, or slew and luff friction beyond that weight at the CP's reach (the longest lever the
# machine has), is friction no machine can have.
FRICTION_COEFFICIENT = 1.0

# m above the yard floor, a pile's heights as a survey or a stacking's pile.npz gives them. The
# tallest open stockpiles of ore and coal stand some 20-30 m, as high as a stacker's boom reaches
# (the heavy scenes' pile stands 8 m); 100 m is no stockpile, but a survey in millimetres or
# feet x 1e3. Below the floor lies only a survey's noise and the yard's drainage falls, a few
# decimetres: 5 m below it is another datum, not the yard.
PILE_HEIGHT = (-5.0, 100.0)
PILE_HEIGHT_SOURCE = "metres above the yard floor: open stockpiles stand at most some 30 m"

# m, a rail position or a world coordinate of a run's time series, read where the machine is not
# known (with it, its own operating envelope bounds its joints: bwr_twin.results.run_files). The
# shipped heavy machine's rail spans 400 m (mjcf/bwr_heavy.xml, an envelope of +-200 m), and the beds
# of the largest bulk terminals run a few kilometres; 10 km from the yard's origin lies in no yard.
YARD_EXTENT = 10_000.0
YARD_EXTENT_SOURCE = "metres from the yard's origin: a yard's rail runs at most a few kilometres"

# rad, a slew or luff angle of a run's time series, read where the machine is not known. The shipped
# machines slew within +-115 deg and luff within +-16 deg (mjcf/bwr_heavy.xml); a reclaimer's boom
# conveyor and cables hold its slew within a turn either way, its luff far within.
JOINT_ANGLE = 6.283185307179586
JOINT_ANGLE_SOURCE = "radians: no slew or luff of a reclaimer turns more than a turn either way"

# m/s, a rail-mounted yard machine's long travel where its MJCF gives no rated speed. Stackers and
# reclaimers travel at some 30 m/min (0.5 m/s, both shipped machines' rating, mjcf/bwr_heavy.xml),
# the fastest at about 60 m/min on a long-travel gear: 5 m/s is no yard machine's travel.
RAIL_SPEED = 5.0
RAIL_SPEED_SOURCE = "a yard machine's long travel runs at 0.5-1 m/s, 30-60 m/min"

# deg/s, a slew or luff where the MJCF gives no rated speed: the shipped machines slew at 0.5-1.15
# deg/s and luff at about 0.1 deg/s (mjcf/bwr.xml, mjcf/bwr_heavy.xml); a boom of 50 m turning at
# 10 deg/s would sweep its wheel at 9 m/s, beyond any slew drive of a bucket wheel machine.
ANGULAR_SPEED = 10.0

# A grade is a content of the stream: a share, a percentage or parts per million of it. A grade
# whose name says "%" (Fe %, ash %) lies in 0-100; any other in 0-1e6, the whole in ppm. Its sd
# spans at most that range: a wider spread draws grades no material holds (and overflows the
# metrics' squares, writing Infinity into metrics.json).
GRADE_PERCENT = (0.0, 100.0)
GRADE_ANY = (0.0, 1e6)

_Facts = tuple[str, float, float, float, float]  # machine file name, weight N, reach m, boom m, wheel drive W


def check_bounds(scene) -> None:
    """SceneError, naming the file, the key and the limit, for a physical input of `scene` (a
    bwr_twin.config.sections.Scene; bwr_twin.config.rules calls this as a scene is built) out of
    its range."""
    p, pile, plant = scene.path, scene.stockpile, scene.plant
    if pile is not None:
        _within(p, "stockpile.bulk_density", pile.bulk_density, BULK_DENSITY, "kg/m3",
                "from wood chips to lead ore, CEMA's table of bulk materials")
        if pile.angle_of_repose is not None:
            _within(p, "stockpile.angle_of_repose", pile.angle_of_repose, ANGLE_OF_REPOSE, "deg",
                    "the angles at which freely formed piles of bulk solids stand, CEMA Table 3-1")
        if pile.windrow is not None:
            _within(p, "stockpile.windrow.angle_of_repose", pile.windrow.angle_of_repose, ANGLE_OF_REPOSE,
                    "deg", "the angles at which freely formed piles of bulk solids stand, CEMA Table 3-1")
    if scene.stacking is not None:
        _within(p, "stacking.bulk_density", scene.stacking.bulk_density, BULK_DENSITY, "kg/m3",
                "from wood chips to lead ore, CEMA's table of bulk materials")
        _within(p, "stacking.angle_of_repose", scene.stacking.angle_of_repose, ANGLE_OF_REPOSE, "deg",
                "the angles at which freely formed piles of bulk solids stand, CEMA Table 3-1")
    peak = plant.wind_speed + plant.gust_amplitude
    if peak > WIND_PEAK:
        raise SceneError(f"{p}: 'plant.wind_speed' + 'plant.gust_amplitude' ({plant.wind_speed:g} + "
                         f"{plant.gust_amplitude:g} m/s) must be at most {WIND_PEAK:g} m/s, the strongest "
                         "gust ever measured (113.3 m/s, Barrow Island, 1996)")
    _within(p, "plant.air_density", plant.air_density, AIR_DENSITY, "kg/m3",
            "the standard atmosphere from sea level at -50 degC to 8,000 m, ISO 2533")
    if scene.digging is not None:
        _within(p, "digging.lateral_ratio", scene.digging.lateral_ratio, LATERAL_RATIO, "",
                "the side force of a cut is a share of its cutting force")
    if scene.stacking is not None and scene.stacking.grade.mean is not None:
        _check_grade(scene)
    if scene.faults:
        _check_faults_against_machine(scene)
    if scene.neighbour is not None:
        _check_neighbour_speed(scene)
    if plant.frictionloss is not None or (scene.digging is not None and scene.digging.idle_power > 0):
        _check_against_machine(scene)


def _within(path: Path, key: str, value: float, bounds: tuple[float, float], unit: str, why: str) -> None:
    low, high = bounds
    if not low <= value <= high:
        unit = f" {unit}" if unit else ""
        raise SceneError(f"{path}: '{key}' must lie in [{low:g}, {high:g}]{unit} ({why}), got {value:g}")


def _check_against_machine(scene) -> None:
    """Friction within the machine's weight, the wheel's idle power within its drive's rating."""
    facts = _machine_facts(scene.machine.mjcf, version(scene.machine.mjcf), scene.plant.payload)
    if facts is None:
        return  # a model that does not compile is named where it is used
    name, weight, reach, boom, wheel_power = facts
    p, friction = scene.path, scene.plant.frictionloss
    if friction is not None:
        mu = FRICTION_COEFFICIENT
        limits = (("travel", mu * weight, "N", "its weight"),
                  ("slew", mu * weight * reach, "N m", f"its weight at the CP's {reach:.3g} m reach"),
                  ("luff", mu * weight * boom, "N m", f"its weight at the {boom:.3g} m boom's end"))
        for value, (axis, limit, unit, lever) in zip(friction, limits):
            if value > limit:
                raise SceneError(
                    f"{p}: 'plant.frictionloss' ({axis}) {value:.3g} {unit} is more than friction can be on "
                    f"{name}: at most {limit:.3g} {unit}, {lever} ({weight:.3g} N) with a friction "
                    f"coefficient of {mu:g}"
                )
    if scene.digging is not None and scene.digging.idle_power > wheel_power:
        raise SceneError(f"{p}: 'digging.idle_power' {scene.digging.idle_power:.3g} W is more than the wheel "
                         f"drive of {name} is rated for ({wheel_power:.3g} W, its 'wheel_power')")


@functools.lru_cache(maxsize=16)
def _machine_facts(mjcf: Path, stamp: tuple, payloads: tuple) -> _Facts | None:
    """(file name, weight N, CP reach from the slew axis m, boom length m, wheel drive W) of the
    plant with its payloads, or None if it does not compile; once per version of the file."""
    from bwr_twin.model.machine import Machine  # compiles MuJoCo models: only for scenes that need it

    try:
        machine = Machine.shared(mjcf, payloads)
    except ModelError:
        return None
    g = machine.geometry
    weight = float(machine.model.body_mass.sum()) * float(abs(machine.model.opt.gravity[2]))
    wheel_power = machine.wheel.power if machine.wheel is not None else float("inf")
    return mjcf.name, weight, float(g.pivot_reach + g.boom_length), float(g.boom_length), float(wheel_power)


def _check_grade(scene) -> None:
    """[stacking.grade]'s mean and sd within a content's range: a percentage if its name says %."""
    g, p = scene.stacking.grade, scene.path
    percent = "%" in g.name
    bounds, unit = (GRADE_PERCENT, "%") if percent else (GRADE_ANY, "")
    why = (f"the grade {g.name!r} is a percentage of the stream" if percent else
           f"a grade ({g.name!r}) is a content: a share, a percentage or ppm of the stream")
    _within(p, "stacking.grade.mean", g.mean, bounds, unit, why)
    _within(p, "stacking.grade.sd", g.sd, (0.0, bounds[1] - bounds[0]), unit, f"{why}: its spread spans at most "
            "the whole range")


def _axis_facts_or_none(mjcf: Path):
    try:
        return _axis_facts(mjcf, version(mjcf))
    except OSError:
        return None


def _check_faults_against_machine(scene) -> None:
    """Faults on hardware the plant lacks, and drifts and noises beyond what its axes can do."""
    facts = _axis_facts_or_none(scene.machine.mjcf)
    if facts is None:
        return  # a model that does not compile is named where it is used
    name, rated, spans, scanners, belt_scale = facts
    p = scene.path
    for number, fault in enumerate(scene.faults):
        where = f"faults[{number}]"
        if fault.kind == "scanner_blinded" and not scanners:
            raise SceneError(f"{p}: '{where}.kind' \"scanner_blinded\" blinds a scanner, but {name} has none "
                             "(no site named 'scanner...', docs/sensing.md): the fault would never act")
        if fault.kind == "belt_scale_frozen" and not belt_scale:
            raise SceneError(f"{p}: '{where}.kind' \"belt_scale_frozen\" freezes a belt scale, but {name} has none "
                             "(custom numeric 'belt_scale_distance', docs/sensing.md): the fault would never act")
        if fault.axis is None or fault.axis not in _AXES:
            continue
        j = _AXES.index(fault.axis)
        unit = "m" if j == 0 else "deg"
        if fault.kind == "encoder_drift" and fault.rate is not None:
            limit, why = rated[j], f"{name}'s rated {fault.axis} speed"
            if not math.isfinite(limit):
                limit, why = (RAIL_SPEED, RAIL_SPEED_SOURCE) if j == 0 else (
                    ANGULAR_SPEED, "no reclaimer's boom slews or luffs at 10 deg/s")
            if abs(fault.rate) > limit:
                raise SceneError(f"{p}: '{where}.rate' {fault.rate:g} {unit}/s drifts faster than the {fault.axis} "
                                 f"axis can move: at most {limit:.4g} {unit}/s ({why})")
        if fault.kind == "encoder_noise" and fault.sigma is not None:
            limit, why = spans[j], f"the span of {name}'s {fault.axis} envelope"
            if not math.isfinite(limit):
                limit, why = (2 * YARD_EXTENT, YARD_EXTENT_SOURCE) if j == 0 else (
                    2 * math.degrees(JOINT_ANGLE), JOINT_ANGLE_SOURCE)
            if fault.sigma > limit:
                raise SceneError(f"{p}: '{where}.sigma' {fault.sigma:g} {unit} is noisier than the {fault.axis} "
                                 f"axis is long: at most {limit:.4g} {unit} ({why})")


def _check_neighbour_speed(scene) -> None:
    """The neighbour's schedule no faster between its steps than its machine is rated to move."""
    facts = _axis_facts_or_none(scene.neighbour.mjcf)
    if facts is None:
        return  # a model that does not compile is named where it is used
    name, rated, _, _, _ = facts
    steps = scene.neighbour.schedule
    for i in range(1, len(steps)):
        dt = steps[i].t - steps[i - 1].t
        if not dt > 0:
            return  # the order of the steps is refused with its own message
        for j, axis in enumerate(_AXES):
            speed = abs(steps[i].q[j] - steps[i - 1].q[j]) / dt
            unit = "m/s" if j == 0 else "deg/s"
            limit, why = rated[j], f"{name}'s rated {axis} speed"
            if not math.isfinite(limit):
                limit, why = (RAIL_SPEED, RAIL_SPEED_SOURCE) if j == 0 else (
                    ANGULAR_SPEED, "no reclaimer's boom slews or luffs at 10 deg/s")
            if speed > limit:
                raise SceneError(f"{scene.path}: 'neighbour.schedule[{i}]' asks the neighbour's {axis} for "
                                 f"{speed:.4g} {unit} on average from schedule[{i - 1}]: at most {limit:.4g} {unit} "
                                 f"({why})")


_AXES = ("travel", "slew", "luff")  # qpos order, as bwr_twin.model.machine.AXES


@functools.lru_cache(maxsize=16)
def _axis_facts(mjcf: Path, stamp: tuple):
    """(file name, rated speeds m/s deg/s deg/s, envelope spans m deg deg, scanner names, has a belt
    scale) of a machine file, or None if it does not compile; once per version of the file."""
    from bwr_twin.model.machine import Machine  # compiles MuJoCo models: only for scenes that need it

    try:
        machine = Machine.shared(mjcf)
    except ModelError:
        return None
    rated = [float(v) for v in machine.rated_speed]
    rated[1:] = [math.degrees(v) for v in rated[1:]]
    spans = [float(high - low) for low, high in machine.envelope]
    spans[1:] = [math.degrees(v) for v in spans[1:]]
    scanners = tuple(s.name for s in machine.scanners)
    return mjcf.name, tuple(rated), tuple(spans), scanners, machine.belt_scale is not None
