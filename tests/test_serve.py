"""The OPC UA server (`python -m bwr_twin.serve`) as a PLC sees it: a real asyncua client against
the server in its own process, on a free loopback port, on the short path of conftest.

A PID written here drives the twin over the wire exactly as it drives the same run in-process;
two sessions of the same scene read the same encoders; the watchdog stops silent PLCs; users
and units are what docs/opcua.md promises; bad arguments get one line. The address space is
typed as the companion specifications type machines: analog items with their ranges, the
Machinery identification and states, alarms a SCADA client subscribes to, a NodeSet2 file that
loads into another server, and users who log in with a certificate.
"""

from __future__ import annotations

import asyncio
import os
import selectors
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from asyncua import Client, Node, ua
from conftest import PAPER_MJCF, ROOT, unrated_paper_mjcf, write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.serve.address_space import (AXIS_VARIABLES, MACHINE_VARIABLES, METHODS, NAMESPACE_URI, node_path,
                                          unit_of)
from bwr_twin.serve.security import hash_password
from bwr_twin.shipped import find_scene
from bwr_twin.sim.lockstep import Lockstep

AXES = ("travel", "slew", "luff")
STARTUP_TIMEOUT = 40.0  # s: imports, the scene, asyncua's standard address space, on a busy machine
REQUEST_TIMEOUT = 60.0  # s a request may take: a Step of thousands of periods on a busy machine
# asyncua (2.x) reads the server's state every watchdog interval and drops the connection when
# that read takes longer than the interval (1 s by default): as patient as any other request
WATCHDOG = REQUEST_TIMEOUT
CALL_TIMEOUT = 120.0  # s: any one client session below, a bound on a hang (a busy machine steps slowly)
PID_PERIODS = 300  # the first 3 s of the short path: travel and slew accelerate, their largest errors
USER, PASSWORD = "plc", "s3cret"
EVENT_TIMEOUT = 10.0  # s: an alarm event reaches a subscriber within a publishing interval, on a busy machine


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def serve_command(scene, *options: str) -> list[str]:
    return [sys.executable, "-m", "bwr_twin.serve", str(scene), *options]


def environment() -> dict:
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}


