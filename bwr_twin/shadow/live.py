"""The live shadow: an OPC UA client (asyncua) of the machine's PLC, reading the tags a tag map
names, and the shadow over its samples as they arrive.

Each poll reads every tag in one Read request, so that a sample's readings belong together; a
poll that finds the time unchanged adds nothing. Every whole block of samples is handed to the
twin as soon as it is complete, and the detectors run over the blocks so far (bwr_twin.shadow.
detect, the same as over a log). When the source drops, the shadow says so, reconnects every
RETRY s, and says when it is back: the samples it missed make a gap, which no block spans and
which is reported as one, never as an alarm.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from asyncua import Client, ua

from bwr_twin.errors import BwrError
from bwr_twin.shadow.detect import SOURCES, Alarm, Thresholds, assess
from bwr_twin.shadow.measured import GAP, Air, Measured
from bwr_twin.shadow.tags import Tags
from bwr_twin.shadow.twin import Blocks, ShadowTwin

RETRY = 1.0  # s between attempts to reach a lost source
REQUEST_TIMEOUT = 60.0  # s an OPC UA request may take on a busy machine


@dataclass(frozen=True)
class Sample:
    """One read of every tag the map names."""

    time: float  # s, the PLC's
    position: np.ndarray  # (3,) m, rad, rad: the encoders
    speed: np.ndarray  # (3,) m/s, rad/s, rad/s: the speed feedback
    force: np.ndarray  # (3,) N, N m, N m: the drives' force, held over the period that ended at `time`
    wind: float | None = None  # m/s: the anemometer's, over the same period, where the map names it

    @classmethod
    def of(cls, values: Sequence[float]) -> Sample:
        """From the tags' values in Tags.nodes()'s order."""
        row = np.asarray(values, dtype=float)
        axes = row[1:10].reshape(3, 3)  # per axis: position, speed, force
        return cls(float(row[0]), axes[:, 0].copy(), axes[:, 1].copy(), axes[:, 2].copy(),
                   float(row[10]) if len(row) > 10 else None)


class Source:
    """The machine's PLC over OPC UA: its tags, checked once connected, read a sample at a time."""

    def __init__(self, url: str, tags: Tags):
        self.url, self.tags = url, tags
        self._client: Client | None = None
        self._nodes: list = []

    async def connect(self) -> None:
        """Connect and find every tag; BwrError naming a tag that is missing, not a Double, or in
        another unit than the map needs."""
        client = Client(self.url, timeout=REQUEST_TIMEOUT)
        await client.connect()
        try:
            namespaces = await client.get_namespace_array()
            if self.tags.namespace not in namespaces:
                raise BwrError(f"{self.tags.path}: namespace {self.tags.namespace!r} is not served at {self.url}")
            ns = namespaces.index(self.tags.namespace)
            nodes = []
            for node_id, what, unit in self.tags.nodes():
                node = client.get_node(ua.NodeId(node_id, ns))
                await _check_tag(node, node_id, what, unit, self.tags)
                nodes.append(node)
        except BaseException:
            await _close(client)
            raise
        self._client, self._nodes = client, nodes

    async def read(self) -> Sample:
        """Every tag, in one Read request."""
        return Sample.of(await self._client.read_values(self._nodes))

    async def close(self) -> None:
        if self._client is not None:
            await _close(self._client)
            self._client = None


async def _close(client: Client) -> None:
    """Close a connection that may already be lost: one that is cannot be closed cleanly, and need not be."""
    with contextlib.suppress(Exception):
        await client.disconnect()


