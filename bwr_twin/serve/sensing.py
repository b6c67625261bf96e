"""The run's own senses on Objects/Reclaimer, only where the run has them (docs/opcua.md): each
boom scanner's latest profile under `Scanners`, each scheduled fault's state under `Faults`.
The belt scale and the wheel current are machine-level rows of
`bwr_twin.serve.address_space.INSTRUMENT_VARIABLES`, published with the other variables.

    Scanners/<site>/Ranges     Double[rays], m from the scanner's origin along each ray, NaN where
                               nothing returned (dropped, blinded or no pile within range)
    Scanners/<site>/Angles     Double[rays], rad: each ray's angle in the site's x-z plane, from
                               its -z axis towards +x (docs/sensing.md); written once
    Scanners/<site>/ScanTime   Double, s: the SimTime of the scan that Ranges holds
    Scanners/<site>/Scans      UInt32: scans so far; 0: none yet (Ranges all NaN, ScanTime 0)
    Faults/Fault<i>_<kind>     Boolean: faults[i] acts in the control period that starts at SimTime

A publication writes a scanner's nodes only when it has scanned since the last one, and a
fault's only when its state changed: a Step that brings neither costs a few comparisons.
"""

from __future__ import annotations

from collections.abc import Mapping
from datetime import datetime, timezone

from asyncua import Node, ua

from bwr_twin.config.faults import FaultSection
from bwr_twin.opcua import nodes
from bwr_twin.serve.address_space import AddressSpace, B, D, U, Variable, data_value
from bwr_twin.sim.ranges import scanner_ranges
from bwr_twin.sim.twin import LatestScan, Twin

RANGES = Variable("Ranges", D, "m", "the scanner's latest profile: per ray, the distance from the scanner's origin "
                  "to where the ray met the pile, NaN where nothing returned; its time is ScanTime")
ANGLES = Variable("Angles", D, "rad", "each ray's angle in the scanner's x-z plane, from its -z axis towards its "
                  "+x axis (docs/sensing.md), in the order of Ranges")
SCAN_TIME = Variable("ScanTime", D, "s", "the simulated time of the scan that Ranges holds; 0 before the first")
SCANS = Variable("Scans", U, None, "the scanner's scans so far; 0: none yet")


def fault_name(index: int, fault: FaultSection) -> str:
    """The browse name of a fault's state: 'Fault0_belt_scale_frozen' for faults[0]."""
    return f"Fault{index}_{fault.kind}"


def fault_meaning(index: int, fault: FaultSection) -> str:
    """What a fault's state says: the scene's table, and when it is true."""
    what = {"axis": fault.axis, "scanner": fault.scanner, "rate": fault.rate, "sigma": fault.sigma,
            "periods": fault.periods, "percent": fault.percent, "mass": fault.mass, "ramp": fault.ramp}
    details = ", ".join(f"{key} {value}" for key, value in what.items() if value is not None)
    window = f"from {fault.start:g} s" + (f" for {fault.duration:g} s" if fault.duration is not None else
                                          " to the run's end")
    return (f"faults[{index}], {fault.kind}{f' ({details})' if details else ''}, {window}: true in the control "
            "periods it acts, the one starting at SimTime")


class Sensing:
    """The scanner and fault nodes of one run, and their publishing from the twin's readings."""

    def __init__(self, space: AddressSpace, scanners: list[dict[str, Node]], rays: list[int], faults: list[Node]):
        self.space = space
        self._scanners, self._rays = scanners, rays  # per scanner: variable name -> node; its rays
        self._faults = faults  # per fault: its state's node
        self._published_scans: list[tuple[object, int]] = [(None, 0)] * len(scanners)  # (log, count) shown
        self._published_faults: tuple[bool, ...] | None = None

    @classmethod
    async def build(cls, space: AddressSpace, twin: Twin) -> Sensing | None:
        """The nodes of `twin`'s scanners and faults under Objects/Reclaimer; None if it has neither."""
        loop, ns = twin.loop, space.namespace
        scanners = loop.scanning.scanners if loop.scanning is not None else ()
        faults = loop.faults.faults
        if not scanners and not faults:
            return None
        reclaimer = space.objects[None]
        scanner_nodes = []
        if scanners:
            folder = await nodes.add_object(reclaimer, ua.NodeId("Reclaimer.Scanners", ns),
                                            ua.QualifiedName("Scanners", ns), ua.ObjectIds.FolderType,
                                            description="the machine's 2D profile scanners (docs/sensing.md)")
        for scanner in scanners:
            path = f"Reclaimer.Scanners.{scanner.name}"
            node = await nodes.add_object(folder, ua.NodeId(path, ns), ua.QualifiedName(scanner.name, ns),
                                          ua.ObjectIds.BaseObjectType,
                                          description=f"the scanner at site {scanner.name}: {scanner.rays} rays, "
                                                      f"{scanner.rate:g} scans a second")
            ranges = scanner_ranges(scanner, loop.duration)
            rays, nan = scanner.rays, float("nan")
            found = {
                "Ranges": await space.add_variable(node, f"{path}.Ranges", RANGES, "m", ranges["Ranges"],
                                                   value=[nan] * rays, length=rays),
                "Angles": await space.add_variable(node, f"{path}.Angles", ANGLES, "rad", ranges["Angles"],
                                                   value=[float(a) for a in scanner.angles], length=rays),
                "ScanTime": await space.add_variable(node, f"{path}.ScanTime", SCAN_TIME, "s", ranges["ScanTime"]),
                "Scans": await space.add_variable(node, f"{path}.Scans", SCANS, None, None),
            }
            scanner_nodes.append(found)
        fault_nodes = []
        if faults:
            folder = await nodes.add_object(reclaimer, ua.NodeId("Reclaimer.Faults", ns),
                                            ua.QualifiedName("Faults", ns), ua.ObjectIds.FolderType,
                                            description="the scene's [[faults]]: each one's state (docs/sensing.md)")
        for index, fault in enumerate(faults):
            name = fault_name(index, fault)
            variable = Variable(name, B, None, fault_meaning(index, fault))
            fault_nodes.append(await space.add_variable(folder, f"Reclaimer.Faults.{name}", variable, None, None))
        return cls(space, scanner_nodes, [s.rays for s in scanners], fault_nodes)

    async def publish(self, readings: Mapping[str, object]) -> None:
        """Write the scans made and the faults' states changed since the last publication."""
        now = None
        write = self.space.server.write_attribute_value
        for i, scan in enumerate(readings.get("Scans", ())):
            key = (None, 0) if scan is None else (scan.log, scan.count)
            if key == self._published_scans[i]:
                continue
            now = now or datetime.now(timezone.utc)
            for name, value, variant in _scan_values(scan, self._rays[i]):
                await write(self._scanners[i][name].nodeid, data_value(value, variant, now))
            self._published_scans[i] = key
        states = readings.get("Faults")
        if states is not None and states != self._published_faults:
            now = now or datetime.now(timezone.utc)
            before = self._published_faults or (None,) * len(states)
            for node, state, was in zip(self._faults, states, before):
                if state != was:
                    await write(node.nodeid, data_value(state, B, now))
            self._published_faults = states


def _scan_values(scan: LatestScan | None, rays: int) -> list[tuple[str, object, ua.VariantType]]:
    """What a scanner's nodes show of its latest scan; before the first, no returns, time 0, count 0."""
    if scan is None:
        return [("Ranges", [float("nan")] * rays, D), ("ScanTime", 0.0, D), ("Scans", 0, U)]
    return [("Ranges", scan.ranges().tolist(), D), ("ScanTime", float(scan.time), D), ("Scans", scan.count, U)]