class Launched:
    """A server process on a free loopback port, started at once; `ready()` waits for it."""

    def __init__(self, scene, *options: str, stop_signal=signal.SIGTERM):
        self.url = f"opc.tcp://127.0.0.1:{free_port()}"
        self.stop_signal, self.lines, self._pending = stop_signal, [], b""
        self.process = subprocess.Popen(serve_command(scene, "--endpoint", self.url, *options), cwd=ROOT,
                                        env=environment(), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
        self.returncode, self.stderr = None, ""

    def ready(self) -> str:
        """The URL, once the server says it listens."""
        self.wait_for("Ctrl-C stops", STARTUP_TIMEOUT)
        return self.url

    def wait_for(self, prefix: str, timeout: float) -> str:
        """The first printed line starting with `prefix`, waiting up to `timeout` s for it."""
        deadline = time.monotonic() + timeout
        with selectors.DefaultSelector() as selector:
            selector.register(self.process.stdout, selectors.EVENT_READ)
            while not (found := [line for line in self.lines if line.startswith(prefix)]):
                # Raw reads: a buffered readline would hide lines the selector has already seen.
                if not selector.select(timeout=max(deadline - time.monotonic(), 0)):
                    pytest.fail(f"no line {prefix!r} within {timeout:g} s: {self.lines}")
                chunk = os.read(self.process.stdout.fileno(), 65536)
                if not chunk:
                    pytest.fail(f"the server exited: {self.process.wait()} {self.process.stderr.read().decode()}")
                *complete, self._pending = (self._pending + chunk).split(b"\n")
                self.lines.extend(line.decode() for line in complete)
        return found[0]

    def stop(self) -> int:
        """Stop the server with its signal; its exit status."""
        if self.returncode is None:
            self.process.send_signal(self.stop_signal)
            try:
                out, err = self.process.communicate(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                out, err = self.process.communicate()
            self.lines.extend((self._pending + out).decode().splitlines())
            self.returncode, self.stderr = self.process.returncode, err.decode()
        return self.returncode


def run(coroutine):
    return asyncio.run(asyncio.wait_for(coroutine, CALL_TIMEOUT))


def run_served(scene, session, *options: str):
    """What `session(url)` returns from a server of `scene` launched for it, which then stops cleanly."""
    server = Launched(scene, *options)
    try:
        found = run(session(server.ready()))
    finally:
        status = server.stop()
    assert status == 0 and "Traceback" not in server.stderr, server.stderr
    return found


def client(url: str, password: str | None = None) -> Client:
    """An asyncua client of the server at url: anonymous, or the users file's PLC with `password`."""
    connection = Client(url, timeout=REQUEST_TIMEOUT, watchdog_intervall=WATCHDOG)
    if password is not None:
        connection.set_user(USER)
        connection.set_password(password)
    return connection


class Plc:
    """A client's handles on the twin: per-axis nodes by variable name, machine nodes, methods."""

    def __init__(self, client: Client, ns: int, reclaimer, axis: dict, machine: dict, methods: dict):
        self.client, self.ns, self.reclaimer, self.axis, self.machine = client, ns, reclaimer, axis, machine
        self.methods = methods

    @classmethod
    async def attach(cls, client: Client) -> Plc:
        ns = await client.get_namespace_index(NAMESPACE_URI)
        reclaimer = await client.nodes.objects.get_child(f"{ns}:Reclaimer")
        axis = {v.name: [await reclaimer.get_child([f"{ns}:{a.capitalize()}", f"{ns}:{v.name}"]) for a in AXES]
                for v in AXIS_VARIABLES}
        machine = {v.name: await reclaimer.get_child(f"{ns}:{v.name}") for v in MACHINE_VARIABLES}
        methods = {name: await reclaimer.get_child(f"{ns}:{name}") for name in METHODS}
        return cls(client, ns, reclaimer, axis, machine, methods)

    async def read(self, *names: str) -> list[np.ndarray]:
        values = await self.client.read_values([n for name in names for n in self.axis[name]])
        return [np.array(values[3 * i:3 * i + 3]) for i in range(len(names))]

    async def value(self, name: str):
        return await self.machine[name].read_value()

    async def set_drives(self, forces) -> None:
        await self.client.write_values(self.axis["DriveSetpoint"],
                                       [ua.Variant(float(f), ua.VariantType.Double) for f in forces])

    async def call(self, method: str, *arguments):
        return await self.reclaimer.call_method(self.methods[method], *arguments)

    async def step(self, periods: int = 1):
        return await self.call("Step", ua.Variant(periods, ua.VariantType.UInt32))


class AlarmEvents:
    """A subscription to the events of one alarm type on Objects/Reclaimer, as a SCADA client
    makes it; `next()` waits for the next event, as its fields by name."""

    def __init__(self):
        self.queue: asyncio.Queue = asyncio.Queue()

    def event_notification(self, event) -> None:  # asyncua's subscription handler
        self.queue.put_nowait({k: v for k, v in vars(event).items() if k not in event.internal_properties})

    @classmethod
    async def subscribe(cls, plc: Plc, event_type: int, notifier: Node | None = None) -> AlarmEvents:
        """Events of `event_type` from `notifier` (default: the Reclaimer)."""
        events = cls()
        subscription = await plc.client.create_subscription(20, events)
        await subscription.subscribe_events(notifier or plc.reclaimer, event_type)
        return events

    async def next(self) -> dict:
        return await asyncio.wait_for(self.queue.get(), EVENT_TIMEOUT)


MACHINERY = "Reclaimer.MachineryBuildingBlocks"


async def item_state(plc: Plc) -> str:
    """The reclaimer's MachineryItemState, by its CurrentState's node id."""
    node = plc.client.get_node(ua.NodeId(f"{MACHINERY}.MachineryItemState.CurrentState", plc.ns))
    return (await node.read_value()).Text


class Pid:
    """The PLC's per-axis PID with a holding force, in SI units (m, rad, N, N m)."""

    def __init__(self, settings, period: float):
        self.kp, self.ki, self.kd, self.hold = (np.array(getattr(settings, k)) for k in
                                                ("kp", "ki", "kd", "holding_force"))
        self.period, self.integral = period, np.zeros(3)

    def __call__(self, q, qd, q_ref, qd_ref) -> np.ndarray:
        error = q_ref - q
        force = self.hold + self.kp * error + self.ki * self.integral + self.kd * (qd_ref - qd)
        self.integral += error * self.period
        return force


@pytest.fixture(scope="module")
def short_scene(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("serve"))


@pytest.fixture(scope="module")
def users_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("users") / "users.txt"
    path.write_text(f"# the PLC\n{USER}:{hash_password(PASSWORD)}\n")  # the floor: 0.3-0.4 s a login
    return path


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("out") / "run"


@pytest.fixture(scope="module")
def servers(short_scene, users_file, run_dir):
    """The two servers the tests share, started together: their start-up (about 3 s each, mostly
    asyncua's standard address space) overlaps on the machine's two cores."""
    launched = {
        "lockstep": Launched(short_scene, "--out", str(run_dir), "--no-plots"),
        # Real-time mode and users; Ctrl-C stops it (the last test). With its clock stopped, Step works.
        "guarded": Launched(short_scene, "--realtime", "--watchdog-periods", "20", "--users", str(users_file),
                            stop_signal=signal.SIGINT),
    }
    try:
        yield launched
    finally:
        for name, server in launched.items():
            status = server.stop()
            assert "Traceback" not in server.stderr, server.stderr
            assert status == (130 if server.stop_signal == signal.SIGINT else 0), (name, server.stderr)


def pid_settings():
    return load_scene(find_scene("pid_paper")).controller.settings  # 2 rad/s, the luff's holding torque


async def pid_session(url: str, periods: int, password: str | None = None,
                      make_pid=lambda period: Pid(pid_settings(), period)) -> tuple[np.ndarray, np.ndarray]:
    """Reset, then the PID `make_pid(control period)` over the wire for `periods`: (periods, 3)
    encoder positions and references as the PLC read them."""
    async with client(url, password) as connection:
        plc = await Plc.attach(connection)
        await plc.call("Reset")
        pid = make_pid(await plc.value("ControlPeriod"))
        positions, references = [], []
        for _ in range(periods):
            q, qd, q_ref, qd_ref = await plc.read("EncoderPosition", "EncoderVelocity", "ReferencePosition",
                                                  "ReferenceVelocity")
            await plc.set_drives(pid(q, qd, q_ref, qd_ref))
            await plc.step(1)
            positions.append(q)
            references.append(q_ref)
        return np.array(positions), np.array(references)


def test_a_pid_over_the_wire_tracks_the_path_as_it_does_in_process(servers, short_scene):
    wire_q, wire_ref = run(pid_session(servers["lockstep"].ready(), PID_PERIODS))

    # The same PID on the same run without a wire: the server must add nothing, not one bit.
    loop = Lockstep([load_scene(short_scene)], nthread=1)
    pid = Pid(pid_settings(), loop.period)
    local_q = []
    while loop.k < PID_PERIODS:
        q, qd = loop.measure()
        local_q.append(q[0].copy())
        loop.advance(pid(q[0], qd[0], loop.path[0][loop.k], loop.path[1][loop.k])[None])
    np.testing.assert_array_equal(wire_q, np.array(local_q))
    np.testing.assert_array_equal(wire_ref, loop.path[0][:PID_PERIODS])

    # Tracking: a PID at 2 rad/s holds this gentle start of the paper path within two encoder
    # counts per axis (the encoders' resolution: 1.53 mm, 1.53 mrad, 0.76 mrad); measured: 2.8 mm,
    # 0.85 mrad, 0 (the luff barely moves here). A PLC that broke the loop (a sign, a unit, a
    # period of delay too many) drifts by metres and radians.
    worst = np.abs(wire_ref - wire_q).max(axis=0)
    resolution = np.array(load_scene(short_scene).encoders.resolution)
    assert (worst <= 2 * resolution).all(), f"largest errors {worst} beyond two counts {2 * resolution}"
    assert (worst[:2] > 0).all()  # travel and slew did move along the path


async def exported_block_session(url: str, block, periods: int) -> np.ndarray:
    """Reset, then the exported fuzzy + model-based block over the wire: the encoder positions read."""
    async with client(url) as connection:
        plc = await Plc.attach(connection)
        await plc.call("Reset")
        positions = []
        for _ in range(periods):
            q, qd, q_ref, qd_ref, qdd_ref = await plc.read("EncoderPosition", "EncoderVelocity", "ReferencePosition",
                                                           "ReferenceVelocity", "ReferenceAcceleration")
            block(*(list(x) for x in (q, qd, q_ref, qd_ref, qdd_ref)))
            await plc.set_drives(block.force)
            await plc.step(1)
            positions.append(q)
        return np.array(positions)


def test_the_exported_plc_block_drives_the_twin_as_the_twins_controller(servers, short_scene, tmp_path):
    """The scene's controller exported as Structured Text (python -m bwr_twin.export plc), parsed by
    blark and run as the PLC over OPC UA, reads the same encoders, bit for bit, as the twin's own
    controller in-process on the same scene."""
    from st_python import load_exported

    from bwr_twin.sim.lockstep import simulate

    export = subprocess.run([sys.executable, "-m", "bwr_twin.export", "plc", str(short_scene), "--out",
                             str(tmp_path / "plc")], capture_output=True, text=True)
    assert export.returncode == 0, export.stderr
    block = load_exported(tmp_path / "plc")
    wire = run(exported_block_session(servers["lockstep"].ready(), block, PID_PERIODS))
    scene = load_scene(short_scene)
    local = simulate(load_scene(short_scene, {"simulation.record_period": scene.simulation.control_period}))
    np.testing.assert_array_equal(wire, local.q_measured[:PID_PERIODS])
    assert (np.ptp(wire, axis=0)[:2] > 0).all()  # travel and slew moved


def test_two_identical_sessions_read_identical_encoders(servers):
    url = servers["lockstep"].ready()
    first = run(pid_session(url, periods=100))
    again = run(pid_session(url, periods=100))  # after Reset on the same server
    # Another server process, in real-time mode with its clock stopped: Step drives the same machine.
    fresh = run(pid_session(servers["guarded"].ready(), periods=100, password=PASSWORD))
    for session in (again, fresh):
        np.testing.assert_array_equal(session[0], first[0])
    assert np.ptp(first[0][:, 0]) > 0  # the machine moved: equal readings are not equal zeros


def test_stepping_past_the_path_end_is_refused_until_reset(servers, run_dir):
    server = servers["lockstep"]
    url = server.ready()

    async def session():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            left = await plc.value("PeriodsLeft")
            with pytest.raises(ua.uaerrors.BadInvalidState):
                await plc.step(left + 1)  # refused whole: nothing stepped
            assert await plc.value("PeriodsLeft") == left
            assert not run_dir.exists()  # --out: written only for a completed path
            sim_time = await plc.step(left)  # Step's output: SimTime after it
            assert await plc.value("PeriodsLeft") == 0
            with pytest.raises(ua.uaerrors.BadInvalidState):
                await plc.step(1)
            with pytest.raises(ua.uaerrors.BadInvalidArgument):
                await plc.step(0)
            await plc.call("Reset")
            assert await plc.value("SimTime") == 0.0
            await plc.step(1)
            return sim_time

    assert run(session()) == pytest.approx(20.0)
    server.wait_for(f"results in {run_dir}/", 30.0)
    written = sorted(p.name for p in run_dir.iterdir())
    assert written == [".bwr_twin", "metrics.json", "scene.json", "timeseries.csv"]


def test_bad_writes_and_calls_get_their_status_codes(servers):
    async def session():
        async with client(servers["lockstep"].ready()) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            await plc.set_drives((1.0, 2.0, 3.0))
            travel = plc.axis["DriveSetpoint"][0]
            with pytest.raises(ua.uaerrors.BadOutOfRange):
                await travel.write_value(ua.Variant(float("nan"), ua.VariantType.Double))
            with pytest.raises(ua.uaerrors.BadTypeMismatch):
                await travel.write_value(ua.Variant(5, ua.VariantType.Int64))
            with pytest.raises(ua.uaerrors.BadUserAccessDenied):  # not writable: the contract's "read"
                await plc.axis["EncoderPosition"][0].write_value(ua.Variant(0.0, ua.VariantType.Double))
            for method in ("Start", "Stop"):
                with pytest.raises(ua.uaerrors.BadNotSupported):  # lockstep mode: no clock
                    await plc.call(method)
            return (await plc.read("DriveSetpoint"))[0]

    assert run(session()).tolist() == [1.0, 2.0, 3.0]  # the refused writes changed nothing


def test_engineering_units_are_declared_on_every_variable(servers):
    url = servers["lockstep"].ready()

    def unece(code: str) -> int:  # OPC UA Part 8: the code's characters as the bytes of an Int32
        return int.from_bytes(code.encode(), "big")

    expected = {
        ("EncoderPosition", "travel"): ("m", unece("MTR")),
        ("EncoderPosition", "slew"): ("rad", unece("C81")),
        ("EncoderVelocity", "luff"): ("rad/s", unece("2A")),
        ("ReferenceAcceleration", "travel"): ("m/s²", unece("MSK")),
        ("DriveSetpoint", "travel"): ("N", unece("NEW")),
        ("DriveApplied", "luff"): ("N·m", unece("NU")),
        ("SimTime", None): ("s", unece("SEC")),
    }

    async def session():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            found = {}
            for variable in AXIS_VARIABLES + MACHINE_VARIABLES:
                for index, axis in enumerate(AXES if variable in AXIS_VARIABLES else (None,)):
                    node = plc.axis[variable.name][index] if axis else plc.machine[variable.name]
                    properties = {(await p.read_browse_name()).Name: p for p in await node.get_properties()}
                    if unit_of(variable, axis) is None:
                        assert "EngineeringUnits" not in properties
                        continue
                    eu = await properties["EngineeringUnits"].read_value()
                    assert eu.NamespaceUri == "http://www.opcfoundation.org/UA/units/un/cefact"
                    found[variable.name, axis] = (eu.DisplayName.Text, eu.UnitId)
            return found

    found = run(session())
    with_units = [v for v in AXIS_VARIABLES + MACHINE_VARIABLES if v.unit is not None]
    assert len(found) == sum(3 if v in AXIS_VARIABLES else 1 for v in with_units) >= 7 * 3 + 2
    for key, unit in expected.items():
        assert found[key] == unit, key


def test_clients_of_the_documented_node_ids_still_read_and_call(servers):
    """docs/opcua.md's node ids (`ns=<index>;s=` and the browse path with dots) and the units'
    property ids: typing the variables changed none of them."""
    url = servers["lockstep"].ready()
    documented = [node_path(v.name) for v in MACHINE_VARIABLES] + [
        node_path(v.name, axis) for v in AXIS_VARIABLES for axis in AXES]

    async def session():
        async with client(url) as connection:
            ns = await connection.get_namespace_index(NAMESPACE_URI)
            nodes = [connection.get_node(f"ns={ns};s={path.replace('/', '.')}") for path in documented]
            values = await connection.read_values(nodes)
            reclaimer = connection.get_node(f"ns={ns};s=Reclaimer")
            await reclaimer.call_method(connection.get_node(f"ns={ns};s=Reclaimer.Reset"))
            stepped_to = await reclaimer.call_method(connection.get_node(f"ns={ns};s=Reclaimer.Step"),
                                                     ua.Variant(2, ua.VariantType.UInt32))
            unit = await connection.get_node(
                f"ns={ns};s=Reclaimer.Travel.EncoderPosition.EngineeringUnits").read_value()
            names = [(await n.read_browse_name()).Name for n in nodes]
            return values, stepped_to, unit, names

    values, stepped_to, unit, names = run(session())
    assert len(values) == len(MACHINE_VARIABLES) + 3 * len(AXIS_VARIABLES) and None not in values
    assert names == [path.rsplit("/", 1)[1] for path in documented]
    assert stepped_to == pytest.approx(0.02) and unit.DisplayName.Text == "m"


async def analog_variables(connection: Client, ns: int) -> dict[str, dict]:
    """Every variable under Objects/Reclaimer whose data type is Double, by browse path: its type
    definition and its properties' values by name."""
    found = {}

    async def walk(node, path):
        for child in await node.get_children(refs=ua.ObjectIds.HierarchicalReferences):
            name = (await child.read_browse_name()).Name
            if await child.read_node_class() == ua.NodeClass.Variable:
                if await child.read_data_type() == ua.NodeId(ua.ObjectIds.Double):
                    properties = {(await p.read_browse_name()).Name: await p.read_value()
                                  for p in await child.get_properties()}
                    found[f"{path}/{name}"] = {"type": await child.read_type_definition(), **properties}
            else:
                await walk(child, f"{path}/{name}")

    await walk(connection.get_node(ua.NodeId("Reclaimer", ns)), "Reclaimer")
    return found


def test_every_analog_variable_is_an_analog_item_with_its_range(servers, short_scene):
    """A browse of every variable finds each Double an AnalogUnitType with its EngineeringUnits and
    an EURange, finite and not empty; the ranges are the MJCF's (the paper machine's end stops,
    rated speeds and drive ratings) and the run's (path, period)."""
    url = servers["lockstep"].ready()

    async def session():
        async with client(url) as connection:
            return await analog_variables(connection, await connection.get_namespace_index(NAMESPACE_URI))

    analog = run(session())
    assert len(analog) == 3 * 8 + 3  # eight Doubles per axis, SimTime, ControlPeriod, ReclaimRate
    for path, found in analog.items():
        assert found["type"] == ua.NodeId(ua.ObjectIds.AnalogUnitType), path
        assert "EngineeringUnits" in found, path
        low, high = found["EURange"].Low, found["EURange"].High
        assert np.isfinite([low, high]).all() and low < high, (path, low, high)

    machine = Machine(load_scene(short_scene).machine.mjcf)
    mass, gravity = machine.dynamics.at(np.zeros(3), np.zeros(3))
    expected = {
        "Reclaimer/Luff/EncoderPosition": (-0.28, 0.28),  # the end stops
        "Reclaimer/Slew/ReferencePosition": (-1.63, 1.63),
        "Reclaimer/Travel/EncoderVelocity": (-0.5, 0.5),  # rated_speed_travel
        "Reclaimer/Luff/ReferenceVelocity": (-0.002, 0.002),
        "Reclaimer/Luff/DriveSetpoint": (-5.6e5, 1.1e6),  # forcerange
        "Reclaimer/Travel/DriveApplied": (-3.2e3, 3.2e3),
        "Reclaimer/Slew/DriveCommanded": (-3.0e4, 3.0e4),
        "Reclaimer/Luff/ReferenceAcceleration": ((-5.6e5 - gravity[2]) / mass[2, 2], (1.1e6 - gravity[2]) / mass[2, 2]),
        "Reclaimer/SimTime": (0.0, 20.0),  # the short path
        "Reclaimer/ControlPeriod": (0.0, 0.01),
        "Reclaimer/ReclaimRate": (0.0, 1.0),  # no stockpile: the documented span
    }
    for path, (low, high) in expected.items():
        assert (analog[path]["EURange"].Low, analog[path]["EURange"].High) == pytest.approx((low, high)), path


def test_a_machine_without_ratings_gets_the_documented_finite_ranges(tmp_path):
    """The paper's machine stripped of its drive ratings and rated speeds: the ranges follow the
    documented rules (docs/opcua.md), never infinite: drive forces that give ±1 m/s² (rad/s²)
    from rest at home against gravity, accelerations ±1, speeds the end stops' span in 60 s."""
    import re

    from bwr_twin.sim.ranges import eu_ranges

    unrated = unrated_paper_mjcf(tmp_path)
    unrated.write_text(re.sub(r'<numeric name="rated_speed_\w+"[^>]*/>', "", unrated.read_text()))
    scene = write_short_scene(tmp_path, edit=lambda text: text.replace(f'"{PAPER_MJCF}"', f'"{unrated}"'))
    loop = Lockstep([load_scene(scene)], nthread=1)
    assert np.isinf(loop.machine.drive_limits).all() and np.isinf(loop.machine.rated_speed).all()
    ranges = eu_ranges(loop)
    assert all(np.isfinite(r).all() and r[0] < r[1] for r in ranges.values())
    mass, gravity = loop.machine.dynamics.at(np.zeros(3), np.zeros(3))
    assert ranges["DriveSetpoint", "luff"] == pytest.approx((gravity[2] - mass[2, 2], gravity[2] + mass[2, 2]))
    assert ranges["DriveApplied", "travel"] == pytest.approx((-mass[0, 0], mass[0, 0]))  # no gravity on the rail
    assert ranges["ReferenceAcceleration", "luff"] == pytest.approx((-1.0, 1.0))
    assert ranges["EncoderVelocity", "slew"] == pytest.approx((-2 * 1.63 / 60, 2 * 1.63 / 60))
    assert ranges["EncoderPosition", "travel"] == (-26.0, 26.0)  # the end stops stay the MJCF's


def test_the_reclaimer_is_a_machinery_machine_with_identification_and_states(servers, short_scene):
    """A client finds the reclaimer in Objects/Machines, its Identification typed
    MachineIdentificationType (under MachineryItemIdentificationType), the nameplate from the
    MJCF, and the MachineryItemState following the lockstep run: NotExecuting, Executing from
    the first Step, NotExecuting at the path's end."""
    url = servers["lockstep"].ready()

    async def session():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            ns = plc.ns
            machines = await connection.nodes.objects.get_child(f"{ns}:Machines")
            listed = [(await n.read_browse_name()).Name for n in await machines.get_children()]
            identification = await plc.reclaimer.get_child(f"{ns}:Identification")
            type_node = connection.get_node(await identification.read_type_definition())
            chain = [(await type_node.read_browse_name()).Name]
            for _ in range(2):
                (type_node,) = await type_node.get_referenced_nodes(ua.ObjectIds.HasSubtype, ua.BrowseDirection.Inverse)
                chain.append((await type_node.read_browse_name()).Name)
            nameplate = {(await p.read_browse_name()).Name: await p.read_value()
                         for p in await identification.get_properties()}
            blocks = await plc.reclaimer.get_child(f"{ns}:MachineryBuildingBlocks")
            add_ins = {(await n.read_browse_name()).Name for n in await blocks.get_children(refs=ua.ObjectIds.HasAddIn)}
            mode_node = connection.get_node(ua.NodeId(f"{MACHINERY}.MachineryOperationMode.CurrentState", ns))
            mode = await mode_node.read_value()
            await plc.call("Reset")
            states = [await item_state(plc)]
            await plc.step(1)
            current = f"{MACHINERY}.MachineryItemState.CurrentState"
            state_id = await connection.get_node(ua.NodeId(f"{current}.Id", ns)).read_value()
            number = await connection.get_node(ua.NodeId(f"{current}.Number", ns)).read_value()
            executing = connection.get_node(state_id)
            state_number = await (await executing.get_child("0:StateNumber")).read_value()
            states.append(await item_state(plc))
            await plc.step(await plc.value("PeriodsLeft"))
            states.append(await item_state(plc))
            await plc.call("Reset")
            return (listed, chain, nameplate, add_ins, mode.Text, states, (await executing.read_browse_name()).Name,
                    number, state_number)

    listed, chain, nameplate, add_ins, mode, states, executing, number, state_number = run(session())
    assert "Reclaimer" in listed
    assert chain == ["MachineIdentificationType", "MachineryItemIdentificationType", "FolderType"]
    texts = Machine(load_scene(short_scene).machine.mjcf).identification
    assert nameplate["Manufacturer"].Text == texts["manufacturer"] == "bwr_twin"
    assert nameplate["Model"].Text == texts["model"] and nameplate["SerialNumber"] == texts["serial_number"]
    assert nameplate["ProductInstanceUri"] == f"urn:bwr_twin:bwr:{texts['serial_number']}"
    assert add_ins == {"Identification", "MachineryItemState", "MachineryOperationMode"}
    assert mode == "Processing"
    assert states == ["NotExecuting", "Executing", "NotExecuting"]
    assert (executing, number, state_number) == ("Executing", 3, 3)  # OPC 40001-1's StateNumber


LUFF_PUSH = (0.0, 0.0, -1e7)  # N, N m, N m: the luff driven down at its rating, into its envelope's bottom
LIMIT_PERIODS = 200  # 2 s: the luff falls through its 15 degrees in under one


def test_a_limit_raises_an_alarm_a_scada_client_receives(servers):
    """Subscribed to OffNormalAlarmType events on Objects/Reclaimer, a client receives the luff's
    limit switch closing when a large setpoint drives the luff down in lockstep, and opening
    again when Reset brings it back; a client of the Server object receives the same event."""
    url = servers["lockstep"].ready()

    async def session():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            alarms = await AlarmEvents.subscribe(plc, ua.ObjectIds.OffNormalAlarmType)
            on_server = await AlarmEvents.subscribe(plc, ua.ObjectIds.OffNormalAlarmType, connection.nodes.server)
            await plc.set_drives(LUFF_PUSH)
            await plc.step(LIMIT_PERIODS)
            at_limit = (await plc.read("AtLimit"))[0]
            raised = await alarms.next()
            assert (await on_server.next())["EventId"] == raised["EventId"]
            await plc.call("Reset")
            cleared = await alarms.next()
            luff, switch = ua.NodeId("Reclaimer.Luff", plc.ns), ua.NodeId("Reclaimer.Luff.AtLimit", plc.ns)
            return at_limit, raised, cleared, luff, switch

    at_limit, raised, cleared, luff, luff_switch = run(session())
    assert at_limit.tolist() == [False, False, True]
    assert raised["EventType"] == ua.NodeId(ua.ObjectIds.OffNormalAlarmType)
    assert (raised["SourceNode"], raised["SourceName"], raised["InputNode"]) == (luff, "Luff", luff_switch)
    assert (raised["ActiveState/Id"], raised["Retain"], raised["Severity"]) == (True, True, 700)
    sim_time = float(raised["Message"].Text.split("at SimTime ")[1].split(" s")[0])
    assert raised["Message"].Text.startswith("Luff: limit switch closed") and 0 < sim_time < LIMIT_PERIODS * 0.01
    assert (cleared["ActiveState/Id"], cleared["Retain"], cleared["NodeId"]) == (False, False, raised["NodeId"])


async def browse_tree(objects: Node, ns: int) -> dict:
    """Browse path -> (node class, node id, type definition, EURange) of every node of namespace
    `ns` below `objects` by hierarchical references, and of the namespace's types these are
    instances of (under "types"), with their supertypes of the namespace and their children.
    Names and ids are (in `ns`, text): two servers that number the namespace differently compare."""
    tree, types = {}, []

    def name(qualified: ua.QualifiedName) -> tuple[bool, str]:
        return qualified.NamespaceIndex == ns, qualified.Name

    def identity(node_id: ua.NodeId) -> tuple[bool, object]:
        return node_id.NamespaceIndex == ns, node_id.Identifier

    async def walk(node: Node, path: tuple) -> None:
        for ref in await node.get_references(ua.ObjectIds.HierarchicalReferences, ua.BrowseDirection.Forward,
                                             includesubtypes=True):
            child, child_path = Node(node.session, ref.NodeId), (*path, name(ref.BrowseName))
            if ref.NodeId.NamespaceIndex != ns or child_path in tree:
                continue
            eu_range = await child.read_value() if ref.BrowseName.Name == "EURange" else None
            tree[child_path] = (ref.NodeClass, identity(ref.NodeId), identity(ref.TypeDefinition),
                                eu_range and (eu_range.Low, eu_range.High))
            if ref.TypeDefinition.NamespaceIndex == ns and ref.TypeDefinition not in types:
                types.append(ref.TypeDefinition)
            await walk(child, child_path)

    await walk(objects, ())
    for type_id in types:  # the list grows by the supertypes of the namespace as they are found
        type_node = Node(objects.session, type_id)
        (supertype,) = await type_node.get_referenced_nodes(ua.ObjectIds.HasSubtype, ua.BrowseDirection.Inverse)
        path = ((None, "types"), name(await type_node.read_browse_name()))
        tree[path] = (await type_node.read_node_class(), identity(type_id), identity(supertype.nodeid), None)
        if supertype.nodeid.NamespaceIndex == ns and supertype.nodeid not in types:
            types.append(supertype.nodeid)
        await walk(type_node, path)
    return tree


def test_the_nodeset_file_loads_into_a_fresh_server_with_the_same_tree(servers, short_scene, tmp_path):
    """--nodeset writes the address space and exits; asyncua's importer loads the file into a
    fresh server, which then has the served browse tree: the same paths, node classes, node ids,
    types and EURanges. The file is not replaced without --overwrite, nor a file the twin did not
    write at all."""
    from asyncua import Server

    nodeset = tmp_path / "reclaimer.xml"
    written = subprocess.run(serve_command(short_scene, "--nodeset", str(nodeset)), cwd=ROOT, env=environment(),
                             capture_output=True, text=True, timeout=120)
    assert written.returncode == 0, written.stderr
    assert written.stdout.startswith("nodeset: ") and written.stdout.endswith(f" written to {nodeset}\n")
    url = servers["lockstep"].ready()

    async def trees():
        async with client(url) as connection:
            served = await browse_tree(connection.nodes.objects, await connection.get_namespace_index(NAMESPACE_URI))
        fresh = Server()
        await fresh.init()
        await fresh.import_xml(str(nodeset))
        loaded = await browse_tree(fresh.nodes.objects, await fresh.get_namespace_index(NAMESPACE_URI))
        return served, loaded

    served, loaded = run(trees())
    assert loaded == served
    paths = {tuple(name for _, name in path) for path in served}
    assert ("Reclaimer", "Luff", "DriveSetpoint", "EURange") in paths
    assert ("Machines", "Reclaimer", "Identification", "SerialNumber") in paths
    assert ("types", "MachineryItemState_StateMachineType", "Executing", "StateNumber") in paths
    ranges = [value[2] for path, value in served.items() if path[-1] == (False, "EURange")]
    assert len(ranges) == 2 * (3 * 8 + 3) and all(ranges)  # every analog item, under Objects and under Machines

    again = subprocess.run(serve_command(short_scene, "--nodeset", str(nodeset)), cwd=ROOT, env=environment(),
                           capture_output=True, text=True, timeout=120)
    assert again.returncode == 2 and again.stderr == (f"error: {nodeset}: already exists; choose another "
                                                      "--nodeset or pass --overwrite\n")
    foreign = tmp_path / "foreign.xml"
    foreign.write_text("<?xml version='1.0' encoding='utf-8'?>\n<UANodeSet/>\n")
    refused = subprocess.run(serve_command(short_scene, "--nodeset", str(foreign), "--overwrite"), cwd=ROOT,
                             env=environment(), capture_output=True, text=True, timeout=120)
    assert refused.returncode == 2 and refused.stderr == (f"error: {foreign}: exists and was not written "
                                                          "by the twin; it is left alone, choose another --nodeset\n")
    assert foreign.read_text() == "<?xml version='1.0' encoding='utf-8'?>\n<UANodeSet/>\n"

def test_the_watchdog_stops_the_drives_of_a_silent_plc(servers):
    hold = (0.0, 0.0, 490500.0)  # N, N m, N m: the luff's holding torque
    server = servers["guarded"]

    async def session():
        async with client(server.ready(), PASSWORD) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            alarms = await AlarmEvents.subscribe(plc, ua.ObjectIds.TripAlarmType)
            assert await plc.value("Mode") == "realtime"
            await plc.set_drives(hold)
            await plc.call("Start")
            executing = await item_state(plc)
            for _ in range(30):  # 0.3 s of a PLC writing every period
                await plc.set_drives(hold)
                await asyncio.sleep(0.01)
            alive = await plc.value("WatchdogTripped"), (await plc.read("DriveApplied"))[0]
            trip = await alarms.next()  # silent from now on: 20 periods later the drives are cut
            tripped, state = await plc.value("WatchdogTripped"), await item_state(plc)
            setpoints, applied = await plc.read("DriveSetpoint", "DriveApplied")
            with pytest.raises(ua.uaerrors.BadInvalidState):  # latched: a fresh write does not clear it
                await plc.set_drives(hold)
            running = await plc.value("Running")
            await plc.call("Reset")
            cleared = await alarms.next()
            return (alive, tripped, setpoints, applied, running, await plc.value("WatchdogTripped"),
                    (executing, state, await item_state(plc)), trip, cleared)

    ((was_tripped, applied_alive), tripped, setpoints, applied, running, after_reset, states, trip,
     cleared) = run(session())
    assert not was_tripped and applied_alive[2] == pytest.approx(hold[2])
    assert tripped and running
    assert (setpoints == 0).all() and (applied == 0).all()
    assert not after_reset
    assert server.wait_for("watchdog: no DriveSetpoint write for 20 control periods", 5.0)
    # Machinery: the clock ran, the trip took the machine out of service, Reset brought it back.
    assert states == ("Executing", "OutOfService", "NotExecuting")
    # The trip is an alarm on the Reclaimer, raised and then cleared by Reset.
    assert (trip["ActiveState/Id"], trip["Retain"], trip["Severity"]) == (True, True, 900)
    assert trip["SourceName"] == "Reclaimer" and trip["ConditionName"] == "WatchdogAlarm"
    assert trip["Message"].Text.startswith("watchdog tripped at SimTime ")
    assert (cleared["ActiveState/Id"], cleared["Retain"]) == (False, False)
    assert cleared["NodeId"] == trip["NodeId"]  # the same condition


def test_writes_need_a_user_when_users_are_configured(servers, users_file):
    server = servers["guarded"]
    url = server.ready()

    async def authenticated(password):
        async with client(url, password) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            await plc.set_drives((1.0, 2.0, 3.0))
            await plc.step(1)
            return (await plc.read("DriveSetpoint"))[0], await plc.value("SimTime")

    async def anonymous():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            sim_time = await plc.value("SimTime")  # reading is open
            with pytest.raises(ua.uaerrors.BadUserAccessDenied):
                await plc.set_drives((4.0, 5.0, 6.0))
            with pytest.raises(ua.uaerrors.BadUserAccessDenied):
                await plc.step(1)
            return sim_time, (await plc.read("DriveSetpoint"))[0]

    written, stepped_to = run(authenticated(PASSWORD))
    sim_time, kept = run(anonymous())
    with pytest.raises(ua.uaerrors.BadUserAccessDenied):
        run(authenticated("wrong"))
    assert written.tolist() == [1.0, 2.0, 3.0] and stepped_to == pytest.approx(0.01)
    assert sim_time == stepped_to and kept.tolist() == [1.0, 2.0, 3.0]  # the anonymous session changed nothing
    assert f"anonymous access: read only; writes and method calls need one of the 1 user(s) of {users_file}" \
        in server.lines


def test_the_documented_client_example_runs(servers):
    result = subprocess.run([sys.executable, str(ROOT / "examples" / "opcua_client.py"), "--url",
                             servers["lockstep"].ready(), "--periods", "50"],
                            capture_output=True, text=True, timeout=60, env=environment())
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("largest encoder error over 50 periods: travel ")


@pytest.mark.parametrize("case", ["bad URL", "missing scene", "port in use", "open to the network"])
def test_bad_arguments_get_one_line_and_a_nonzero_exit(case, short_scene):
    free = free_port()
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        busy = taken.getsockname()[1]
        scene, endpoint, expected = {
            "bad URL": (short_scene, f"http://127.0.0.1:{free}",
                        f"error: --endpoint http://127.0.0.1:{free}: expected opc.tcp://HOST:PORT"),
            "missing scene": ("no_such_scene", f"opc.tcp://127.0.0.1:{free}",
                              "error: no_such_scene: scene file not found"),
            "port in use": (short_scene, f"opc.tcp://127.0.0.1:{busy}",
                            f"error: --endpoint opc.tcp://127.0.0.1:{busy}: cannot listen "
                            f"(port {busy} is in use)"),
            "open to the network": (short_scene, f"opc.tcp://0.0.0.0:{free}",
                                    f"error: opc.tcp://0.0.0.0:{free}: an endpoint other than loopback needs "
                                    "--users FILE"),
        }[case]
        result = subprocess.run(serve_command(scene, "--endpoint", endpoint), cwd=ROOT, env=environment(),
                                capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(expected), result.stderr


def test_ctrl_c_stops_the_server_with_status_130(servers):
    """Ends the shared real-time server: the file's last test."""
    guarded = servers["guarded"]
    guarded.ready()
    assert guarded.stop() == 130
    assert guarded.stderr == "interrupted: server stopped\n"
    assert guarded.lines[-1] == "server stopped"


def test_the_reclaim_rate_is_published_as_the_wheel_digs():
    from test_stockpile import SHORT_DIG

    from bwr_twin.config.plugins import controller_class
    from bwr_twin.sim.twin import Twin

    twin = Twin(load_scene(find_scene("heavy_dig_pile"), SHORT_DIG))
    loop = twin.loop
    pid = controller_class("pid")(loop.controller_context(), [twin.scene.controller.settings])
    rates = []
    while not twin.done:
        reading = twin.reading
        command = pid.compute(reading["EncoderPosition"][None], reading["EncoderVelocity"][None],
                              reading["ReferencePosition"], reading["ReferenceVelocity"],
                              reading["ReferenceAcceleration"], None)
        twin.advance(command[0])
        rates.append(twin.reading["ReclaimRate"])
    assert max(rates) > 1000.0  # t/h while cutting
    assert rates[0] == 0.0 and rates[-1] == 0.0  # beside the pile at the start, lifted clear at the end


BENCH_PERIODS = 200  # 2 s into the small bench scene's approach (11.3 s): travel and slew under way
BENCH_CHUNK = 100  # periods of one Step(n) after them


def test_a_bench_reclaim_is_served_with_the_plans_reference(tmp_path):
    """A [reclaim] scene has no path sampled in advance: the server publishes the plan's
    reference of the current period. Over the wire it is the approach's cubic at the period's
    time, stepped one period or many at a time, and PeriodsLeft counts down the periods."""
    from test_reclaim_plan import scene_file

    from bwr_twin.planning.bench import plan_scene

    path = scene_file(tmp_path)
    scene = load_scene(path)
    plan = plan_scene(scene)
    approach, period = plan.segments[0], scene.simulation.control_period
    assert approach.kind == "approach" and approach.duration > (BENCH_PERIODS + BENCH_CHUNK) * period

    async def session(url):
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            pid = Pid(scene.controller.settings, await plc.value("ControlPeriod"))
            left = [await plc.value("PeriodsLeft")]
            positions, references = [], []
            for _ in range(BENCH_PERIODS):
                q, qd, q_ref, qd_ref = await plc.read("EncoderPosition", "EncoderVelocity",
                                                      "ReferencePosition", "ReferenceVelocity")
                await plc.set_drives(pid(q, qd, q_ref, qd_ref))
                await plc.step(1)
                positions.append(q)
                references.append(q_ref)
            left.append(await plc.value("PeriodsLeft"))
            sim_time = await plc.step(BENCH_CHUNK)  # under the last forces written
            left.append(await plc.value("PeriodsLeft"))
            references.append((await plc.read("ReferencePosition"))[0])
            return np.array(positions), np.array(references), left, sim_time

    positions, references, left, sim_time = run_served(path, session, "--no-plots")

    times = np.append(np.arange(BENCH_PERIODS), BENCH_PERIODS + BENCH_CHUNK) * period
    np.testing.assert_allclose(references, [approach.sample(t)[0] for t in times], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(references[0], plan.start)
    moved = np.abs(references[BENCH_PERIODS - 1] - plan.start)
    assert moved[0] > 0.15 and moved[1] > np.radians(0.1), moved  # m, rad: the approach is under way
    assert sim_time == pytest.approx((BENCH_PERIODS + BENCH_CHUNK) * period)
    assert left[0] >= round(plan.nominal_duration / period)  # the whole plan ahead
    assert left[1:] == [left[0] - BENCH_PERIODS, left[0] - BENCH_PERIODS - BENCH_CHUNK]
    # The PID over the wire carried travel and slew along with the reference.
    followed = (positions[-1] - positions[0])[:2] / (references[BENCH_PERIODS - 1] - references[0])[:2]
    assert ((followed > 0.5) & (followed < 1.5)).all(), followed


# -- refused at start: users, certificates, endpoints -------------------------------------------

def certificate_pair(folder, name: str, uri: str | None = "urn:bwr_twin:serve", common_name: str = "bwr_twin"):
    """folder/NAME_cert.pem and folder/NAME_key.pem: a self-signed RSA certificate of
    `common_name` naming `uri` in its subjectAltName (none if None), and its key."""
    import datetime

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import rsa
    from cryptography.x509.oid import NameOID

    key = rsa.generate_private_key(public_exponent=65537, key_size=2048)
    subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, common_name)])
    builder = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject).public_key(key.public_key())
               .serial_number(1).not_valid_before(datetime.datetime(2020, 1, 1))
               .not_valid_after(datetime.datetime(2040, 1, 1)))
    if uri is not None:
        builder = builder.add_extension(x509.SubjectAlternativeName([x509.UniformResourceIdentifier(uri),
                                                                     x509.DNSName("localhost")]), critical=False)
    cert, key_file = folder / f"{name}_cert.pem", folder / f"{name}_key.pem"
    cert.write_bytes(builder.sign(key, hashes.SHA256()).public_bytes(serialization.Encoding.PEM))
    key_file.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return cert, key_file