async def _check_tag(node, node_id: str, what: str, unit: str, tags: Tags) -> None:
    try:
        value = await node.read_data_value()
    except ua.UaStatusCodeError as exc:
        raise BwrError(f"{tags.path}: tag {what} = {node_id!r}: {exc.__class__.__name__}: the node cannot be "
                       "read (missing?)") from None
    if value.Value is None or value.Value.VariantType != ua.VariantType.Double:
        kind = None if value.Value is None else value.Value.VariantType.name
        raise BwrError(f"{tags.path}: tag {what} = {node_id!r} is a {kind}, not the Double the shadow needs")
    try:
        units = await node.get_child("0:EngineeringUnits")
        shown = (await units.read_value()).DisplayName.Text
    except ua.UaStatusCodeError:
        return  # a tag without EngineeringUnits: its unit is the map's word
    if shown != unit:
        raise BwrError(f"{tags.path}: tag {what} = {node_id!r} is in {shown}, the shadow needs {unit}")


class Output(Protocol):
    """Where the live shadow publishes: its OPC UA server (bwr_twin.shadow.publish), its view
    (bwr_twin.shadow.view)."""

    async def residuals(self, blocks: Blocks, measured_q: np.ndarray, arrived: float | None = None) -> None:
        """The blocks a sample completed; the encoders at the newest one's end; when the sample came."""

    async def verdict(self, health: dict[str, float], alarms: list[Alarm]) -> None:
        """Each source's health and every alarm so far, after the detectors ran."""

    async def stop(self) -> None:
        """Stop serving."""


class LiveShadow:
    """The shadow over a source's samples as they arrive: blocks, gaps and alarms so far.

    `say(event)` hears every event (a dict, as events.jsonl holds them) as it happens: the source
    lost and back, a gap, an alarm. Without `thresholds` (None) it only makes blocks, to learn
    thresholds from (`blocks()`, `measured()`); set them and it detects from the next block on.
    `air`: the air of the anemometer's wind, when the samples carry it (Tags.wind)."""

    def __init__(self, twin: ShadowTwin, thresholds: Thresholds | None, say: Callable[[dict], None],
                 air: Air | None = None):
        self._twin, self.thresholds, self._say, self._air = twin, thresholds, say, air
        self._samples: list[Sample] = []
        self._done = 0  # the first sample of the block not yet handed to the twin
        self._blocks: list[Blocks] = []
        self.alarms: list[Alarm] = []
        self.health = dict.fromkeys(SOURCES, 100.0)  # % after the newest block (bwr_twin.shadow.detect.assess)
        self._statistics: list = []  # the detectors' statistics of the blocks so far, for these thresholds
        self._statistics_for: Thresholds | None = None
        self.gaps: list[tuple[float, float]] = []

    @property
    def time(self) -> float:
        """s: the newest sample's time; 0 before the first."""
        return self._samples[-1].time if self._samples else 0.0

    def add(self, sample: Sample, detect: bool = True) -> bool:
        """One sample; one whose time has not moved on adds nothing.
        True if it completed a block, whose detectors have run unless `detect` is False (then
        call `detect()`)."""
        if self._samples and sample.time <= self._samples[-1].time:
            return False
        self._samples.append(sample)
        made = self._advance()
        if made and detect:
            self.detect()
        return made

    def measured(self, start: int = 0) -> Measured:
        """The samples from `start` on but the newest, whose force (and wind) the next sample
        reads: a force tag gives the force held over the period that ended at its sample's time,
        and so does the anemometer."""
        samples = self._samples[start:]
        time = np.array([s.time for s in samples])
        position, speed = np.array([s.position for s in samples]), np.array([s.speed for s in samples])
        force = np.array([s.force for s in samples])
        period = float(np.median(np.diff(time))) if len(samples) > 1 else 1.0
        windy = self._air is not None and samples[0].wind is not None
        wind = np.array([s.wind for s in samples[1:]]) if windy else None
        return Measured(time[:-1], position[:-1], speed[:-1], force[1:], period, speed[:-1], wind,
                        self._air if windy else None)

    def _advance(self) -> bool:
        samples = self._samples
        if len(samples) >= 3:
            steps = np.diff([s.time for s in samples[-3:]])
            if steps[1] > GAP * steps[0]:  # the newest step is a gap: nothing before it makes a block with what follows
                gap = (samples[-2].time, samples[-1].time)
                self.gaps.append(gap)
                self._say({"event": "gap", "time_s": gap[0], "from_s": gap[0], "to_s": gap[1],
                           "meaning": "no samples: nothing is concluded over it"})
                self._done = len(samples) - 1
                return False
        tail = self.measured(self._done) if len(samples) - self._done > 3 else None
        if tail is None:
            return False
        blocks = self._twin.blocks(tail)
        if not len(blocks.start):
            return False
        self._blocks.append(blocks)
        self._done += int(np.searchsorted(tail.time, blocks.end[-1]))
        return True

    def detect(self) -> None:
        """Run the detectors over the blocks so far (with thresholds set): say each new alarm,
        and update `health`."""
        if self.thresholds is None or not self._blocks:
            return
        if self._statistics_for is not self.thresholds:  # thresholds set or changed: start afresh
            self._statistics, self._statistics_for = [], self.thresholds
        alarms, self.health = assess(self.blocks(), self.thresholds, self._statistics, complete=False)
        known = {(a.kind, a.axis) for a in self.alarms}
        for alarm in alarms:
            if (alarm.kind, alarm.axis) not in known:
                self.alarms.append(alarm)
                self._say(alarm.event())

    def newest(self) -> Blocks:
        """The blocks the newest sample completed."""
        return self._blocks[-1]

    def position(self, t: float) -> np.ndarray:
        """(3,) the encoders' reading at the sample of time `t` (m, rad, rad)."""
        for sample in reversed(self._samples):
            if sample.time <= t:
                return sample.position.copy()
        return self._samples[0].position.copy()

    def blocks(self) -> Blocks:
        """Every block so far."""
        return Blocks(*(np.concatenate([getattr(b, f) for b in self._blocks]) for f in Blocks.__dataclass_fields__))


