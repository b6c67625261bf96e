"""The stockpile: the pile in the scene and in the MuJoCo world, the cut against geometry, the
mass balance, the digging load, and what a run writes about them."""

from __future__ import annotations

import json
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, SCENES, VARIANT_MJCF

from bwr_twin import ModelError, SceneError
from bwr_twin.config.scene import load_scene
from bwr_twin.config.sections import StockpileSection, WindrowSection
from bwr_twin.model.machine import Machine
from bwr_twin.model.spec import STOCKPILE, Edits, compile_model, set_stockpile_heights
from bwr_twin.pile.cutting import Cutter
from bwr_twin.pile.relaxation import Talus
from bwr_twin.pile.surface import Surface, build_surface
from bwr_twin.results.run_files import read_timeseries
from bwr_twin.results.summary import summary_table
from bwr_twin.sim.lockstep import simulate, simulate_lockstep
from bwr_twin.stockpile.digging import jacobian_transpose
from bwr_twin.stockpile.placement import check_placement

# heavy_dig_pile's cut, shortened: from beside the windrow's flank at slew 30 deg into it at
# 0.15 deg/s, then up and clear of the pile, where the run ends (travel m, slew deg, luff deg).
SHORT_DIG = {
    "path.via_points": [
        {"t": 0.0, "p": [50.899, 29.387, 18.985]},   # (0, 30, 5.2): beside the flank
        {"t": 66.0, "p": [45.023, 37.779, 18.985]},  # (0, 40, 5.2): into the windrow
        {"t": 96.0, "p": [41.24, 41.24, 22.604]},    # (0, 45, 9): lifted clear
    ]
}


@pytest.fixture(scope="module")
def short_dig():
    return simulate(load_scene(SCENES / "heavy_dig_pile.toml", SHORT_DIG))


def test_the_pile_loses_exactly_what_the_buckets_carry_and_spill(short_dig):
    reclaim = short_dig.metrics["reclaim"]
    pile = short_dig.reclaim
    cell_area = (pile.x[1] - pile.x[0]) ** 2
    lost = (pile.z_start.sum() - pile.z_end.sum()) * cell_area  # m^3, from the heights alone
    assert reclaim["mass_t"] > 50  # it really dug
    density = 2.4  # t/m^3, the scene's bulk density
    assert lost == pytest.approx(reclaim["dug_m3"], rel=1e-12, abs=0)
    assert reclaim["mass_t"] + reclaim["spill_t"] == pytest.approx(lost * density, rel=1e-12)
    # The run ends with the wheel clear of the pile: the rate's integral is all that was carried.
    assert reclaim["conveyed_t"] == pytest.approx(reclaim["mass_t"], rel=1e-12)
    period = short_dig.scene.simulation.record_period
    assert reclaim["rate_mean_tph"] * reclaim["carrying_time_s"] / 3600 == pytest.approx(reclaim["conveyed_t"], rel=1e-9)
    assert np.sum(pile.rate) * period / 3600 == pytest.approx(reclaim["conveyed_t"], rel=0.02)  # recorded every 10th period


def test_the_faces_a_cut_leaves_slump_to_the_angle_of_repose_and_the_pile_still_loses_what_was_dug(short_dig):
    """With a `stockpile.angle_of_repose` the faces the wheel cuts slump after each cut, the
    volume kept: the pile ends with no slope steeper than the angle (the windrow starts at it),
    and loses exactly what the buckets took. Without it the cut face stands steeper."""
    slumping = simulate(load_scene(SCENES / "heavy_dig_pile.toml",
                                   {**SHORT_DIG, "stockpile.angle_of_repose": 37.0}))
    pile, reclaim = slumping.reclaim, slumping.metrics["reclaim"]
    talus = Talus.of(pile.x[1] - pile.x[0], 37.0)
    assert talus.excess(pile.z_start) <= talus.tolerance  # the windrow stands at its angle
    assert talus.excess(pile.z_end) <= talus.tolerance
    assert talus.excess(short_dig.reclaim.z_end) > 0.05  # m a cell: the 45 deg the wheel's rim leaves, unslumped
    assert reclaim["slumped_m3"] > 10.0 and reclaim["slumps_unconverged"] == 0
    cell_area = (pile.x[1] - pile.x[0]) ** 2
    lost = (pile.z_start.sum() - pile.z_end.sum()) * cell_area
    assert lost == pytest.approx(reclaim["dug_m3"], rel=1e-12, abs=0)
    # The slumped material fell into the wheel's way and was dug: more than the face alone gave.
    assert reclaim["dug_m3"] > short_dig.metrics["reclaim"]["dug_m3"]
    assert "slumped_m3" not in short_dig.metrics["reclaim"]  # a pile without the angle is as before
    assert f"the cut faces slumped {reclaim['slumped_m3']:,.0f} m³" in summary_table(slumping.metrics)