@pytest.fixture(scope="module")
def credentials(tmp_path_factory):
    """Users files with iterations out of bounds, and certificates: good, another's key, no URI."""
    folder = tmp_path_factory.mktemp("credentials")
    line = hash_password(PASSWORD, iterations=1)
    files = {"good users": folder / "users.txt"}
    files["good users"].write_text(f"{USER}:{hash_password(PASSWORD)}\n")
    for name, count in (("no iterations", "0"), ("years a login", "10000000000000")):
        files[name] = folder / f"{name.replace(' ', '_')}.txt"
        files[name].write_text(f"# fine\n{USER}:{line.replace('$1$', f'${count}$')}\n")
    files["cert"], files["key"] = certificate_pair(folder, "server")
    _, files["other key"] = certificate_pair(folder, "other")
    files["no URI cert"], files["no URI key"] = certificate_pair(folder, "bare", uri=None)
    (folder / "empty").mkdir()
    files["user certificates"] = users = folder / "trusted_users"
    users.mkdir()
    files["operator cert"], files["operator key"] = certificate_pair(users, "operator", uri=None,
                                                                     common_name="operator")
    files["stranger cert"], files["stranger key"] = certificate_pair(folder, "stranger", uri=None,
                                                                     common_name="stranger")
    (users / "operator_key.pem").rename(folder / "operator_key.pem")  # the server holds certificates only
    files["operator key"] = folder / "operator_key.pem"
    return files


