"""A second machine on the rail over OPC UA (docs/opcua.md): a real asyncua client reads the
neighbour's latest position report from the server in its own process, against the same run
stepped in-process under the same (zero) drive forces."""

from __future__ import annotations

import numpy as np
import pytest
from asyncua import ua
from test_serve import Plc, analog_variables, client, run_served
from test_two_machines import SCENE, SHORT

from bwr_twin.config.scene import load_scene
from bwr_twin.sim.lockstep import Lockstep

CHECKPOINTS = (1, 50, 100, 7000, 12000)  # the neighbour at rest, then moving (from 60 s)
AXES = ("Travel", "Slew", "Luff")
READ = ("Reclaimer.SimTime", "Reclaimer.NeighbourReportTime",
        *(f"Reclaimer.{axis}.NeighbourPosition" for axis in AXES))


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    rows = "".join(f"  {{ t = {v['t']}, p = [{', '.join(str(x) for x in v['p'])}] }},\n"
                   for v in SHORT["path.via_points"])
    path = tmp_path_factory.mktemp("serve_neighbour") / "two.toml"
    path.write_text(f'extends = "{SCENE}"\n\n[path]\nframe = "world"\nvia_points = [\n{rows}]\n')
    return path


@pytest.fixture(scope="module")
def in_process(scene_file):
    loop = Lockstep([load_scene(scene_file)], nthread=1)
    found = {}
    loop.measure()
    for _ in range(CHECKPOINTS[-1]):
        loop.advance(np.zeros((1, 3)))
        loop.measure()
        if loop.k in CHECKPOINTS:
            found[loop.k] = (loop.neighbour.report_time, loop.neighbour.reported[0, 0].copy())
    return found


@pytest.fixture(scope="module")
def served(scene_file):
    async def session(url):
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            nodes = [connection.get_node(f"ns={plc.ns};s={node_id}") for node_id in READ]
            await plc.set_drives([0.0, 0.0, 0.0])
            readings, at = {}, 0
            for k in CHECKPOINTS:
                await plc.step(k - at)
                at = k
                readings[k] = await connection.read_values(nodes)
            return readings, await analog_variables(connection, plc.ns)

    return run_served(scene_file, session, "--no-plots")


def test_the_neighbours_report_over_opc_ua_is_the_twins_report_delay_late(served, in_process):
    readings, _ = served
    for k in CHECKPOINTS:
        sim_time, report_time, *position = readings[k]
        expected_time, expected = in_process[k]
        assert sim_time == pytest.approx(k * 0.01)
        assert report_time == pytest.approx(expected_time) == pytest.approx(max(k * 0.01 - 0.5, 0.0))
        np.testing.assert_array_equal(position, expected)
    assert readings[CHECKPOINTS[-1]][2] > readings[100][2] + 5.0  # it has set off towards the machine


def test_the_neighbours_nodes_are_analog_items_with_units_and_its_envelope(served):
    """Analog items with their units and ranges: the neighbour's envelope (its MJCF's), the run's time."""
    _, analog = served
    expected = {"Reclaimer/Travel/NeighbourPosition": ("m", (-200.0, 200.0)),
                "Reclaimer/Slew/NeighbourPosition": ("rad", (-1.9198621771937625, 1.9198621771937625)),
                "Reclaimer/NeighbourReportTime": ("s", (0.0, 400.0))}
    for path, (unit, (low, high)) in expected.items():
        found = analog[path]
        assert found["type"] == ua.NodeId(ua.ObjectIds.AnalogUnitType), path
        assert found["EngineeringUnits"].DisplayName.Text == unit, path
        assert (found["EURange"].Low, found["EURange"].High) == pytest.approx((low, high)), path
