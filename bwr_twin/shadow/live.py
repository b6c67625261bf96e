"""The live shadow: an OPC UA client (asyncua) of the machine's PLC, reading the tags a tag map
names, and the shadow over its samples as they arrive.

By default the shadow subscribes to every tag and groups the notifications into samples by
their source timestamp: a PLC's server stamps one cycle's values alike, so a sample is complete
when every tag has reported that stamp (a server hands a publish's notifications over item by
item, so their order says nothing). Polled instead (`poll`), each read takes every tag in one
Read request, for a server that stamps its values apart; a poll that finds the time unchanged
adds nothing. Every whole block of samples is handed to the twin as soon as it is complete, and
the detectors run over the blocks so far (bwr_twin.shadow.detect, the same as over a log). When
the source drops, the shadow says so, reconnects every RETRY s, and says when it is back: the
samples it missed make a gap, which no block spans and which is reported as one, never as an
alarm.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from asyncua import Client, ua

from bwr_twin.errors import BwrError
from bwr_twin.shadow.detect import ISOLATE, SOURCES, WINDOW, Alarm, Thresholds, assess
from bwr_twin.shadow.measured import GAP, Air, Measured
from bwr_twin.shadow.tags import Tags
from bwr_twin.shadow.twin import Blocks, ShadowTwin

RETRY = 1.0  # s between attempts to reach a lost source
KEPT_BLOCKS = 20 * WINDOW  # blocks a watching live shadow keeps at least (40 min of 1 s blocks)
REQUEST_TIMEOUT = 60.0  # s an OPC UA request may take on a busy machine
PUBLISHING_INTERVAL = 10.0  # ms: how often the subscription's notifications are sent, a control period
KEEP_ALIVE = 500  # publishing intervals without a notification before the server says it is there (5 s)
LIFETIME = 3000  # publishing intervals without the client before the server ends the subscription (30 s)
QUEUED = 1000  # notifications a tag's monitored item keeps between two publishes (10 s at a 10 ms cycle)
QUIET = 2.0  # s without a notification after which the subscribed source is asked whether it is still there
APART = 100  # stamps waiting on a tag: more, and the server stamps the tags apart (a subscription cannot group them)


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
    """The machine's PLC over OPC UA: its tags, checked once connected, then subscribed to; or
    with `poll` (s), read a sample every `poll` s."""

    def __init__(self, url: str, tags: Tags, poll: float | None = None):
        self.url, self.tags, self.poll = url, tags, poll
        self._client: Client | None = None
        self._nodes: list = []
        self._arrivals: Arrivals | None = None

    async def connect(self) -> None:
        """Connect and find every tag; BwrError naming a tag that is missing, not a Double, or in
        another unit than the map needs."""
        # asyncua's own liveness probe as patient as a request: a source that stops answering is
        # found by `read()`, and a busy source is not dropped after a second's silence
        client = Client(self.url, timeout=REQUEST_TIMEOUT, watchdog_intervall=REQUEST_TIMEOUT)
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
            arrivals = None if self.poll is not None else await _subscribe(client, nodes, self.tags)
        except BaseException:
            await _close(client)
            raise
        self._client, self._nodes, self._arrivals = client, nodes, arrivals

    async def read(self) -> list[Sample]:
        """The samples since the last call, oldest first. Polled: every tag in one Read request.
        Subscribed: every sample complete by now, waiting up to QUIET s for the first; none if
        none came and the source still answers (asyncua's errors if it does not)."""
        if self._arrivals is None:
            return [Sample.of(await self._client.read_values(self._nodes))]
        samples = await self._arrivals.take(QUIET)
        if not samples:
            await self._client.read_values(self._nodes[:1])  # still there? raises if not
        return samples

    async def close(self) -> None:
        if self._client is not None:
            await _close(self._client)
            self._client, self._arrivals = None, None


class Arrivals:
    """A subscription's notifications grouped into samples, by source timestamp: asyncua's
    handler of data changes. A sample is complete when every tag has reported its stamp; a stamp
    that a newer complete one overtakes is dropped (a tag's queue overflowed); `take()` hands the
    complete samples over in order."""

    def __init__(self, tags: Tags):
        self._path, self._tags = tags.path, tags.nodes()
        self._pending: dict[object, dict[int, float]] = {}  # source timestamp -> {tag index: value}
        self._complete: deque[Sample] = deque()
        # Set when a sample completes or the grouping fails. A sample is never handed over through
        # the wait itself: asyncio.wait_for may drop what its awaitable returned as it times out.
        self._arrived = asyncio.Event()
        self.error: BwrError | None = None

    def datachange_notification(self, node, value, data) -> None:
        item = data.monitored_item
        stamp, index = item.Value.SourceTimestamp, item.ClientHandle - FIRST_HANDLE
        if stamp is None:
            self._fail(f"tag {self._tags[index][1]} = {self._tags[index][0]!r} comes without a source timestamp")
            return
        group = self._pending.setdefault(stamp, {})
        group[index] = value
        if len(group) == len(self._tags):
            for older in [s for s in self._pending if s <= stamp]:
                del self._pending[older]
            self._complete.append(Sample.of([group[i] for i in range(len(self._tags))]))
            self._arrived.set()
        elif len(self._pending) > APART:
            # The tags apart: those missing from most of the stamps the time carries (a few are
            # missing from the newest only because their notifications are still on the way).
            timed = [group for group in self._pending.values() if 0 in group]
            apart = [i for i in range(1, len(self._tags)) if sum(i in group for group in timed) < len(timed) / 2]
            if not timed or len(apart) == len(self._tags) - 1:
                apart = [0]  # the time itself
            named = ", ".join(f"{self._tags[i][1]} = {self._tags[i][0]!r}" for i in apart)
            self._fail(f"tag {named} never carries the source timestamp the others do" if len(apart) == 1 else
                       f"tags {named} never carry the source timestamp the others do")

    def _fail(self, why: str) -> None:
        if self.error is None:
            self.error = BwrError(f"{self._path}: {why}: the server stamps a cycle's values apart, and a "
                                  "subscription cannot group them into samples; read them with --poll")
        self._arrived.set()

    async def take(self, timeout: float) -> list[Sample]:
        """Every complete sample not yet taken, oldest first, waiting up to `timeout` s for the
        first; BwrError if the tags cannot be grouped."""
        if not self._complete and self.error is None:
            with contextlib.suppress(asyncio.TimeoutError):
                await asyncio.wait_for(self._arrived.wait(), timeout)
        self._arrived.clear()
        if self.error is not None:
            raise self.error
        found = list(self._complete)
        self._complete.clear()
        return found


FIRST_HANDLE = 1  # the client handle of the first tag's monitored item; the others follow in Tags.nodes()'s order


async def _subscribe(client: Client, nodes: list, tags: Tags) -> Arrivals:
    """A subscription to every tag's value, notified on each new source timestamp even where the
    value repeats (an axis at rest), with a queue for the cycles between two publishes."""
    arrivals = Arrivals(tags)
    subscription = await client.create_subscription(ua.CreateSubscriptionParameters(
        RequestedPublishingInterval=PUBLISHING_INTERVAL, RequestedLifetimeCount=LIFETIME,
        RequestedMaxKeepAliveCount=KEEP_ALIVE, PublishingEnabled=True), arrivals)
    trigger = ua.DataChangeFilter(Trigger=ua.DataChangeTrigger.StatusValueTimestamp)
    requests = []
    for handle, node in enumerate(nodes, start=FIRST_HANDLE):
        request = ua.MonitoredItemCreateRequest()
        request.ItemToMonitor = ua.ReadValueId(NodeId=node.nodeid, AttributeId=ua.AttributeIds.Value)
        request.MonitoringMode = ua.MonitoringMode.Reporting
        request.RequestedParameters = ua.MonitoringParameters(ClientHandle=handle, SamplingInterval=0.0,
                                                              Filter=trigger, QueueSize=QUEUED, DiscardOldest=True)
        requests.append(request)
    for node, result in zip(nodes, await subscription.create_monitored_items(requests), strict=True):
        if isinstance(result, ua.StatusCode):
            raise BwrError(f"{tags.path}: tag {node.nodeid.Identifier!r} cannot be subscribed to: {result.name}")
    return arrivals


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
    thresholds from (`blocks()`, `counts`); set them and it detects from the next block on.
    `air`: the air of the anemometer's wind, when the samples carry it (Tags.wind).

    It keeps only the samples a block still needs: those from the newest block's end on, and
    the two before, whose steps a gap is told by (a day at 100 Hz would otherwise hold 4.8 GB).
    Watching (thresholds set), it keeps the newest `kept_blocks` to 2 `kept_blocks` blocks: at
    twice, the older half goes, and the detectors start again on the rest, knowing the alarms
    raised (bwr_twin.shadow.detect.assess's `earlier`). Without thresholds it keeps every block."""

    def __init__(self, twin: ShadowTwin, thresholds: Thresholds | None, say: Callable[[dict], None],
                 air: Air | None = None, kept_blocks: int = KEPT_BLOCKS):
        if kept_blocks <= WINDOW + ISOLATE:
            raise ValueError(f"kept_blocks must exceed a GLR window and the isolation, {WINDOW + ISOLATE}")
        self._twin, self.thresholds, self._say, self._air = twin, thresholds, say, air
        self._kept_blocks = kept_blocks
        self._samples: list[Sample] = []
        self._done = 0  # the first sample of the block not yet handed to the twin
        self.counts = np.full(3, np.inf)  # m, rad: each encoder's smallest step seen (as encoder_counts)
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
        if self._samples:
            step = np.abs(sample.position - self._samples[-1].position)
            self.counts = np.where(step > 1e-12, np.minimum(self.counts, step), self.counts)
        self._samples.append(sample)
        made = self._advance()
        if made and detect:
            self.detect()
        return made

    def _measured(self, start: int) -> Measured:
        """The kept samples from `start` on. A force tag gives the force held over the period
        that ended at its sample's time, and so does the anemometer: a sample's force is the
        next sample's, and the newest sample's is not known yet (NaN). A block reads the forces
        of its periods only, so the block that ends at the newest sample is made at once."""
        samples = self._samples[start:]
        time = np.array([s.time for s in samples])
        position, speed = np.array([s.position for s in samples]), np.array([s.speed for s in samples])
        force = np.array([s.force for s in samples[1:]] + [np.full(3, np.nan)])
        period = float(np.median(np.diff(time))) if len(samples) > 1 else 1.0
        windy = self._air is not None and samples[0].wind is not None
        wind = np.array([s.wind for s in samples[1:]] + [np.nan]) if windy else None
        return Measured(time, position, speed, force, period, speed, wind, self._air if windy else None)

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
        tail = self._measured(self._done) if len(samples) - self._done > 3 else None
        if tail is None:
            return False
        blocks = self._twin.blocks(tail)
        if not len(blocks.start):
            return False
        self._blocks.append(blocks)
        if self.thresholds is not None and sum(len(b.start) for b in self._blocks) >= 2 * self._kept_blocks:
            kept = self.blocks()
            self._blocks = [Blocks(*(getattr(kept, f)[-self._kept_blocks:] for f in Blocks.__dataclass_fields__))]
            self._statistics = []  # the detectors' running sums start again on the blocks kept
        self._done += int(np.searchsorted(tail.time, blocks.end[-1]))
        kept = max(self._done - 2, 0)
        del samples[:kept]
        self._done -= kept
        return True

    def detect(self) -> None:
        """Run the detectors over the blocks so far (with thresholds set): say each new alarm,
        and update `health`."""
        if self.thresholds is None or not self._blocks:
            return
        if self._statistics_for is not self.thresholds:  # thresholds set or changed: start afresh
            self._statistics, self._statistics_for = [], self.thresholds
        alarms, self.health = assess(self.blocks(), self.thresholds, self._statistics, complete=False,
                                     earlier=self.alarms)
        known = {(a.kind, a.axis) for a in self.alarms}
        for alarm in alarms:
            if (alarm.kind, alarm.axis) not in known:
                self.alarms.append(alarm)
                self._say(alarm.event())

    def newest(self) -> Blocks:
        """The blocks the newest sample completed."""
        return self._blocks[-1]

    def position(self, t: float) -> np.ndarray:
        """(3,) the encoders' reading at the sample of time `t` (m, rad, rad), one of the kept
        samples (the newest block's end is)."""
        for sample in reversed(self._samples):
            if sample.time <= t:
                return sample.position.copy()
        return self._samples[0].position.copy()

    def blocks(self) -> Blocks:
        """Every block kept (every block so far, without thresholds)."""
        if not self._blocks:
            return Blocks.none()
        return Blocks(*(np.concatenate([getattr(b, f) for b in self._blocks]) for f in Blocks.__dataclass_fields__))


async def read_once(source: Source, shadow: LiveShadow, say: Callable[[dict], None],
                    outputs: Sequence[Output] = ()) -> bool:
    """Read the samples since the last call into the shadow; on a dropped source say so,
    reconnect (every RETRY s until it answers) and say when it is back. True if a sample was
    read. A block's residuals go to the `outputs` as soon as the twin has them, then its
    detectors run, then the health and the alarms go to them."""
    try:
        samples = await source.read()
    except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError, AttributeError):
        say({"event": "source_lost", "time_s": shadow.time, "source": source.url})
        await source.close()
        await _reconnect(source, shadow, say)
        return False
    arrived = time.perf_counter()
    for sample in samples:
        if shadow.add(sample, detect=not outputs) and outputs:
            newest = shadow.newest()
            for output in outputs:
                await output.residuals(newest, shadow.position(float(newest.end[-1])), arrived)
            shadow.detect()
            for output in outputs:
                await output.verdict(shadow.health, shadow.alarms)
    return bool(samples)


async def _reconnect(source: Source, shadow: LiveShadow, say: Callable[[dict], None]) -> None:
    """Try the source every RETRY s until it answers; say when it is back."""
    while True:
        try:
            await source.connect()
            break
        except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError):
            await asyncio.sleep(RETRY)
    say({"event": "source_back", "time_s": shadow.time, "source": source.url})


async def run_live(source: Source, shadow: LiveShadow, say: Callable[[dict], None], *, duration: float | None,
                   outputs: Sequence[Output] = ()) -> None:
    """Watch `source` for `duration` s (None: until cancelled), as its samples come or as it is
    polled, publishing to `outputs`; a source that cannot be reached at the start is said so
    and tried again every RETRY s, as one that drops later."""
    async def watch() -> None:
        try:
            await source.connect()
        except (ConnectionError, OSError, asyncio.TimeoutError, ua.UaError):
            say({"event": "source_lost", "time_s": 0.0, "source": source.url})
            await _reconnect(source, shadow, say)
        while True:
            await read_once(source, shadow, say, outputs)
            if source.poll is not None:
                await asyncio.sleep(source.poll)

    try:
        await asyncio.wait_for(watch(), duration)
    except asyncio.TimeoutError:
        pass
    finally:
        await source.close()
