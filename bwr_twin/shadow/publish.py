"""The shadow's own OPC UA server: what it found, for a SCADA or a maintenance system.

    Objects/Shadow/Time                                s: the end of the newest block, the machine's time
    Objects/Shadow/<Travel|Slew|Luff>/ForceResidual    N, N m: the drive's force the nominal machine lacks
                                     /PositionResidual m, rad: measured less predicted, at the block's end
                                     /SpeedResidual    m/s, rad/s: likewise
                                     /DriftResidual    m/s, rad/s: the encoder's speed less the drive's feedback
                                     /Health           %: 100 far from any alarm, 0 at one
    Objects/Shadow/WheelEnd/Health                     %: of the mass at the wheel end

Every Double is an analog item of OPC UA Part 8 with its EngineeringUnits and EURange
(`residual_ranges` says how each is set). The node ids follow the browse paths
("Shadow.Slew.Health") in the namespace NAMESPACE_URI.

Each alarm is a Part 9 condition of FaultAlarmType (an AlarmConditionType with FaultClass,
Axis, Size, SizeUnit and OnsetTime of its own, and OnsetEarliest and OnsetLatest: the onsets
the residuals leave possible, s, both OnsetTime for a stuck encoder, which is seen, not
estimated; Alternatives: the faults not told apart from it, "travel drive_derate", joined by
"; ", empty for most), one condition per class and axis, of the
Maintenance condition class, its SourceNode the axis's object (WheelEnd's for a mass change),
its Message the alarm as the console says it. A fault once found stays active while the shadow
runs (a fault does not heal itself); ConditionRefresh sends the active ones again. Every node is
read-only, and the endpoint serves without security: a SCADA reads it, nobody writes.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import time

import numpy as np
from asyncua import Node, Server, ua

from bwr_twin.errors import BwrError
from bwr_twin.opcua import nodes
from bwr_twin.opcua.analog import add_analog_item
from bwr_twin.opcua.conditions import Conditions
from bwr_twin.shadow.detect import AXES, HYPOTHESES, SOURCES, Alarm, Thresholds
from bwr_twin.shadow.twin import BLOCK, Blocks

NAMESPACE_URI = "urn:bwr_twin:shadow"
UNITS = {"ForceResidual": ("N", "N·m"), "PositionResidual": ("m", "rad"), "SpeedResidual": ("m/s", "rad/s"),
         "DriftResidual": ("m/s", "rad/s")}
FIELD = {"ForceResidual": "force", "PositionResidual": "position", "SpeedResidual": "speed", "DriftResidual": "drift"}
# How the EURange of each residual is set: the force's is the drive's rating (the largest force it
# can explain), the speeds' the axis's rated speed, the position's what the rated speed covers in
# a block. An axis its MJCF does not rate gets the force's noise times UNRATED_SIGMAS, and 1 m/s
# (rad/s) for its speed.
UNRATED_SIGMAS = 10.0
UNRATED_SPEED = 1.0  # m/s, rad/s
SEVERITY = {"stuck_encoder": 900}  # stop the axis: its position is unknown; every other fault 600 (plan a job)
DEFAULT_SEVERITY = 600
SOURCE_NAMES = {"travel": "Travel", "slew": "Slew", "luff": "Luff", "wheel end": "WheelEnd"}
FAULT_FIELDS = (("FaultClass", ua.VariantType.String), ("Axis", ua.VariantType.String),
                ("Size", ua.VariantType.Double), ("SizeUnit", ua.VariantType.String),
                ("OnsetTime", ua.VariantType.Double), ("OnsetEarliest", ua.VariantType.Double),
                ("OnsetLatest", ua.VariantType.Double), ("Alternatives", ua.VariantType.String))


def residual_ranges(limits: np.ndarray, rated_speed: np.ndarray, thresholds: Thresholds) -> dict[str, np.ndarray]:
    """Residual name -> (3, 2) the EURange (low, high) per axis, as RESIDUAL_RANGES says."""
    force = np.max(np.abs(limits), axis=1)
    force = np.where(np.isfinite(force), force, UNRATED_SIGMAS * np.asarray(thresholds.force_sigma))
    speed = np.where(np.isfinite(rated_speed), rated_speed, UNRATED_SPEED)
    spans = {"ForceResidual": force, "PositionResidual": speed * BLOCK, "SpeedResidual": speed,
             "DriftResidual": speed}
    return {name: np.stack([-span, span], axis=1) for name, span in spans.items()}


class ShadowServer:
    """The shadow's OPC UA server at `url`: `start`, then `residuals`, `verdict`, and `stop`.

    `latencies` holds, for each block published live, the wall-clock s between the arrival of
    the sample that completed it and the write of its residuals."""

    def __init__(self, url: str, ranges: dict[str, np.ndarray]):
        self.url, self.ranges = url, ranges
        self.latencies: list[float] = []
        self._server: Server | None = None
        self._variables: dict[tuple[str, str], Node] = {}  # (variable, source) -> node
        self._conditions: Conditions | None = None
        self._raised: set[tuple[str, str]] = set()

    async def start(self) -> None:
        """Listen at the url with the address space built; BwrError if it cannot."""
        logging.getLogger("asyncua").setLevel(logging.CRITICAL)  # the shadow reports in its own lines
        server = Server()
        await server.init()
        server.set_endpoint(self.url)
        server.set_server_name("bwr_twin shadow")
        server.set_security_policy([ua.SecurityPolicyType.NoSecurity])
        ns = await server.register_namespace(NAMESPACE_URI)
        shadow = await server.nodes.objects.add_object(ua.NodeId("Shadow", ns), ua.QualifiedName("Shadow", ns))
        self._variables["Time", "shadow"] = await add_analog_item(
            shadow, ua.NodeId("Shadow.Time", ns), ua.QualifiedName("Time", ns), "s", (0.0, 86400.0 * 365))
        objects = {}
        for j, source in enumerate(SOURCES):
            name = SOURCE_NAMES[source]
            objects[source] = folder = await nodes.add_object(shadow, ua.NodeId(f"Shadow.{name}", ns),
                                                              ua.QualifiedName(name, ns), ua.ObjectIds.BaseObjectType)
            await shadow.add_reference(folder.nodeid, ua.ObjectIds.HasEventSource)
            if j < 3:
                for variable, units in UNITS.items():
                    low, high = self.ranges[variable][j]
                    self._variables[variable, source] = await add_analog_item(
                        folder, ua.NodeId(f"Shadow.{name}.{variable}", ns), ua.QualifiedName(variable, ns),
                        units[min(j, 1)], (float(low), float(high)))
            self._variables["Health", source] = await add_analog_item(
                folder, ua.NodeId(f"Shadow.{name}.Health", ns), ua.QualifiedName("Health", ns), "%", (0.0, 100.0),
                value=100.0)
        fault_type = await server.create_custom_event_type(ns, "FaultAlarmType", ua.ObjectIds.AlarmConditionType,
                                                           list(FAULT_FIELDS))
        self._conditions = conditions = await Conditions.build(server, shadow)
        kinds = [(h.kind, h.source) for h in HYPOTHESES]
        kinds += [("stuck_encoder", axis) for axis in AXES]
        for index, (kind, source) in enumerate(kinds):
            condition = f"Shadow.{SOURCE_NAMES[source]}.{kind}"
            await conditions.add((kind, source), fault_type.nodeid, first=index == 0, source=objects[source],
                                 condition=ua.NodeId(condition, ns), name=kind,
                                 severity=SEVERITY.get(kind, DEFAULT_SEVERITY),
                                 condition_class=(ua.ObjectIds.MaintenanceConditionClassType, "Maintenance"))
        try:
            await server.start()
        except OSError as exc:
            reason = "the port is in use" if exc.errno == errno.EADDRINUSE else exc.strerror or str(exc)
            raise BwrError(f"--serve {self.url}: cannot listen ({reason})") from None
        self._server = server

    async def residuals(self, blocks: Blocks, measured_q: np.ndarray | None = None,
                        arrived: float | None = None) -> None:
        """Publish the newest of `blocks`' residuals (`measured_q`, the encoders at its end, is the
        view's); `arrived`: the perf_counter time the sample that completed it arrived, for
        `latencies`."""
        if not len(blocks.start):
            return
        await self._write("Time", "shadow", float(blocks.end[-1]))
        for j, axis in enumerate(AXES):
            for variable, field in FIELD.items():
                await self._write(variable, axis, float(getattr(blocks, field)[-1, j]))
        if arrived is not None:
            self.latencies.append(time.perf_counter() - arrived)

    async def verdict(self, health: dict[str, float], alarms: list[Alarm]) -> None:
        """Publish each source's health, and raise the alarms not raised yet."""
        for source, value in health.items():
            await self._write("Health", source, value)
        for alarm in alarms:
            key = (alarm.kind, alarm.axis)
            if key in self._raised:
                continue
            self._raised.add(key)
            earliest, latest = alarm.onset_range_s or (alarm.onset_s, alarm.onset_s)
            fields = {"FaultClass": alarm.kind, "Axis": alarm.axis, "Size": alarm.size, "SizeUnit": alarm.unit,
                      "OnsetTime": alarm.onset_s, "OnsetEarliest": earliest, "OnsetLatest": latest,
                      "Alternatives": "; ".join(alarm.alternatives)}
            await self._conditions.change(key, True, alarm.describe(), fields)

    async def _write(self, variable: str, source: str, value: float) -> None:
        await self._server.write_attribute_value(self._variables[variable, source].nodeid,
                                                 ua.DataValue(ua.Variant(value, ua.VariantType.Double)))

    async def stop(self) -> None:
        if self._server is not None:
            with contextlib.suppress(Exception):  # a client that went away mid-request does not stop the stop
                await self._server.stop()
            self._server = None

