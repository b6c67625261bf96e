"""The reclaimer as an FMI 2.0 co-simulation slave: one run of a scene, the importer the controller.

`python -m bwr_twin.export fmu` packs this file into the FMU with the scene (resources/scene.toml and
the files it reads); pythonfmu's binary loads it in the importing tool's Python, where `bwr_twin`
is installed. The machine is `bwr_twin.sim.twin.Twin`, the same one the OPC UA server serves, so
the FMU, the server and an in-process loop give one PID the same encoders, bit for bit.

Variables (their units and meanings in bwr_twin.export.fmu_variables), named as the OPC UA
address space names them:
- inputs `<Axis>.DriveSetpoint` (N, N m), held over the periods a step advances; in a bench
  reclaim, `SlewSpeedTrim` with `SlewSpeedTrimFromInput`, the importer's rate loop in place of the
  scene's;
- outputs per axis: encoder position and velocity, the reference's position, velocity and
  acceleration, the drive force applied, the limit switch; `ReclaimRate` where the scene digs,
  `BeltScale` and `WheelCurrent` where its machine has them;
- parameters read once, on leaving initialisation: the disturbance seed, amplitudes and hold time,
  and the encoders' resolution;
- `ControlPeriod`: a communication step is a whole number of these, anything else is refused.
"""

from __future__ import annotations

import ctypes
import math
import os
from dataclasses import dataclass, field
from itertools import chain
from operator import itemgetter
from pathlib import Path
from xml.etree.ElementTree import Element, SubElement

from pythonfmu import Boolean, Fmi2Causality, Fmi2Slave, Fmi2Variability, Integer, Real
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Initial, Fmi2Status

from bwr_twin.config.scene import load_scene
from bwr_twin.export.fmu_variables import (
    AXES,
    BELT_SCALE,
    NEIGHBOUR_POSITION,
    NEIGHBOUR_REPORT_TIME,
    OUTPUTS,
    PARAMETERS,
    RECLAIM_RATE,
    SETPOINT,
    SWITCHES,
    TRIM,
    TRIM_FROM_INPUT,
    UNITS,
    WHEEL_CURRENT,
    axis_unit,
)
from bwr_twin.model.instruments import read_instruments
from bwr_twin.model.spec import compile_model
from bwr_twin.sim.plant import mujoco_warnings
from bwr_twin.sim.twin import Twin

SCENE_FILE = "scene.toml"  # in the FMU's resources, beside the files it reads
STEP_TOLERANCE = 1e-9  # relative: a step this close to a whole number of periods counts as one
PICKERS_KEPT = 64  # the sets of Reals an importer gets at once whose picking is kept: a few in practice

def _keep_library_loaded(unzipped: Path) -> None:
    """Mark pythonfmu's library in this FMU as never to be unloaded (Linux: RTLD_NODELETE).

    Importers unload an FMU's library after fmi2FreeInstance; pythonfmu's runs Python, and the
    modules the model imported (MuJoCo, numba, their threads) outlive the instance, so an unloaded
    library can corrupt the heap when the process exits. Kept loaded, it is released with the process.
    """
    if not hasattr(os, "RTLD_NODELETE"):
        return  # Windows and macOS keep their own rules; the crash was seen on Linux
    for library in (unzipped / "binaries").glob("linux64/*.so"):
        ctypes.CDLL(str(library), mode=os.RTLD_NOW | os.RTLD_NOLOAD | os.RTLD_NODELETE)


@dataclass
class ValueRefs:
    """Where the input and output Reals sit in `BwrReclaimer._now`, by value reference."""

    setpoints: itemgetter | None = None  # the three DriveSetpoints, in axis order
    inputs: set[int] = field(default_factory=set)
    outputs: slice = field(default_factory=lambda: slice(0))  # OUTPUTS' axes, in the order the twin gives them
    rate: int | None = None  # ReclaimRate, in the scenes that dig
    trim: int | None = None  # SlewSpeedTrim, in a bench reclaim
    instruments: list[tuple[int, str]] = field(default_factory=list)  # (value reference, the twin's method)
    neighbour: tuple[slice, int] | None = None  # the neighbour's axes' slice, its report time's reference


