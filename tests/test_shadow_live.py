"""The live shadow as a real OPC UA client of `python -m bwr_twin.serve` playing the heavy machine
(scenes/heavy_shadow.toml), driven by a PLC client (a per-axis PID at 10 Hz): thresholds learned
from a fault-free machine's session; on the machine with a slew friction rise, the alarm names
it, through a dropped connection that is reported and becomes a gap, with no false alarm; the
command line killed and started again watches on from the live machine with its thresholds; and
a tag map for another machine, or a tag that is missing, is one line."""

from __future__ import annotations

import asyncio
import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from asyncua import ua
from conftest import ROOT
from heavy_plc import HeavyPlc
from test_serve import CALL_TIMEOUT, STARTUP_TIMEOUT, AlarmEvents, Launched, client, environment, free_port
from test_shadow import ServedShadow

from bwr_twin.errors import BwrError
from bwr_twin.shadow.detect import learn
from bwr_twin.shadow.live import APART, LiveShadow, Sample, Source, read_once
from bwr_twin.shadow.publish import ShadowServer, residual_ranges
from bwr_twin.shadow.tags import read_tags
from bwr_twin.shadow.twin import Blocks, ShadowTwin

SCENE = ROOT / "scenes" / "heavy_shadow.toml"
MJCF = ROOT / "mjcf" / "bwr_heavy.xml"
TAGS = ROOT / "examples" / "shadow_tags.toml"
STEP = 10  # control periods a PLC cycle: 0.1 s
SECONDS = 40.0  # the path's first slew, 8 deg
LEARNED = 80.0  # s of the fault-free session the thresholds are learned on: the slew, then the travel moving
ONSET = 8.0  # s: the friction rise's start


async def session(url: str, shadow: LiveShadow, events: list, drop_at: float | None = None,
                  server: ShadowServer | None = None, seconds: float = SECONDS) -> None:
    """A PLC at 10 Hz for `seconds`; the shadow polls after every cycle (publishing on `server`); at
    `drop_at` s its connection is cut and the PLC runs a second on before the shadow polls again."""
    source = Source(url, read_tags(TAGS, "bwr_heavy"))
    await source.connect()
    async with client(url) as connection:
        plc = await HeavyPlc.attach(connection, STEP, 0.01)
        cycles = round(seconds / (STEP * 0.01))
        for cycle in range(cycles):
            await plc.cycle()
            now = (cycle + 1) * STEP * 0.01
            if drop_at is not None and drop_at <= now < drop_at + 1.0:
                if now - drop_at < STEP * 0.01 / 2:
                    await source._client.disconnect()  # the network drops the shadow's session
                continue
            await read_once(source, shadow, events.append, [server] if server is not None else [])
    await source.close()


def served(scene, coroutine_of):
    server = Launched(scene)
    try:
        return asyncio.run(asyncio.wait_for(coroutine_of(server.ready()), CALL_TIMEOUT * 3))
    finally:
        assert server.stop() == 0, server.stderr


@pytest.fixture(scope="module")
def twin() -> ShadowTwin:
    return ShadowTwin(MJCF)


async def missing_tag_then_session(url: str, wrong_tags, shadow: LiveShadow, events: list) -> None:
    """A tag map naming a node the server lacks is refused in one line; then a session."""
    with pytest.raises(BwrError, match=r"tag luff.speed = 'Reclaimer.Luff.Tachometer': .*cannot be read"):
        await Source(url, read_tags(wrong_tags, "bwr_heavy")).connect()
    await session(url, shadow, events, seconds=LEARNED)


@pytest.fixture(scope="module")
def thresholds(twin, tmp_path_factory):
    """Learned live, on a fault-free session of the served machine. Also: a tag that is missing
    is one line, as the shadow connects."""
    wrong = tmp_path_factory.mktemp("tags") / "tags.toml"
    wrong.write_text(TAGS.read_text().replace("Reclaimer.Luff.EncoderVelocity", "Reclaimer.Luff.Tachometer"))
    free: list = []
    baseline = LiveShadow(twin, None, free.append)
    served(SCENE, lambda url: missing_tag_then_session(url, wrong, baseline, free))
    assert free == []
    return learn([baseline.blocks()], baseline.counts, 0.01)


def faulty_scene(folder, fault: str):
    scene = folder / "faulty.toml"
    scene.write_text(f'extends = "{SCENE}"\n[[faults]]\n{fault}\nstart = {ONSET}\n')
    return scene


