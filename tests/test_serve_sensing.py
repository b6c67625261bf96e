"""The run's senses over OPC UA (docs/opcua.md): the belt scale, the wheel current, the boom
scanner's latest profile and the faults' states, read by a real asyncua client from the server
in its own process, against the same run stepped in-process under the same drive forces.

The scene is heavy_dig_pile's short cut (test_stockpile.SHORT_DIG) with a frozen belt scale:
under zero drive forces the luff sinks and the wheel digs into the windrow's flank from about
5 s, and the belt scale, 8.9 s downstream, weighs the material from about 14 s. The scale is
frozen from 14.5 s for 1 s, while it rises.
"""

from __future__ import annotations

import subprocess
import xml.etree.ElementTree as Et

import numpy as np
import pytest
from asyncua import Server, ua
from conftest import ROOT
from test_serve import Plc, analog_variables, client, environment, run, run_served, serve_command
from test_stockpile import SHORT_DIG

from bwr_twin.config.scene import load_scene
from bwr_twin.serve.address_space import NAMESPACE_URI
from bwr_twin.shipped import SCENES, find_scene
from bwr_twin.sim.lockstep import Lockstep

FREEZE_START, FREEZE_DURATION = 14.5, 1.0  # s: control periods 1450 to 1549 at 0.01 s
# SimTime's period after each Step of the session: either side of the fault's window, and
# through the cut and the scale's first weighing.
CHECKPOINTS = (1, 2, 400, 1000, 1449, 1450, 1451, 1549, 1550, 1551, 1700)
SCANNER = "Reclaimer.Scanners.scanner_boom"
FAULT = "Reclaimer.Faults.Fault0_belt_scale_frozen"
READ = ("Reclaimer.SimTime", "Reclaimer.BeltScale", "Reclaimer.WheelCurrent", f"{SCANNER}.Ranges",
        f"{SCANNER}.ScanTime", f"{SCANNER}.Scans", FAULT)


def unece(code: str) -> int:
    return int.from_bytes(code.encode(), "big")


@pytest.fixture(scope="module")
def dig_scene(tmp_path_factory):
    """heavy_dig_pile over SHORT_DIG's 96 s path, with the belt scale frozen for a second."""
    rows = "".join(f"  {{ t = {v['t']}, p = [{', '.join(str(x) for x in v['p'])}] }},\n"
                   for v in SHORT_DIG["path.via_points"])
    path = tmp_path_factory.mktemp("serve_sensing") / "dig_frozen.toml"
    path.write_text(f'extends = "{SCENES / "heavy_dig_pile.toml"}"\n\n[path]\nframe = "world"\n'
                    f"via_points = [\n{rows}]\n\n[[faults]]\nkind = \"belt_scale_frozen\"\n"
                    f"start = {FREEZE_START}\nduration = {FREEZE_DURATION}\n")
    return path


@pytest.fixture(scope="module")
def in_process(dig_scene):
    """The same run stepped here under zero forces: at each checkpoint its instruments' readings,
    its scanner's latest scan (ScanLog.share: t, origin, hits), its count, and the fault's state
    in the period about to be stepped."""
    loop = Lockstep([load_scene(dig_scene)], nthread=1)
    assert loop.instruments is not None and loop.scanning is not None and len(loop.faults.faults) == 1
    log = loop.scanning.logs[0]
    found = {}
    for k in range(CHECKPOINTS[-1]):
        loop.measure()
        loop.advance(np.zeros((1, 3)))
        if loop.k in CHECKPOINTS:
            t, origin, hits = log.share(0)
            found[loop.k] = {"belt": float(loop.instruments.belt_scale[0]),
                             "current": float(loop.instruments.wheel_current[0]),
                             "time": float(t[-1]), "origin": origin[-1], "hits": hits[-1], "count": log.count,
                             "fault": loop.faults.acting(loop.k)[0]}
    return {"readings": found, "angles": loop.scanning.scanners[0].angles, "loop": loop}


@pytest.fixture(scope="module")
def served(dig_scene):
    """A PLC session over the wire: zero setpoints, Step to each checkpoint and read; then the
    analog items' types and properties, and what Reset leaves."""

    async def session(url):
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            ns = plc.ns
            nodes = [connection.get_node(f"ns={ns};s={node_id}") for node_id in READ]
            await plc.set_drives([0.0, 0.0, 0.0])
            start = await connection.read_values(nodes)
            readings, at = {}, 0
            for k in CHECKPOINTS:
                await plc.step(k - at)
                at = k
                readings[k] = dict(zip(READ, await connection.read_values(nodes)))
            analog = await analog_variables(connection, ns)
            ranges_node = connection.get_node(f"ns={ns};s={SCANNER}.Ranges")
            shape = (await ranges_node.read_value_rank(), await ranges_node.read_array_dimensions())
            angles = await connection.get_node(f"ns={ns};s={SCANNER}.Angles").read_value()
            fault = connection.get_node(f"ns={ns};s={FAULT}")
            fault_description = (await fault.read_description()).Text
            fault_type = await fault.read_data_type()
            await plc.call("Reset")
            after_reset = dict(zip(READ, await connection.read_values(nodes)))
            return {"start": dict(zip(READ, start)), "readings": readings, "analog": analog, "shape": shape,
                    "angles": angles, "fault_description": fault_description, "fault_type": fault_type,
                    "after_reset": after_reset}

    return run_served(dig_scene, session, "--no-plots")