class BwrReclaimer(Fmi2Slave):
    """One run of the packed scene, stepped a whole number of control periods at a time."""

    author = "bwr_twin"
    description = "Bucket wheel reclaimer (travel, slew, luff) under drive forces from the importer"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._scene_path = Path(self.resources) / SCENE_FILE
        _keep_library_loaded(Path(self.resources).parent)
        self._base = load_scene(self._scene_path)
        self._units: dict[str, str] = {}
        self._register()
        self._start_values()
        self._build()
        self.modelName = "BwrReclaimer"
        self.default_experiment = DefaultExperiment(0.0, self._twin.samples * self._twin.period, self._twin.period)

    # -- the variables --------------------------------------------------------------------------

    # The input and output Reals live in one list by value reference, `self._now`: the inputs as
    # last set, the outputs as of the last step. get_real picks an importer's set of them with one
    # operator.itemgetter, and set_real writes the inputs in place, where pythonfmu calls a Python
    # getter or setter per variable: twelve outputs cost 0.6 us a step so, 1.7 us through their
    # getters, against some 15 us for a whole control period in process. The getters and setters
    # (pythonfmu's own paths) use the list too.

    def _register(self) -> None:
        self._stored_refs: set[int] = set()
        self._pickers: dict[tuple[int, ...], itemgetter] = {}
        self._refs = refs = ValueRefs()
        setpoints = [self._stored(f"{axis}.{SETPOINT.name}", axis_unit(SETPOINT, i), SETPOINT.meaning,
                                  Fmi2Causality.input) for i, axis in enumerate(AXES)]
        refs.setpoints = itemgetter(*setpoints)
        refs.inputs = set(setpoints)
        first = len(self.vars)
        for signal in OUTPUTS:
            for i, axis in enumerate(AXES):
                self._stored(f"{axis}.{signal.name}", axis_unit(signal, i), signal.meaning, Fmi2Causality.output)
        refs.outputs = slice(first, len(self.vars))
        for i, axis in enumerate(AXES):
            self.register_variable(Boolean(f"{axis}.{SWITCHES.name}", causality=Fmi2Causality.output,
                                           variability=Fmi2Variability.discrete, description=SWITCHES.meaning,
                                           getter=lambda i=i: self._twin.at_limit[i]))
        if self._base.stockpile is not None:
            refs.rate = self._stored(RECLAIM_RATE.name, RECLAIM_RATE.unit, RECLAIM_RATE.meaning,
                                          Fmi2Causality.output)
            mjcf = self._base.machine.mjcf
            scale, motor = read_instruments(compile_model(mjcf), mjcf)
            for signal, present, method in ((BELT_SCALE, scale, "belt_scale"), (WHEEL_CURRENT, motor, "wheel_current")):
                if present is not None:
                    ref = self._stored(signal.name, signal.unit, signal.meaning, Fmi2Causality.output)
                    refs.instruments.append((ref, method))
        if self._base.neighbour is not None:
            first = len(self.vars)
            for i, axis in enumerate(AXES):
                self._stored(f"{axis}.{NEIGHBOUR_POSITION.name}", axis_unit(NEIGHBOUR_POSITION, i),
                             NEIGHBOUR_POSITION.meaning, Fmi2Causality.output)
            refs.neighbour = (slice(first, len(self.vars)),
                               self._stored(NEIGHBOUR_REPORT_TIME.name, NEIGHBOUR_REPORT_TIME.unit,
                                            NEIGHBOUR_REPORT_TIME.meaning, Fmi2Causality.output))
        if self._base.reclaim is not None:
            refs.trim = self._stored(TRIM.name, TRIM.unit, TRIM.meaning, Fmi2Causality.input)
            refs.inputs.add(refs.trim)
            self.register_variable(Boolean(TRIM_FROM_INPUT.name, causality=Fmi2Causality.input,
                                           variability=Fmi2Variability.discrete, description=TRIM_FROM_INPUT.meaning,
                                           getter=lambda: self._trim_from_input,
                                           setter=lambda v: setattr(self, "_trim_from_input", bool(v))))
        self.register_variable(Integer("PeriodsLeft", causality=Fmi2Causality.output,
                                       variability=Fmi2Variability.discrete, description="control periods left on the path; 0 at its end",
                                       getter=lambda: int(self._twin.periods_left)))
        self._real("ControlPeriod", "s", "the control period: a communication step is a whole number of them",
                   Fmi2Causality.calculatedParameter, variability=Fmi2Variability.fixed,
                   initial=Fmi2Initial.calculated, getter=lambda: self._twin.period)
        for name, _, _, unit, meaning in PARAMETERS:
            setter = lambda v, name=name: self._values.__setitem__(name, v)
            if unit is None:
                self.register_variable(Integer(name, causality=Fmi2Causality.parameter,
                                               variability=Fmi2Variability.fixed, description=meaning,
                                               getter=lambda name=name: int(self._values[name]), setter=setter))
            else:
                self._real(name, unit, meaning, Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                           getter=lambda name=name: float(self._values[name]), setter=setter)

    def _real(self, name: str, unit: str | None, meaning: str, causality: Fmi2Causality, **options) -> Real:
        described = f"{meaning}, {unit}" if unit else meaning
        variable = Real(name, causality=causality, description=described, **options)
        self.register_variable(variable)
        if unit:
            self._units[name] = unit
        return variable

    def _stored(self, name: str, unit: str | None, meaning: str, causality: Fmi2Causality) -> int:
        """An input or output Real whose value is kept in `self._now`: its value reference."""
        # `vr` is bound once registered, before either lambda is called
        setter = None
        if causality == Fmi2Causality.input:
            setter = lambda value: self._now.__setitem__(vr, float(value))
        vr = self._real(name, unit, meaning, causality, getter=lambda: self._now[vr], setter=setter).value_reference
        self._stored_refs.add(vr)
        return vr

    def get_real(self, vrs):
        pick = self._pickers.get(tuple(vrs)) or self._picker(vrs)
        return list(pick(self._now)) if pick else super().get_real(vrs)

    def _picker(self, vrs) -> itemgetter | None:
        """The itemgetter of `vrs` in `self._now`, kept for the next time; None, for pythonfmu's
        getters to answer, if there are fewer than two, or one is not an input or output Real
        (pythonfmu names a reference that is not a Real's), or PICKERS_KEPT sets are kept."""
        refs = tuple(vrs)
        if len(refs) < 2 or not self._stored_refs.issuperset(refs) or len(self._pickers) >= PICKERS_KEPT:
            return None
        self._pickers[refs] = pick = itemgetter(*refs)
        return pick

    def set_real(self, vrs, values):
        if not self._refs.inputs.issuperset(vrs):
            return super().set_real(vrs, values)  # a parameter's setter, or pythonfmu names the bad reference
        now = self._now
        for vr, value in zip(vrs, values):
            now[vr] = float(value)

    def to_xml(self, model_options=None) -> Element:
        """pythonfmu's modelDescription.xml with what FMI 2.0 asks and pythonfmu 0.7 leaves out:
        the unit of every Real and their definitions, and `ModelStructure/InitialUnknowns`."""
        root = super().to_xml(model_options or {})
        definitions = Element("UnitDefinitions")
        for name in sorted(set(self._units.values())):
            exponents = dict(UNITS[name])
            factor = exponents.pop("factor", None)
            attributes = {k: str(v) for k, v in exponents.items()} | ({"factor": repr(factor)} if factor else {})
            SubElement(SubElement(definitions, "Unit", name=name), "BaseUnit", attributes)
        root.insert(list(root).index(root.find("CoSimulation")) + 1, definitions)
        for element in root.find("ModelVariables"):
            if element.get("name") in self._units:
                element.find("Real").set("unit", self._units[element.get("name")])
        # An output or calculated parameter computed in initialisation is an initial unknown (FMI 2.0, 2.2.8).
        unknowns = [index for index, v in enumerate(self.vars.values(), start=1)
                    if v.causality in (Fmi2Causality.output, Fmi2Causality.calculatedParameter)]
        initial = SubElement(root.find("ModelStructure"), "InitialUnknowns")
        for index in unknowns:
            SubElement(initial, "Unknown", index=str(index))
        return root

    # -- the run --------------------------------------------------------------------------------

    def _scene_value(self, key: str, index: int | None):
        table, name = key.split(".")
        value = getattr(getattr(self._base, table), name)
        return value if index is None else value[index]

    def _start_values(self) -> None:
        """The parameters and inputs as the model description starts them."""
        self._values = {name: self._scene_value(key, index) for name, key, index, _, _ in PARAMETERS}
        self._now: list = [None] * len(self.vars)
        for vr in self._refs.inputs:
            self._now[vr] = 1.0 if vr == self._refs.trim else 0.0  # SlewSpeedTrim 1, the drive setpoints 0
        self._trim_from_input = False

    def _build(self) -> None:
        """A fresh run of the scene with the parameters as they are now."""
        overrides: dict[str, object] = {}
        for name, key, index, _, _ in PARAMETERS:
            if index is None:
                overrides[key] = self._values[name]
            else:
                overrides.setdefault(key, list(self._scene_value(key, None)))[index] = float(self._values[name])
        self._twin = Twin(load_scene(self._scene_path, overrides))
        self._read_outputs()

    def _read_outputs(self) -> None:
        """The outputs into `self._now`, as Python floats: once a step rather than once a get."""
        twin, now, refs = self._twin, self._now, self._refs
        now[refs.outputs] = chain(*twin.measured, twin.drive_applied())  # OUTPUTS' (3,) lists, end to end
        if refs.rate is not None:
            now[refs.rate] = twin.reclaim_rate()
            for ref, method in refs.instruments:
                now[ref] = getattr(twin, method)()
        if refs.neighbour is not None:
            axes, report_time = refs.neighbour
            now[axes], now[report_time] = twin.neighbour_position(), twin.neighbour_report_time()

    def exit_initialization_mode(self):
        self._build()  # the parameters as the importer left them

    def do_step(self, current_time: float, step_size: float) -> bool:
        twin = self._twin
        periods = step_size / twin.period
        whole = round(periods)
        if whole < 1 or abs(periods - whole) > STEP_TOLERANCE * whole:
            return self._refuse(f"a communication step of {step_size!r} s is not a whole number of control "
                                f"periods ({twin.period!r} s); step by n x {twin.period!r} s, n >= 1")
        if abs(current_time - twin.k * twin.period) > STEP_TOLERANCE * max(1.0, current_time):
            return self._refuse(f"the step starts at t = {current_time!r} s, the machine is at "
                                f"t = {twin.k * twin.period!r} s; steps follow each other without gaps")
        trim = self._now[self._refs.trim] if self._refs.trim is not None else 1.0
        from_input = self._trim_from_input
        if from_input and not (math.isfinite(trim) and trim > 0):
            return self._refuse(f"SlewSpeedTrim {trim!r}: must be a positive number while SlewSpeedTrimFromInput "
                                "is true")
        if self._base.reclaim is not None:
            twin.set_rate_trim(trim if from_input else None)
        if whole > twin.periods_left:
            return self._refuse(f"a step of {whole} control periods passes the path's end at "
                                f"t = {twin.samples * twin.period:g} s ({twin.periods_left} periods left)")
        drive = self._refs.setpoints(self._now)
        with mujoco_warnings():  # MuJoCo's warnings become the run's failure, never the importer's console
            for _ in range(whole):
                twin.advance(drive)
                if twin.failure is not None:
                    return self._refuse(f"the run diverged: {twin.failure}")
        self._read_outputs()
        return True

    def _refuse(self, message: str) -> bool:
        self.log(message, Fmi2Status.error)
        return False

    def terminate(self):
        # The machine (its MuJoCo batch and threads) goes now, with the last reference to it. Not
        # gc.collect() here: inside a pythonfmu call it frees objects pythonfmu's library still
        # refers to, and the process's heap is corrupted (seen as a crash at exit).
        self._twin = None

    def reset(self):
        self._start_values()
        self._build()