def test_the_live_shadow_names_a_friction_rise_through_a_dropped_source(twin, thresholds, tmp_path):
    faulty = faulty_scene(tmp_path, 'kind = "friction_rise"\naxis = "slew"\npercent = 60.0')
    events: list = []
    shadow = LiveShadow(twin, thresholds, events.append)
    published = ShadowServer(f"opc.tcp://127.0.0.1:{free_port()}",
                             residual_ranges(twin.limits, twin.machine.rated_speed, thresholds))
    newest, health, condition = served(faulty, lambda url: watched_and_served(url, shadow, events, published))
    kinds = [e["event"] for e in events]
    assert "source_lost" in kinds and "source_back" in kinds, events
    (gap,) = [e for e in events if e["event"] == "gap"]
    assert 24.0 < gap["from_s"] < gap["to_s"] < 27.0
    alarms = [e for e in events if e["event"] == "alarm"]
    assert [(a["kind"], a["axis"]) for a in alarms] == [("friction_rise", "slew")], events
    assert alarms[0]["time_s"] >= ONSET
    # Served as it went: each block's residuals, the slew's health down to 0 with its alarm.
    assert newest == shadow.blocks().end[-1] and len(published.latencies) == len(shadow.blocks().start)
    assert health == 0.0 and condition == ("friction_rise", "slew")


@pytest.mark.parametrize("fault, named", [
    ('kind = "mass_change"\nmass = 4900.0', ("mass_change", "wheel end")),
    ('kind = "drive_derate"\naxis = "travel"\npercent = 15.0', ("drive_derate", "travel")),
], ids=["mass_change", "drive_derate"])
def test_the_live_shadow_names_the_other_plant_faults(twin, thresholds, tmp_path, fault, named):
    """serve plays the machine with the fault from ONSET s, at tools/shadow_study.py's sizes, over
    the path's first LEARNED s (the travel moves from 40 s); the shadow, reading the drives' setpoints
    as their forces (examples/shadow_tags.toml), names its class and where it is."""
    events: list = []
    shadow = LiveShadow(twin, thresholds, events.append)
    served(faulty_scene(tmp_path, fault), lambda url: session(url, shadow, events, seconds=LEARNED))
    alarms = [e for e in events if e["event"] == "alarm"]
    assert alarms and (alarms[0]["kind"], alarms[0]["axis"]) == named, events
    assert alarms[0]["time_s"] >= ONSET


async def watched_and_served(url: str, shadow: LiveShadow, events: list, published: ShadowServer) -> tuple:
    """The session with the shadow publishing; then what a client reads of it: the newest block's
    end, the slew's health and the fault class and axis of the condition ConditionRefresh sends."""
    await published.start()
    try:
        await session(url, shadow, events, drop_at=25.0, server=published)
        async with client(published.url) as connection:
            ns = await connection.get_namespace_index("urn:bwr_twin:shadow")
            newest = await connection.get_node(ua.NodeId("Shadow.Time", ns)).read_value()
            health = await connection.get_node(ua.NodeId("Shadow.Slew.Health", ns)).read_value()
            alarms = AlarmEvents()
            subscription = await connection.create_subscription(20, alarms)
            fault_type = await connection.nodes.base_event_type.get_child(
                ["0:ConditionType", "0:AcknowledgeableConditionType", "0:AlarmConditionType", f"{ns}:FaultAlarmType"])
            await subscription.subscribe_events(connection.nodes.server, fault_type)
            refresh = connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh))
            await connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType)).call_method(
                refresh, ua.Variant(subscription.subscription_id, ua.VariantType.UInt32))
            await alarms.next()  # RefreshStart
            alarm = await alarms.next()
            return newest, health, (alarm["FaultClass"], alarm["Axis"])
    finally:
        await published.stop()


async def subscribed_and_polled(url: str, apart) -> tuple[list[Sample], list[Sample]]:
    """Five PLC cycles, a Read of every tag after each; the subscription's samples of the same
    cycles, taken only after the fifth. Then a map whose force tags are the PLC's own writes,
    which the server does not stamp with the cycle, subscribed to."""
    subscribed = Source(url, read_tags(TAGS, "bwr_heavy"))
    polled = Source(url, read_tags(apart, "bwr_heavy"), poll=0.01)
    await subscribed.connect()
    await polled.connect()
    read, queued = [], []
    async with client(url) as connection:
        plc = await HeavyPlc.attach(connection, STEP, 0.01)
        for _ in range(5):
            await plc.cycle()
            read += await polled.read()
        while not queued or queued[-1].time < read[-1].time:
            queued += await subscribed.read()
        stamped_apart = Source(url, read_tags(apart, "bwr_heavy"))
        await stamped_apart.connect()
        for _ in range(APART):  # the server stamps each write as it takes it: a cycle brings two stamps
            await plc.cycle()
        with pytest.raises(BwrError, match=r"tags\.toml: tags travel\.force = 'Reclaimer\.Travel\.DriveSetpoint', "
                           r"slew\.force = .*, luff\.force = .* never carry the source timestamp the others do: .* "
                           r"read them with --poll"):
            await stamped_apart.read()
        await stamped_apart.close()
    for source in (subscribed, polled):
        await source.close()
    return read, queued