def _prism(height: float, x: tuple[float, float], y: tuple[float, float], spacing: float) -> Surface:
    """A box of material `height` m high over x and y (m), on a grid with a border of ground."""
    xs = np.arange(x[0] - 20, x[1] + 20 + spacing / 2, spacing)
    ys = np.arange(y[0] - 10, y[1] + 10 + spacing / 2, spacing)
    inside = (xs[None, :] >= x[0]) & (xs[None, :] <= x[1]) & (ys[:, None] >= y[0]) & (ys[:, None] <= y[1])
    return Surface(xs, ys, np.where(inside, height, 0.0))


def _travel_cut(surface: Surface, machine: Machine, slew: float, luff: float, travel: np.ndarray) -> float:
    """m^3 the wheel cuts as the machine travels through `travel` (m) at fixed slew and luff (rad)."""
    cutter = Cutter(surface, machine.wheel, 1)
    dug = 0.0
    for d in travel:
        q = np.array([[d, slew, luff]])
        dug += cutter.cut(machine.fk(q), q[:, 1]).volume[0]
    return dug


def test_a_travel_cut_across_the_wheel_removes_the_circle_segment_the_geometry_gives():
    machine = Machine(HEAVY_MJCF)
    spacing, height = 0.1, 15.0
    slew, luff = np.pi / 2, np.radians(5.2)  # boom square to the rail: the wheel moves along its axis
    cp = machine.fk(np.array([0.0, slew, luff]))
    surface = _prism(height, (-10.0, 10.0), (cp[1] - 8.0, cp[1] + 8.0), spacing)
    dug = _travel_cut(surface, machine, slew, luff, np.arange(-18.0, 18.0, 0.005))
    # The wheel's disc below the surface, a circle segment, over the prism's length.
    r, above = machine.wheel.radius, cp[2] - height
    segment = r**2 * np.arccos(above / r) - above * np.sqrt(r**2 - above**2)
    length = np.count_nonzero(surface.z[len(surface.y) // 2]) * spacing
    assert dug == pytest.approx(segment * length, rel=1e-4)  # 9e-6 measured


def test_a_wheel_that_dips_below_the_yard_floor_digs_no_ground():
    """The pile stands on the yard floor (Z = 0): a wheel whose lowest point is below it takes
    the pile down to the floor, and no further."""
    machine = Machine(HEAVY_MJCF)
    slew = np.pi / 2
    luff = np.arcsin((machine.wheel.radius - 1.0 - machine.geometry.pivot_height) / machine.geometry.boom_length)
    cp = machine.fk(np.array([0.0, slew, luff]))
    assert cp[2] - machine.wheel.radius == pytest.approx(-1.0)  # the wheel's lowest point 1 m below the floor
    surface = _prism(3.0, (-5.0, 5.0), (cp[1] - 8.0, cp[1] + 8.0), 0.25)
    dug = _travel_cut(surface, machine, slew, luff, np.arange(-15.0, 15.0, 0.01))
    cutter = Cutter(surface, machine.wheel, 1)
    for d in np.arange(-15.0, 15.0, 0.05):
        q = np.array([[d, slew, luff]])
        cutter.cut(machine.fk(q), q[:, 1])
    assert cutter.heights.min() == 0.0  # down to the floor where the wheel passed ...
    assert dug == pytest.approx(surface.volume() - surface.volume(cutter.heights[0]), rel=1e-9)
    assert dug <= surface.volume()  # ... and never below it: only the pile is dug


def test_an_oblique_travel_cut_removes_the_swept_envelope():
    machine = Machine(HEAVY_MJCF)
    spacing, height = 0.1, 15.0
    slew, luff = np.radians(60.0), np.radians(5.2)
    cp = machine.fk(np.array([0.0, slew, luff]))
    surface = _prism(height, (-10.0, 10.0), (cp[1] - 9.0, cp[1] + 9.0), spacing)
    dug = _travel_cut(surface, machine, slew, luff, np.arange(-25.0, 25.0, 0.005) - cp[0])  # CP X from -25 to 25 m
    # Swept along X, the envelope's lowest point over each Y line is the cut's floor there.
    r, half_width = machine.wheel.radius, machine.wheel.width / 2
    ys = np.linspace(-9.0, 9.0, 3601)
    xs = np.linspace(-15.0, 15.0, 30001)[:, None]
    along = xs * np.cos(slew) + ys * np.sin(slew)
    across = ys * np.cos(slew) - xs * np.sin(slew)
    envelope = np.where(np.abs(along) < r, cp[2] - np.sqrt(np.clip(r**2 - along**2, 0, None)), np.inf)
    envelope = envelope + machine.wheel.side_slope * np.clip(np.abs(across) - half_width, 0, None)
    floor = envelope.min(axis=0)
    section = np.trapezoid(np.clip(height - floor, 0, None), ys)
    length = np.count_nonzero(surface.z[len(surface.y) // 2]) * spacing
    assert dug == pytest.approx(section * length, rel=2e-3)  # 4.4e-4 measured


def test_a_lockstep_draws_its_pile_as_the_scene_says():
    """[stockpile] colour and base_depth reach the machine's world, where the pile is drawn."""
    from bwr_twin.sim.lockstep import Lockstep

    scene = load_scene(SCENES / "heavy_dig_pile.toml", {"stockpile.colour": [0.2, 0.2, 0.2, 1.0],
                                                        "stockpile.base_depth": 2.5})
    model = Lockstep([scene], observe=False).machine.model
    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, STOCKPILE)
    np.testing.assert_allclose(model.geom_rgba[geom], [0.2, 0.2, 0.2, 1.0], rtol=1e-6)  # float32 in MuJoCo
    assert model.hfield_size[model.geom_dataid[geom], 3] == 2.5


def test_runs_dig_their_own_piles_in_one_lockstep():
    scenes = [load_scene(SCENES / "heavy_dig_pile.toml", {**SHORT_DIG, "simulation.seed": seed}) for seed in (1, 2)]
    together = simulate_lockstep(scenes)
    for scene, result in zip(scenes, together):
        alone = simulate(scene)
        assert result.metrics["reclaim"] == alone.metrics["reclaim"]
        np.testing.assert_array_equal(result.reclaim.z_end, alone.reclaim.z_end)


def test_the_digging_load_resists_the_slewing_within_the_wheel_drive(short_dig):
    cutting = short_dig.reclaim.wheel_power > short_dig.scene.digging.idle_power + 1e5
    assert cutting.sum() > 50
    assert np.all(short_dig.qd_desired[cutting, 1] > 0)  # slewing into the windrow, or lifting out
    assert np.median(short_dig.disturbance[cutting, 1]) < -1e6  # N m against the slewing; the random part is +-0.12 MN m
    assert short_dig.metrics["reclaim"]["digging_force_max_N"] <= 1.0e6 / machine_rim_speed() * 1.1


@pytest.mark.parametrize("mjcf", [HEAVY_MJCF, VARIANT_MJCF])
def test_the_digging_load_on_the_joints_is_mujocos_jacobian_transposed(mjcf):
    """J^T F of a world force at a point fixed to the boom, as the load applies it, equals
    MuJoCo's own Jacobian of that point (mj_jac on the CP's body), at random joint values."""
    machine = Machine(mjcf)
    model, data, g = machine.model, mujoco.MjData(machine.model), machine.geometry
    body = model.site_bodyid[machine.cp_site]
    rng = np.random.default_rng(3)
    jacp = np.zeros((3, model.nv))
    for _ in range(20):
        data.qpos[:] = rng.uniform(machine.envelope[:, 0], machine.envelope[:, 1])
        mujoco.mj_forward(model, data)
        point = data.site_xpos[machine.cp_site] + rng.uniform(-3, 3, 3)  # about where a wheel cuts
        force = rng.uniform(-1e5, 1e5, 3)
        mujoco.mj_jac(model, data, jacp, None, point, body)
        q = data.qpos
        ours = jacobian_transpose(q[0], np.cos(q[1]), np.sin(q[1]), *point, *force, *g.slew_axis_xy,
                                  g.pivot_reach, g.pivot_height)
        np.testing.assert_allclose(ours, jacp.T @ force, rtol=1e-9, atol=1e-6)


def machine_rim_speed() -> float:
    return Machine(HEAVY_MJCF).wheel.rim_speed


def test_the_wheels_optional_keys_have_their_defaults_and_are_checked(tmp_path):
    """wheel_side_slope, wheel_bench_share and wheel_clearance: the file's values, the
    documented defaults without them, refused unless one value > 0."""
    text = HEAVY_MJCF.read_text()
    keys = ("wheel_side_slope", "wheel_bench_share", "wheel_clearance")
    for key in keys:
        assert f'<numeric name="{key}"' in text
    edited = tmp_path / "bwr_heavy.xml"
    edited.write_text(text.replace('name="wheel_side_slope" data="6"', 'name="wheel_side_slope" data="4"'))
    assert Machine(edited).wheel.side_slope == 4.0
    lines = [line for line in text.splitlines() if not any(f'name="{key}"' in line for key in keys)]
    edited.write_text("\n".join(lines))
    wheel = Machine(edited).wheel
    assert (wheel.side_slope, wheel.bench_share, wheel.clearance) == (6.0, 0.6, 0.5)
    edited.write_text(text.replace('name="wheel_clearance" data="0.5"', 'name="wheel_clearance" data="0 1"'))
    with pytest.raises(ModelError, match="bwr_heavy.xml: custom numeric 'wheel_clearance' must hold one value > 0"):
        Machine(edited)


def test_the_pile_stands_in_the_mujoco_world_where_rays_measure_it():
    scene = load_scene(SCENES / "heavy_dig_pile.toml")
    surface = build_surface(scene.stockpile, scene.path)
    machine = Machine(HEAVY_MJCF, stockpile=surface)
    model = machine.model
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom = np.zeros(1, dtype=np.int32)

    def scan(x: float, y: float) -> float:
        distance = mujoco.mj_ray(model, data, np.array([x, y, 100.0]), np.array([0.0, 0.0, -1.0]),
                                 np.array([0, 1, 0, 0, 0, 0], dtype=np.uint8), 1, -1, geom)
        return 100.0 - distance

    for x, y in ((40.0, 40.0), (40.0, 30.0), (100.0, 45.0), (-27.3, 21.1)):
        ix, iy = np.abs(surface.x - x).argmin(), np.abs(surface.y - y).argmin()  # a grid node near
        assert scan(surface.x[ix], surface.y[iy]) == pytest.approx(surface.z[iy, ix], abs=1e-6)
    dug = surface.z.copy()
    dug[surface.z > 10.0] = 10.0  # a pile dug down to 10 m
    set_stockpile_heights(model, dug)
    assert scan(40.0, 40.0) == pytest.approx(10.0, abs=1e-6)
    # The simulation's model carries no pile: it has no mass and touches nothing.
    assert machine.physics_model().nhfield == 0


def test_the_pile_is_drawn_as_its_scene_says():
    scene = load_scene(SCENES / "heavy_dig_pile.toml", {"stockpile.colour": [0.1, 0.2, 0.3, 1.0],
                                                        "stockpile.base_depth": 2.0})
    surface = build_surface(scene.stockpile, scene.path)
    model = compile_model(HEAVY_MJCF, Edits(stockpile=surface, stockpile_drawing=scene.stockpile))
    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, STOCKPILE)
    assert model.geom_rgba[geom] == pytest.approx([0.1, 0.2, 0.3, 1.0])
    assert model.hfield_size[0, 3] == 2.0
    assert load_scene(SCENES / "heavy_dig_pile.toml").stockpile.colour == (0.55, 0.27, 0.15, 1.0)  # iron ore
    with pytest.raises(SceneError, match=r"'stockpile.colour' \(rgba\) must lie in \[0, 1\], got \[0.5, 0.5, 2.0, 1.0\]"):
        load_scene(SCENES / "heavy_dig_pile.toml", {"stockpile.colour": [0.5, 0.5, 2.0, 1.0]})


def test_a_pile_on_the_rail_or_out_of_reach_or_for_a_machine_without_a_wheel_is_refused():
    base = SCENES / "heavy_dig_pile.toml"
    with pytest.raises(SceneError, match=r"\[stockpile\]: the pile comes within .* of the rail axis; the machine needs 8.00 m clear"):
        simulate(load_scene(base, {"stockpile.windrow.centre": [40.0, 12.0]}))
    with pytest.raises(SceneError, match=r"no part of the pile .* is within the wheel's reach: 64.0 m from the slew axis"):
        simulate(load_scene(base, {"stockpile.windrow.centre": [40.0, 150.0]}))
    scene = load_scene(base)
    with pytest.raises(SceneError, match=r"heavy_dig_pile.toml: \[stockpile\]: bwr_variant.xml describes no bucket wheel"):
        check_placement(build_surface(scene.stockpile, scene.path), Machine(VARIANT_MJCF), scene.path)


def test_a_surveyed_surface_from_points_or_a_grid_matches_the_windrow_it_samples(tmp_path):
    windrow = WindrowSection(length=40.0, crest_width=6.0, height=12.0, angle_of_repose=37.0, centre=(0.0, 40.0))
    grid = build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, windrow=windrow), tmp_path)
    np.savez(tmp_path / "survey.npz", x=grid.x, y=grid.y, z=grid.z)
    from_grid = build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, surface_file=tmp_path / "survey.npz"), tmp_path)
    assert from_grid.volume() == pytest.approx(grid.volume(), rel=1e-9)
    gx, gy = np.meshgrid(grid.x[::2], grid.y[::2])
    points = np.column_stack([gx.ravel(), gy.ravel(), grid.z[::2, ::2].ravel()])
    np.savetxt(tmp_path / "survey.csv", points, delimiter=",", header="x,y,z", comments="")
    from_points = build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, surface_file=tmp_path / "survey.csv"), tmp_path)
    assert from_points.volume() == pytest.approx(grid.volume(), rel=0.02)  # linear between 1 m samples


