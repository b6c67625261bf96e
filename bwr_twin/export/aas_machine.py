"""The machine's Digital Nameplate (IDTA 02006-2-0) and Technical Data (IDTA 02003-1-2), from
its compiled model.

The nameplate's maker, type and serial number are the OPC UA Machinery identification's values
(bwr_twin.serve.machinery.identification_values: the same `<custom><text>` entries, read by the
same code), so that the two agree; the rest of it from the MJCF's other identification entries,
or a placeholder where the file has none (docs/aas.md lists the keys and placeholders).
"""

from __future__ import annotations

import datetime

import mujoco
import numpy as np
from basyx.aas import model

from bwr_twin.export.aas_elements import Measures, collection, prop, reference, text
from bwr_twin.export.aas_templates import NAMEPLATE, TECHNICAL_DATA
from bwr_twin.model.machine import AXES, CP_SITES, Machine
from bwr_twin.serve.machinery import identification_values

UNKNOWN = "unknown"  # what the nameplate says where the MJCF does not (docs/aas.md)
# Nameplate element -> the MJCF text entry that fills it, beyond the OPC UA identification's.
NAMEPLATE_TEXTS = {"YearOfConstruction": "year_of_construction", "NationalCode": "manufacturer_country",
                   "CityTown": "manufacturer_city", "Street": "manufacturer_street", "Zipcode": "manufacturer_zipcode"}
# The kind of machine, by its CP site (bwr_twin.model.machine.CP_SITES): a reclaimer's wheel or a stacker's boom tip.
PRODUCT_FAMILY = dict(zip(CP_SITES, ("bucket wheel reclaimer", "stacker")))
AXIS_UNITS = {"travel": ("m/s", "N"), "slew": ("rad/s", "N m"), "luff": ("rad/s", "N m")}


def nameplate_values(machine: Machine) -> dict[str, str]:
    """Nameplate element -> value: the OPC UA identification's, then the other MJCF entries;
    UNKNOWN where the file gives nothing."""
    opc = identification_values(machine)
    values = {"ManufacturerName": opc["Manufacturer"], "ManufacturerProductDesignation": opc["Model"],
              "SerialNumber": opc["SerialNumber"], "URIOfTheProduct": opc["ProductInstanceUri"]}
    values |= {name: machine.identification.get(key, "") for name, key in NAMEPLATE_TEXTS.items()}
    return {name: value or UNKNOWN for name, value in values.items()}


def nameplate(machine: Machine, submodel_id: str) -> model.Submodel:
    v, t = nameplate_values(machine), NAMEPLATE
    contact = collection(t, "ContactInformation", *(text(t, name, v[name]) for name in ("NationalCode", "CityTown",
                                                                                          "Street", "Zipcode")))
    elements = [prop(t, "URIOfTheProduct", v["URIOfTheProduct"]), text(t, "ManufacturerName", v["ManufacturerName"]),
                text(t, "ManufacturerProductDesignation", v["ManufacturerProductDesignation"]), contact,
                text(t, "ManufacturerProductFamily", product_family(machine)),
                text(t, "ManufacturerProductType", machine.name), prop(t, "SerialNumber", v["SerialNumber"]),
                prop(t, "YearOfConstruction", v["YearOfConstruction"])]
    return model.Submodel(submodel_id, id_short="Nameplate", semantic_id=reference(t.semantic_id),
                          submodel_element=elements, kind=model.ModellingKind.INSTANCE)


def product_family(machine: Machine) -> str:
    """What kind of machine it is, told by its CP site."""
    return PRODUCT_FAMILY[mujoco.mj_id2name(machine.model, mujoco.mjtObj.mjOBJ_SITE, machine.cp_site)]