def test_the_belt_scale_and_wheel_current_equal_the_twins_at_the_same_period(served, in_process):
    expected = in_process["readings"]
    for k in CHECKPOINTS:
        got = served["readings"][k]
        assert got["Reclaimer.SimTime"] == pytest.approx(k * 0.01, abs=1e-12)
        assert got["Reclaimer.BeltScale"] == expected[k]["belt"], k
        assert got["Reclaimer.WheelCurrent"] == expected[k]["current"], k
    # Not idle numbers: the wheel cuts at its drive's rating, and the scale weighs it once it arrives.
    last = served["readings"][CHECKPOINTS[-1]]
    assert last["Reclaimer.WheelCurrent"] > 950.0  # A: 1,024 A at the rated 1 MW
    assert last["Reclaimer.BeltScale"] > 5000.0  # t/h
    assert served["readings"][1]["Reclaimer.WheelCurrent"] == pytest.approx(310.0, abs=30.0)  # idle: 300 kW
    # Before the first period there is no reading: both read 0.
    assert served["start"]["Reclaimer.BeltScale"] == 0.0 and served["start"]["Reclaimer.WheelCurrent"] == 0.0


def test_the_scanners_latest_profile_equals_the_lockstep_latest_scan(served, in_process):
    expected = in_process["readings"]
    profiles = []
    for k in CHECKPOINTS:
        got, scan = served["readings"][k], expected[k]
        ranges = np.array(got[f"{SCANNER}.Ranges"])
        distance = np.linalg.norm(scan["hits"].astype(float) - scan["origin"], axis=1)  # NaN where no return
        assert ranges.shape == (191,)
        np.testing.assert_array_equal(np.isnan(ranges), np.isnan(distance))
        np.testing.assert_allclose(ranges, distance, rtol=0, atol=1e-9)
        assert got[f"{SCANNER}.ScanTime"] == scan["time"] and got[f"{SCANNER}.Scans"] == scan["count"]
        assert scan["time"] <= got["Reclaimer.SimTime"] - 0.01 + 1e-12  # made during a period stepped
        assert np.isfinite(ranges).sum() > 150 and np.nanmax(ranges) <= 80.0  # it sees the pile, within range
        profiles.append(ranges)
    # 25 Hz at 100 Hz: the scans at 0, 0.04, 0.08 s, ...; every one is a new profile
    assert [served["readings"][k][f"{SCANNER}.Scans"] for k in (1, 2, 400)] == [1, 1, 100]
    assert not np.allclose(profiles[2], profiles[4], equal_nan=True)  # the wheel sank and dug meanwhile
    np.testing.assert_array_equal(served["angles"], in_process["angles"])
    assert served["angles"][0] == pytest.approx(np.radians(-20.0)) and served["angles"][-1] == pytest.approx(
        np.radians(75.0))
    assert served["shape"] == (1, [191])  # a one-dimensional array of the rays
    start = served["start"]
    assert np.isnan(start[f"{SCANNER}.Ranges"]).all() and start[f"{SCANNER}.Scans"] == 0


def test_a_faults_state_is_true_in_its_window_only(served, in_process):
    states = {k: served["readings"][k][FAULT] for k in CHECKPOINTS}
    assert states == {k: 1450 <= k <= 1549 for k in CHECKPOINTS}
    assert states == {k: in_process["readings"][k]["fault"] for k in CHECKPOINTS}
    assert served["start"][FAULT] is False and served["fault_type"] == ua.NodeId(ua.ObjectIds.Boolean)
    assert served["fault_description"].startswith("faults[0], belt_scale_frozen, from 14.5 s for 1 s")
    # What it does shows on the scale: the reading holds through the window, and moves on after it.
    belt = {k: served["readings"][k]["Reclaimer.BeltScale"] for k in CHECKPOINTS}
    assert belt[1450] == belt[1451] == belt[1549] == belt[1550] != belt[1551]
    assert belt[1449] != belt[1450]


def test_reset_shows_no_scan_no_reading_and_no_fault(served):
    after = served["after_reset"]
    assert after["Reclaimer.SimTime"] == 0.0
    assert after["Reclaimer.BeltScale"] == 0.0 and after["Reclaimer.WheelCurrent"] == 0.0
    assert np.isnan(after[f"{SCANNER}.Ranges"]).all() and after[f"{SCANNER}.Scans"] == 0
    assert after[f"{SCANNER}.ScanTime"] == 0.0 and after[FAULT] is False