async def poll_once(source: Source, shadow: LiveShadow, say: Callable[[dict], None],
                    outputs: Sequence[Output] = ()) -> bool:
    """Read one sample into the shadow; on a dropped source say so, reconnect (every RETRY s until
    it answers) and say when it is back. True if a sample was read. A block's residuals go to
    the `outputs` as soon as the twin has them, then its detectors run, then the health and the
    alarms go to them."""
    try:
        sample = await source.read()
    except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError, AttributeError):
        say({"event": "source_lost", "time_s": shadow.time, "source": source.url})
        await source.close()
        await _reconnect(source, shadow, say)
        return False
    arrived = time.perf_counter()
    if shadow.add(sample, detect=not outputs) and outputs:
        newest = shadow.newest()
        for output in outputs:
            await output.residuals(newest, shadow.position(float(newest.end[-1])), arrived)
        shadow.detect()
        for output in outputs:
            await output.verdict(shadow.health, shadow.alarms)
    return True


async def _reconnect(source: Source, shadow: LiveShadow, say: Callable[[dict], None]) -> None:
    """Try the source every RETRY s until it answers; say when it is back."""
    while True:
        try:
            await source.connect()
            break
        except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError):
            await asyncio.sleep(RETRY)
    say({"event": "source_back", "time_s": shadow.time, "source": source.url})


async def run_live(source: Source, shadow: LiveShadow, say: Callable[[dict], None], *, poll: float,
                   duration: float | None, outputs: Sequence[Output] = ()) -> None:
    """Watch `source` every `poll` s for `duration` s (None: until cancelled), publishing to
    `outputs`; a source that cannot be reached at the start is said so and tried again
    every RETRY s, as one that drops later."""
    async def watch() -> None:
        try:
            await source.connect()
        except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError):
            say({"event": "source_lost", "time_s": 0.0, "source": source.url})
            await _reconnect(source, shadow, say)
        while True:
            await poll_once(source, shadow, say, outputs)
            await asyncio.sleep(poll)

    try:
        await asyncio.wait_for(watch(), duration)
    except asyncio.TimeoutError:
        pass
    finally:
        await source.close()