def test_a_matching_certificate_and_key_pass_the_start_checks(credentials):
    from bwr_twin.serve.certificates import check_certificate

    check_certificate(credentials["cert"], credentials["key"], "urn:bwr_twin:serve")  # no error


@pytest.mark.parametrize("case", ["no iterations", "years a login", "another's key", "no application URI",
                                  "IPv6 unclosed", "IPv6 unbracketed", "IPv6 not an address",
                                  "user certificates without a server certificate", "no user certificates",
                                  "a user certificate that is not one", "a user's key among the certificates",
                                  "nodeset with --out"])
def test_bad_credentials_and_endpoints_are_refused_in_one_line(case, short_scene, credentials):
    users = ["--users", str(credentials["good users"])]
    server = ["--certificate", str(credentials["cert"]), "--private-key", str(credentials["key"])]
    endpoint = f"opc.tcp://127.0.0.1:{free_port()}"
    options, expected = {
        "no iterations": (["--users", str(credentials["no iterations"])],
                          f"error: {credentials['no iterations']}:2: user 'plc': 0 PBKDF2 iterations; the server "
                          "takes 600,000 (OWASP's recommendation for PBKDF2-SHA256) to 1,000,000 (a check under 1 s)"),
        "years a login": (["--users", str(credentials["years a login"])],
                          f"error: {credentials['years a login']}:2: user 'plc': 10000000000000 PBKDF2 iterations; "
                          "the server takes 600,000"),
        "another's key": (users + ["--certificate", str(credentials["cert"]), "--private-key",
                                   str(credentials["other key"])],
                          f"error: --private-key {credentials['other key']} does not match --certificate "
                          f"{credentials['cert']}"),
        "no application URI": (users + ["--certificate", str(credentials["no URI cert"]), "--private-key",
                                        str(credentials["no URI key"])],
                               f"error: --certificate {credentials['no URI cert']}: its subjectAltName must name "
                               "the URI urn:bwr_twin:serve"),
        "IPv6 unclosed": (["--endpoint", "opc.tcp://[::1:4840"],
                          "error: --endpoint opc.tcp://[::1:4840: expected opc.tcp://HOST:PORT"),
        "IPv6 unbracketed": (["--endpoint", "opc.tcp://::1:4840"],
                             "error: --endpoint opc.tcp://::1:4840: expected opc.tcp://HOST:PORT, e.g. "
                             "opc.tcp://127.0.0.1:4840; an IPv6 address goes in brackets"),
        "IPv6 not an address": (["--endpoint", "opc.tcp://[::g]:4840"],
                                "error: --endpoint opc.tcp://[::g]:4840: [::g] is not an IPv6 address"),
        "user certificates without a server certificate": (
            ["--user-certificates", str(credentials["user certificates"])],
            f"error: --user-certificates {credentials['user certificates']}: needs --certificate and --private-key"),
        "no user certificates": (
            server + ["--user-certificates", str(credentials["cert"].parent / "empty")],
            f"error: --user-certificates {credentials['cert'].parent / 'empty'}: holds no certificate (.pem, "),
        "a user certificate that is not one": (
            server + ["--user-certificates", str(credentials["good users"])],
            f"error: --user-certificates {credentials['good users']}: not an X.509 certificate (PEM or DER)"),
        "a user's key among the certificates": (
            server + ["--user-certificates", str(credentials["operator key"])],
            f"error: --user-certificates {credentials['operator key']}: holds a private key; the server needs the "
            "users' certificates only"),
        "nodeset with --out": (["--nodeset", str(credentials["cert"].parent / "a.xml"), "--out",
                                str(credentials["cert"].parent / "run")],
                               f"error: --nodeset {credentials['cert'].parent / 'a.xml'} writes the address space "
                               "and serves nothing: --out does not apply"),
    }[case]
    result = subprocess.run(serve_command(short_scene, "--endpoint", endpoint, *options), cwd=ROOT,
                            env=environment(), capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.count("\n") == 1 and result.stderr.startswith(expected), result.stderr
    assert result.stdout == ""  # refused before it listened


def test_password_checks_leave_the_server_responsive_and_sigterm_stops_it(short_scene, tmp_path):
    """Logins at the top of the iteration bound (about 0.6 s each here), several at once: an
    anonymous client is still answered at once, and SIGTERM stops the server while they are
    being checked."""
    from bwr_twin.serve.security import MAX_ITERATIONS

    users = tmp_path / "users.txt"
    users.write_text(f"{USER}:{hash_password(PASSWORD, iterations=MAX_ITERATIONS)}\n")
    server = Launched(short_scene, "--users", str(users))
    url = server.ready()

    async def login():
        async with client(url, PASSWORD):
            await asyncio.sleep(30)  # held open: SIGTERM ends it

    async def session():
        async with client(url) as watcher:
            plc = await Plc.attach(watcher)
            logins = [asyncio.create_task(login()) for _ in range(4)]  # over 2 s of checks, one at a time
            await asyncio.sleep(0.5)
            started = time.perf_counter()
            await plc.value("SimTime")
            answered = time.perf_counter() - started
            server.process.send_signal(signal.SIGTERM)
            signalled = time.perf_counter()
            while server.process.poll() is None and time.perf_counter() - signalled < 10:
                await asyncio.sleep(0.05)
            stopped_in = time.perf_counter() - signalled
            for task in logins:  # a login that got in holds its session: the server is gone now
                task.cancel()
            await asyncio.gather(*logins, return_exceptions=True)
        return answered, stopped_in

    try:
        answered, stopped_in = asyncio.run(asyncio.wait_for(session(), CALL_TIMEOUT))
    finally:
        status = server.stop()
    # Four checks one at a time hold a blocked loop for over 2 s; a loop that hands them to a
    # thread answers the read between them, well within one check's time.
    assert answered < 1.0, f"a read took {answered:.2f} s during the password checks"
    assert status == 0 and stopped_in < 10, (status, stopped_in, server.stderr)  # stopped, not killed at 10 s
    assert "Traceback" not in server.stderr, server.stderr


def test_a_secure_endpoint_with_a_matching_pair_serves_its_users(short_scene, credentials):
    """The checks pass a good certificate and key; passwords then arrive encrypted, and are
    checked off the event loop as on loopback without security."""
    client_cert, client_key = certificate_pair(credentials["cert"].parent, "client", uri="urn:freeopcua:client")
    server = Launched(short_scene, "--users", str(credentials["good users"]), "--certificate",
                      str(credentials["cert"]), "--private-key", str(credentials["key"]))
    url = server.ready()

    async def session(password):
        connection = client(url, password)
        await connection.set_security_string(f"Basic256Sha256,SignAndEncrypt,{client_cert},{client_key}")
        async with connection:
            plc = await Plc.attach(connection)
            return await plc.step(1)

    try:
        stepped_to = run(session(PASSWORD))
        with pytest.raises(ua.uaerrors.BadUserAccessDenied):
            run(session("wrong"))
    finally:
        status = server.stop()
    assert stepped_to == pytest.approx(0.01)
    assert "security policies: Basic256Sha256 SignAndEncrypt" in server.lines
    assert status == 0 and "Traceback" not in server.stderr, server.stderr


def test_a_user_certificate_logs_in_and_one_not_trusted_is_refused(short_scene, credentials):
    """--user-certificates: a client that identifies with a certificate of the trusted folder
    (an X509IdentityToken, signed with its key) writes and steps; one with a certificate that is
    not there is refused at activation; an anonymous session still only reads."""
    client_cert, client_key = certificate_pair(credentials["cert"].parent, "client", uri="urn:freeopcua:client")
    server = Launched(short_scene, "--user-certificates", str(credentials["user certificates"]), "--certificate",
                      str(credentials["cert"]), "--private-key", str(credentials["key"]))
    url = server.ready()

    async def secure_client(user: str | None) -> Client:
        connection = Client(url, timeout=REQUEST_TIMEOUT, watchdog_intervall=WATCHDOG)
        await connection.set_security_string(f"Basic256Sha256,SignAndEncrypt,{client_cert},{client_key}")
        if user is not None:
            await connection.load_client_certificate(str(credentials[f"{user} cert"]))
            await connection.load_private_key(credentials[f"{user} key"])
        return connection

    async def activate(user: str) -> None:
        async with await secure_client(user):
            pass

    async def session(user: str | None):
        async with await secure_client(user) as connection:
            plc = await Plc.attach(connection)
            if user is None:
                with pytest.raises(ua.uaerrors.BadUserAccessDenied):
                    await plc.step(1)
                return await plc.value("SimTime")
            await plc.call("Reset")
            await plc.set_drives((1.0, 2.0, 3.0))
            return await plc.step(1), (await plc.read("DriveSetpoint"))[0]

    try:
        stepped_to, written = run(session("operator"))
        with pytest.raises(ua.uaerrors.BadUserAccessDenied):  # at activation: no session at all
            run(activate("stranger"))
        run(activate("operator"))
        read_anonymously = run(session(None))
    finally:
        status = server.stop()
    assert stepped_to == pytest.approx(0.01) and written.tolist() == [1.0, 2.0, 3.0]
    assert read_anonymously == pytest.approx(0.01)
    assert (f"anonymous access: read only; writes and method calls need one of the 1 user certificate(s) of "
            f"{credentials['user certificates']}") in server.lines
    assert status == 0 and "Traceback" not in server.stderr, server.stderr


def test_a_users_file_saved_with_a_byte_order_mark_and_crlf_reads_as_without(tmp_path):
    """An editor on Windows may save the users file so: the first user's name is still the name."""
    from bwr_twin.serve.security import load_users

    line = f"{USER}:{hash_password(PASSWORD)}"
    path = tmp_path / "users.txt"
    path.write_bytes(b"\xef\xbb\xbf" + f"{line}\r\nsecond:{line.partition(':')[2]}\r\n".encode())
    assert list(load_users(path)) == [USER, "second"]