@pytest.mark.parametrize("content, message", [
    ("x,y,z\n0,0,1\n1,0,1\n", r"needs at least 3 points, got 2"),
    ("x,y,z\n0,0,1\n1,0,nan\n0,1,2\n", r"z holds a value that is not a finite number"),
    ("x,y,z\n0,0,1\n1,0\n0,1,2\n", r"data row 2 must be three numbers x,y,z \(m\), got '1,0'"),
])
def test_a_bad_survey_is_named_with_its_row(tmp_path, content, message):
    (tmp_path / "survey.csv").write_text(content)
    with pytest.raises(SceneError, match=rf"'stockpile.surface_file' .*survey.csv: {message}"):
        build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, surface_file=tmp_path / "survey.csv"), tmp_path)


def test_a_run_writes_its_pile_rate_and_figures(tmp_path):
    scene = tmp_path / "dig.toml"
    via = ",\n".join(f"  {{ t = {v['t']}, p = {v['p']} }}" for v in SHORT_DIG["path.via_points"])
    scene.write_text(f'extends = "{SCENES / "heavy_dig_pile.toml"}"\n\n[path]\nframe = "world"\nvia_points = [\n{via}\n]\n')
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.run", scene, "--out", tmp_path / "out"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "reclaimed " in proc.stdout and " t/h over " in proc.stdout
    out = tmp_path / "out"
    metrics = json.loads((out / "metrics.json").read_text())
    assert {"mass_t", "volume_m3", "rate_mean_tph", "rate_cv", "spill_t"} <= set(metrics["reclaim"])
    with np.load(out / "pile.npz") as pile:
        assert pile["z_start"].shape == pile["z_end"].shape == (len(pile["y"]), len(pile["x"]))
        assert (pile["z_start"] >= pile["z_end"]).all() and (pile["z_start"] > pile["z_end"]).any()
    series = read_timeseries(out / "timeseries.csv", envelope=Machine(HEAVY_MJCF).envelope)
    assert {"rate", "cut_depth", "wheel_power", "digging_force"} <= set(series.reclaim)
    assert {"reclaim_rate_t/h", "cut_depth_m", "wheel_power_W", "digging_force_x_N"} <= set(series.columns)
    assert (out / "pile.png").stat().st_size > 10_000 and (out / "reclaim.png").stat().st_size > 10_000