def test_a_subscribed_shadow_groups_each_cycle_by_its_stamp_and_a_map_stamped_apart_is_polled(tmp_path):
    """Subscribed, the shadow gets every cycle's sample, in order, even those that came while it
    was not reading: each the same as a Read of every tag right after that cycle (the force the
    setpoint held over it). The PLC's own setpoint writes carry no source timestamp: a map naming
    them is one line when subscribed, and is read with --poll."""
    apart = tmp_path / "tags.toml"
    apart.write_text(TAGS.read_text().replace(".DriveCommanded", ".DriveSetpoint"))
    read, queued = served(SCENE, lambda url: subscribed_and_polled(url, apart))
    assert [s.time for s in read] == pytest.approx([0.1, 0.2, 0.3, 0.4, 0.5])
    by_time = {round(s.time, 6): s for s in queued}
    assert set(by_time) >= {round(s.time, 6) for s in read}
    assert [s.time for s in queued] == sorted(s.time for s in queued)
    for polled in read:
        sample = by_time[round(polled.time, 6)]
        for field in ("position", "speed", "force"):
            assert getattr(sample, field).tolist() == getattr(polled, field).tolist(), (polled.time, field)
    assert np.abs(read[-1].force).max() > 0  # the PLC's forces, not a drive at rest


WIND = "[plant]\nwind_speed = 15.0\ngust_amplitude = 4.0\nwind_direction = 90.0\n"  # m/s, m/s, deg: a windy shift


async def windy_session(url: str, tags, shadows: list[LiveShadow]) -> None:
    """The PLC at 10 Hz for SECONDS; after every cycle the samples since, with the anemometer's
    wind, go to each of `shadows`."""
    source = Source(url, tags)
    await source.connect()
    async with client(url) as connection:
        plc = await HeavyPlc.attach(connection, STEP, 0.01)
        for _ in range(round(SECONDS / (STEP * 0.01))):
            await plc.cycle()
            for sample in await source.read():
                for shadow in shadows:
                    shadow.add(sample)
    await source.close()


KILLED_AT = 4.0  # s of the machine: the shadow command line is killed, and started again a second later
RESTARTED_FOR = 24.0  # s of the machine in all: the friction rise is named at about 17 s


async def killed_and_restarted(url: str, thresholds: Path) -> tuple[ServedShadow, ServedShadow]:
    """A PLC at 10 Hz in real time for RESTARTED_FOR s, the shadow command line subscribed from the start;
    killed (SIGKILL) at KILLED_AT s and started again with the same thresholds a second later (the
    machine, in lockstep, waits for it to listen)."""
    options = ("--source", url, "--tags", str(TAGS), "--model", str(MJCF), "--thresholds", str(thresholds))
    first, second = ServedShadow(*options), None
    first.wait_for("serving the shadow at", STARTUP_TIMEOUT)
    try:
        async with client(url) as connection:
            plc = await HeavyPlc.attach(connection, STEP, 0.01)
            for cycle in range(1, round(RESTARTED_FOR / (STEP * 0.01)) + 1):
                await plc.cycle()
                await asyncio.sleep(STEP * 0.01)  # the machine's own pace
                if cycle == round(KILLED_AT / (STEP * 0.01)):
                    first.stop_signal = signal.SIGKILL
                    first.stop()
                elif cycle == round((KILLED_AT + 1.0) / (STEP * 0.01)):
                    second = ServedShadow(*options)
                    second.wait_for("serving the shadow at", STARTUP_TIMEOUT)
            second.wait_for('{"event": "alarm"', CALL_TIMEOUT)  # however far behind a busy machine leaves it
    finally:
        first.stop()
        if second is not None:
            second.stop()
    return first, second


def test_killed_and_restarted_the_shadow_resumes_from_the_live_machine_with_its_thresholds(thresholds, tmp_path):
    """The command line watching the served machine (a slew friction rise from 8 s) is killed
    before the fault and started again with the same thresholds file: it watches the machine from
    where it is, and names the friction rise, with nothing else raised or lost."""
    kept = tmp_path / "thresholds.json"
    thresholds.write(kept)
    faulty = faulty_scene(tmp_path, 'kind = "friction_rise"\naxis = "slew"\npercent = 60.0')
    first, second = served(faulty, lambda url: killed_and_restarted(url, kept))
    assert first.returncode == -signal.SIGKILL
    assert [line for line in first.lines if line.startswith("{")] == []  # nothing to say before the fault
    events = [json.loads(line) for line in second.lines if line.startswith("{")]
    alarms = [e for e in events if e["event"] == "alarm"]
    assert [(a["kind"], a["axis"]) for a in alarms] == [("friction_rise", "slew")], (events, second.stderr)
    assert alarms[0]["time_s"] > KILLED_AT + 1.0 and alarms[0]["time_s"] >= ONSET
    assert not [e for e in events if e["event"] in ("source_lost", "gap")], events