def test_the_new_doubles_are_analog_items_with_units_and_ranges(served, in_process):
    analog = served["analog"]
    loop = in_process["loop"]
    current_at_rating = 1.0e6 * loop.instruments.motor.amps_per_watt  # the MJCF's wheel_power, 1 MW
    expected = {
        "Reclaimer/BeltScale": ("t/h", "E18", (0.0, 98 * 1.0 / 60 * 2400 * 3.6)),  # 14,112 t/h, as ReclaimRate
        "Reclaimer/WheelCurrent": ("A", "AMP", (0.0, current_at_rating)),
        "Reclaimer/Scanners/scanner_boom/Ranges": ("m", "MTR", (0.0, 80.0)),
        "Reclaimer/Scanners/scanner_boom/Angles": ("rad", "C81", (np.radians(-20.0), np.radians(75.0))),
        "Reclaimer/Scanners/scanner_boom/ScanTime": ("s", "SEC", (0.0, 96.0)),
    }
    assert current_at_rating == pytest.approx(1024.16, abs=0.01)
    assert analog["Reclaimer/ReclaimRate"]["EURange"].High == pytest.approx(expected["Reclaimer/BeltScale"][2][1])
    for path, (unit, code, (low, high)) in expected.items():
        found = analog[path]
        assert found["type"] == ua.NodeId(ua.ObjectIds.AnalogUnitType), path
        assert (found["EngineeringUnits"].DisplayName.Text, found["EngineeringUnits"].UnitId) == (unit, unece(code))
        assert (found["EURange"].Low, found["EURange"].High) == pytest.approx((low, high)), path
    # The paper machine's contract and these: 8 per axis, 3 machine-level, 5 more.
    assert len(analog) == 3 * 8 + 3 + 5


def test_the_nodeset_holds_the_new_nodes_and_loads_into_a_fresh_server(dig_scene, tmp_path):
    nodeset = tmp_path / "dig.xml"
    written = subprocess.run(serve_command(dig_scene, "--nodeset", str(nodeset)), cwd=ROOT, env=environment(),
                             capture_output=True, text=True, timeout=120, check=False)
    assert written.returncode == 0, written.stderr
    ids = {element.get("NodeId").split(";s=", 1)[1] for element in Et.parse(nodeset).getroot()
           if element.get("NodeId", "").startswith("ns=1;s=")}
    for node_id in ("Reclaimer.BeltScale", "Reclaimer.WheelCurrent", "Reclaimer.BeltScale.EURange",
                    "Reclaimer.WheelCurrent.EngineeringUnits", "Reclaimer.Scanners", SCANNER, f"{SCANNER}.Ranges",
                    f"{SCANNER}.Angles", f"{SCANNER}.Angles.EURange", f"{SCANNER}.ScanTime", f"{SCANNER}.Scans",
                    "Reclaimer.Faults", FAULT):
        assert node_id in ids, node_id

    async def loaded():
        fresh = Server()
        await fresh.init()
        await fresh.import_xml(str(nodeset))
        ns = await fresh.get_namespace_index(NAMESPACE_URI)
        angles = await fresh.get_node(f"ns={ns};s={SCANNER}.Angles").read_value()
        current = await fresh.get_node(f"ns={ns};s=Reclaimer.WheelCurrent.EURange").read_value()
        fault = await fresh.get_node(f"ns={ns};s={FAULT}").read_value()
        return angles, current, fault

    angles, current, fault = run(loaded())
    scene = load_scene(dig_scene)
    loop = Lockstep([scene], nthread=1, observe=False)
    np.testing.assert_array_equal(angles, loop.scanning.scanners[0].angles)
    assert current.High == pytest.approx(1.0e6 * loop.instruments.motor.amps_per_watt) and fault is False


def test_a_run_without_senses_serves_none_of_their_nodes():
    """pid_paper: no stockpile, no instruments, no scanner, no faults: the address space is the
    paper contract alone."""
    from bwr_twin.serve.clock import Clock
    from bwr_twin.serve.server import build_address_space
    from bwr_twin.sim.twin import Twin

    async def children():
        server = Server()
        await server.init()
        clock = Clock(Twin(load_scene(find_scene("pid_paper"))), log=lambda line: None)
        space = await build_address_space(server, clock)
        names = [(await child.read_browse_name()).Name for child in await space.objects[None].get_children()]
        return names, len(clock.listeners), sorted(clock.readings())

    names, listeners, readings = run(children())
    assert "ReclaimRate" in names and "Travel" in names
    assert not {"BeltScale", "WheelCurrent", "Scanners", "Faults"} & set(names)
    assert listeners == 2  # the Machinery state and the alarms
    assert not {"BeltScale", "WheelCurrent", "Scans", "Faults"} & set(readings)