def technical_data(machine: Machine, submodel_id: str, measures: Measures) -> model.Submodel:
    """General information, and the technical properties in sections: drives, envelope, wheel and
    capacity, instruments and scanners; every number from the compiled model, with its unit."""
    v, t = nameplate_values(machine), TECHNICAL_DATA
    general = collection(t, "GeneralInformation", prop(t, "ManufacturerName", v["ManufacturerName"]),
                         text(t, "ManufacturerProductDesignation", v["ManufacturerProductDesignation"]),
                         prop(t, "ManufacturerArticleNumber", machine.name),
                         prop(t, "ManufacturerOrderCode", UNKNOWN))
    sections = [_drives(machine, measures), _envelope(machine, measures), _wheel(machine, measures),
                _instruments(machine, measures)]
    properties = collection(t, "TechnicalProperties", *(s for s in sections if s is not None))
    further = collection(t, "FurtherInformation",
                         text(t, "TextStatement", f"From the compiled MuJoCo model {machine.path.name}; SI units."),
                         prop(t, "ValidDate", datetime.date.today(), value_type=model.datatypes.Date))
    return model.Submodel(submodel_id, id_short="TechnicalData", semantic_id=reference(t.semantic_id),
                          submodel_element=[general, properties, further], kind=model.ModellingKind.INSTANCE)


def _section(name: str, elements: list) -> model.SubmodelElementCollection | None:
    return collection(TECHNICAL_DATA, "MainSection", *elements, as_name=name) if elements else None


def _drives(machine: Machine, measures: Measures):
    elements = []
    for j, axis in enumerate(AXES):
        speed_unit, force_unit = AXIS_UNITS[axis]
        title = axis.capitalize()
        if np.isfinite(machine.rated_speed[j]):
            elements.append(measures.measure(f"RatedSpeed{title}", machine.rated_speed[j], speed_unit,
                                             f"rated speed of the {axis} drive"))
        if np.isfinite(machine.drive_limits[j, 1]):
            elements.append(measures.measure(f"DriveRating{title}", machine.drive_limits[j, 1], force_unit,
                                             f"largest force or torque the {axis} drive gives"))
    return _section("Drives", elements)


def _envelope(machine: Machine, measures: Measures):
    elements = []
    for j, axis in enumerate(AXES):
        unit = "m" if axis == "travel" else "rad"
        low, high = machine.envelope[j]
        elements += [measures.measure(f"Envelope{axis.capitalize()}Min", low, unit, f"lowest {axis} in operation"),
                     measures.measure(f"Envelope{axis.capitalize()}Max", high, unit, f"highest {axis} in operation")]
    g = machine.geometry
    elements += [measures.measure("BoomLength", g.boom_length, "m", "luff pivot to the bucket wheel centre"),
                 measures.measure("PivotHeight", g.pivot_height, "m", "luff pivot above the rail")]
    return _section("Envelope", elements)


def _wheel(machine: Machine, measures: Measures):
    wheel = machine.wheel
    if wheel is None:
        return None
    elements = [measures.measure("WheelDiameter", wheel.diameter, "m", "the bucket wheel's cutting circle"),
                measures.measure("WheelWidth", wheel.width, "m", "the buckets' width"),
                measures.measure("WheelBuckets", wheel.buckets, "1", "buckets on the wheel"),
                measures.measure("BucketVolume", wheel.bucket_volume, "m3", "material one bucket holds"),
                measures.measure("WheelDischargesPerMinute", wheel.discharges_per_minute, "1/min",
                                 "buckets emptied a minute"),
                measures.measure("VolumetricCapacity", wheel.capacity, "m3/s", "most material the buckets carry away")]
    if np.isfinite(wheel.power):
        elements.append(measures.measure("WheelDrivePower", wheel.power, "W", "rating of the wheel drive"))
    return _section("BucketWheel", elements)


def _instruments(machine: Machine, measures: Measures):
    elements = []
    for scanner in machine.scanners:
        name = scanner.name.capitalize()
        elements += [measures.measure(f"{name}Rate", scanner.rate, "Hz", f"scans a second of {scanner.name}"),
                     measures.measure(f"{name}Range", scanner.max_range, "m", f"longest range of {scanner.name}"),
                     measures.measure(f"{name}Step", scanner.step, "rad", f"angle between rays of {scanner.name}")]
    if machine.belt_scale is not None:
        elements.append(measures.measure("BeltScaleSpeed", machine.belt_scale.speed, "m/s", "the belt's speed"))
    if machine.wheel_motor is not None:
        elements.append(measures.measure("WheelMotorVoltage", machine.wheel_motor.voltage, "V",
                                         "the wheel motor's line-to-line voltage"))
    return _section("Instruments", elements)