def test_the_live_shadow_reads_the_anemometer_and_takes_no_gust_for_a_fault(twin, thresholds, tmp_path):
    """serve plays the machine in a 15 m/s wind gusting by 4 m/s and serves its anemometer
    (WindSpeed); the shadow that reads it as its [wind] tag raises nothing, with thresholds
    learned in still air, where one without it takes the wind's torque for a drive fault."""
    windy = tmp_path / "windy.toml"
    windy.write_text(f'extends = "{SCENE}"\n{WIND}')
    tags = tmp_path / "tags.toml"
    tags.write_text(TAGS.read_text() + '\n[wind]\nspeed = "Reclaimer.WindSpeed"\ndirection = 90.0\n'
                    'air_density = 1.204\n')
    read = read_tags(tags, "bwr_heavy")
    assert read.wind is not None and read.wind.air.density == 1.204
    heard, unheard = [], []
    with_wind = LiveShadow(twin, thresholds, heard.append, read.wind.air)
    without = LiveShadow(twin, thresholds, unheard.append)
    served(windy, lambda url: windy_session(url, read, [with_wind, without]))
    assert len(with_wind.blocks().start) >= SECONDS - 2
    assert heard == [], heard
    assert [e["event"] for e in unheard][:1] == ["alarm"], unheard


@pytest.mark.parametrize("table, complaint", [
    ('[wind]\ndirection = 90.0\nair_density = 1.2', r"'wind.speed' must be a node id string"),
    ('[wind]\nspeed = "W"\ndirection = 90.0\nair_density = 20.0', r"'wind.air_density' must be a number in \(0, 2\]"),
    ('[wind]\nspeed = "W"\ndirection = "north"\nair_density = 1.2', r"'wind.direction' must be a number"),
    ('[wind]\nspeed = "W"\nvane = "V"\ndirection = 9.0\nair_density = 1.2', r"'wind.vane' is not a key of \[wind\]"),
])
def test_a_bad_wind_table_is_one_line_naming_its_key(tmp_path, table, complaint):
    tags = tmp_path / "tags.toml"
    tags.write_text(TAGS.read_text() + "\n" + table + "\n")
    with pytest.raises(BwrError, match=complaint):
        read_tags(tags, "bwr_heavy")


def test_a_map_for_another_machine_is_one_line():
    with pytest.raises(BwrError, match="the tag map is for machine 'bwr_heavy', the model is 'bwr'"):
        read_tags(TAGS, "bwr")


def test_the_command_line_says_an_unreachable_source_is_lost_and_keeps_trying(tmp_path):
    thresholds = tmp_path / "thresholds.json"
    learn([_still_blocks()], np.array([0.00153, 0.00153, 0.00076]), 0.01).write(thresholds)
    command = [sys.executable, "-m", "bwr_twin.shadow", "--source", f"opc.tcp://127.0.0.1:{free_port()}",
               "--tags", str(TAGS), "--model", str(MJCF), "--thresholds", str(thresholds)]
    done = subprocess.run([*command, "--duration", "3"], check=False, capture_output=True, text=True, cwd=ROOT,
                          env=environment(), timeout=600)
    assert done.returncode == 0, done.stderr
    events = [json.loads(line) for line in done.stdout.splitlines()]
    assert [e["event"] for e in events] == ["source_lost"]
    paper = [*command[:-4], "--model", str(ROOT / "mjcf" / "bwr.xml"), "--thresholds", str(thresholds)]
    other = subprocess.run(paper, check=False, capture_output=True, text=True, cwd=ROOT, env=environment(), timeout=600)
    assert other.returncode == 2 and len(other.stderr.strip().splitlines()) == 1
    assert "a map for another machine is refused" in other.stderr
    never = subprocess.run([*command, "--poll", "0"], check=False, capture_output=True, text=True, cwd=ROOT,
                           env=environment(), timeout=600)
    assert never.returncode == 2 and never.stderr.strip() == "error: --poll must be > 0 s, got 0", never.stderr


def _still_blocks():
    """Blocks of a machine at rest under noise: enough to learn thresholds from."""
    rng = np.random.default_rng(1)
    n = 40

    def noise(scale):
        return rng.normal(0.0, scale, (n, 3))

    zeros = np.zeros((n, 3))
    return Blocks(np.arange(n, dtype=float), np.arange(1, n + 1, dtype=float), noise(1e3), zeros, zeros,
                  noise(1e-4), zeros, zeros, noise(1e3), noise(1e3), noise(1e3), zeros, np.zeros((n, 3, 2)),
                  np.full(n, 10))