def test_a_scene_without_a_pile_digs_nothing():
    scene = load_scene(SCENES / "paper_individual_gains.toml")
    assert scene.stockpile is None
    with pytest.raises(SceneError, match=r"\[digging\] needs a \[stockpile\] to dig"):
        load_scene(SCENES / "paper_individual_gains.toml", {"digging.cutting_energy": 1.0})


@pytest.mark.parametrize("override, message", [
    ({"stockpile.windrow": None}, r"needs either a \[stockpile.windrow\] or a 'stockpile.surface_file', not both"),
    ({"stockpile.windrow.angle_of_repose": 95.0}, r"'stockpile.windrow.angle_of_repose' must lie in \(0, 90\) deg, got 95.0"),
    ({"stockpile.angle_of_repose": 90.0}, r"'stockpile.angle_of_repose' must lie in \(0, 90\) deg, got 90.0"),
    ({"stockpile.angle_of_repose": 0.65}, r"'stockpile.angle_of_repose' must lie in \[10, 60\] deg \(.*CEMA Table 3-1\), got 0.65"),
    ({"stockpile.grid_spacing": 0.0}, r"'stockpile.grid_spacing' must be > 0, got 0.0"),
    ({"stockpile.windrow.centre": [1.0]}, r"'stockpile.windrow.centre' must hold 2 values, got 1"),
    ({"stockpile.grid_spacing": 1e-4}, r"'stockpile.grid_spacing' gives .* height samples, more than 2e\+07"),
])
def test_a_bad_stockpile_is_named(override, message, tmp_path):
    (tmp_path / "pile.csv").write_text("0,0,1\n1,0,1\n0,1,1\n")
    with pytest.raises(SceneError, match=message):
        scene = load_scene(SCENES / "heavy_dig_pile.toml", {k: str(tmp_path / v) if k.endswith("_file") else v
                                                            for k, v in override.items()})
        build_surface(scene.stockpile, scene.path)


def test_one_file_giving_both_a_windrow_and_a_surface_is_refused_and_an_override_replaces_either(tmp_path):
    (tmp_path / "pile.csv").write_text("0,0,1\n1,0,1\n0,1,1\n")
    both = (SCENES / "heavy_dig_pile.toml").read_text().replace("[stockpile]\n", '[stockpile]\nsurface_file = "pile.csv"\n')
    (tmp_path / "both.toml").write_text(both.replace('extends = "', f'extends = "{SCENES}/'))
    with pytest.raises(SceneError, match=r"needs either a \[stockpile.windrow\] or a 'stockpile.surface_file', not both"):
        load_scene(tmp_path / "both.toml")
    surveyed = load_scene(SCENES / "heavy_dig_pile.toml", {"stockpile.surface_file": str(tmp_path / "pile.csv")})
    assert surveyed.stockpile.windrow is None and surveyed.stockpile.surface_file == tmp_path / "pile.csv"


def test_a_batch_summary_reports_each_run_s_reclaim(tmp_path):
    import csv

    scene = tmp_path / "dig.toml"
    via = ",\n".join(f"  {{ t = {v['t']}, p = {v['p']} }}" for v in SHORT_DIG["path.via_points"][:2])
    scene.write_text(f'extends = "{SCENES / "heavy_dig_pile.toml"}"\n\n[path]\nframe = "world"\nvia_points = [\n{via}\n]\n')
    (tmp_path / "sweep.toml").write_text('scene = "dig.toml"\nseeds = [1, 2]\n')
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.batch", tmp_path / "sweep.toml", "--out", tmp_path / "b"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    with open(tmp_path / "b" / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [float(row["reclaim.mass_t"]) > 10.0 for row in rows] == [True, True]
    assert all((tmp_path / "b" / row["run"] / "pile.npz").is_file() for row in rows)
