"""The automation's own senses: the boom's laser scanner read from the MJCF, the ray cast against
MuJoCo's mj_ray, scans of piles whose geometry is known by hand, the scanner's noise and
dropouts, the pile known from the scans, and what a run writes about them (docs/sensing.md)."""

from __future__ import annotations

import dataclasses
import itertools
import math
import types

import mujoco
import numpy as np
import pytest
from conftest import HEAVY_MJCF, PAPER_MJCF, SCENES

from bwr_twin import BwrError, ModelError, SceneError
from bwr_twin.config.plugins import controller_class
from bwr_twin.config.scene import Scene, load_scene
from bwr_twin.model.machine import Machine
from bwr_twin.model.scanner import Mount, Scanner
from bwr_twin.model.spec import Edits, compile_model
from bwr_twin.pile.surface import Surface, build_surface
from bwr_twin.results.rundir import write_run
from bwr_twin.sensing.outputs import HIT_BYTES, SCAN_BYTES, SURVEY_CELL_BYTES
from bwr_twin.sensing.raycast import cast_rays
from bwr_twin.sensing.scanning import Scanning, active_scanners
from bwr_twin.sensing.survey import Survey, tonnes_against
from bwr_twin.sim import budget
from bwr_twin.sim.budget import estimate
from bwr_twin.sim.lockstep import Lockstep, lockstep_key, simulate, simulate_lockstep

DEG = math.pi / 180


# -- the ray cast against MuJoCo ---------------------------------------------------------------

def _hfield_world(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> tuple[mujoco.MjModel, np.ndarray]:
    """A world holding only an hfield of heights z[iy, ix] at grid lines x, y, placed as the
    twin places a pile (bwr_twin.model.spec); and the heights as MuJoCo holds them (float32 x top)."""
    top = float(z.max())
    spec = mujoco.MjSpec()
    spec.add_hfield(name="pile", nrow=len(y), ncol=len(x), size=[(x[-1] - x[0]) / 2, (y[-1] - y[0]) / 2, top, 1.0],
                    userdata=(z / top).ravel().tolist())
    spec.worldbody.add_geom(type=mujoco.mjtGeom.mjGEOM_HFIELD, hfieldname="pile",
                            pos=[(x[0] + x[-1]) / 2, (y[0] + y[-1]) / 2, 0.0])
    model = spec.compile()
    return model, model.hfield_data.astype(float).reshape(len(y), len(x)) * model.hfield_size[0, 2]


def _mj_ray(model: mujoco.MjModel, origins: np.ndarray, directions: np.ndarray,
            groups: np.ndarray | None = None) -> np.ndarray:
    """mj_ray's distance of each ray to the surface of the model's hfield, NaN where it meets none.
    A ray that misses the surface and meets the hfield's base box (below the yard floor, where
    no pile stands) is a miss as well."""
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    geom = np.zeros(1, dtype=np.int32)
    out = np.array([mujoco.mj_ray(model, data, o, d, groups, 1, -1, geom) for o, d in zip(origins, directions)])
    out[out < 0] = np.nan
    below = origins[:, 2] + out * directions[:, 2] < -1e-9
    out[below] = np.nan
    return out


def _rough_pile(rng: np.random.Generator, spacing: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A hipped windrow 5 m high with rough faces, on a grid with a border of ground."""
    x = np.arange(-10.0, 10.0 + spacing / 2, spacing) + 3.0
    y = np.arange(-6.0, 6.0 + spacing / 2, spacing) - 2.0
    gx, gy = np.meshgrid(x, y)
    z = np.clip(5.0 - 0.75 * np.maximum(np.abs(gx - 3.0) - 4.0, np.abs(gy + 2.0) - 1.0), 0.0, None)
    z += rng.uniform(0.0, 0.4, z.shape) * (z > 0)
    z[[0, -1], :] = z[:, [0, -1]] = 0.0
    return x, y, z


def _points_on(x: np.ndarray, y: np.ndarray, heights: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) random points of the hfield's surface, within its cells' triangles."""
    c, r = rng.integers(0, len(x) - 1, n), rng.integers(0, len(y) - 1, n)
    u, v = rng.uniform(0.01, 0.99, n), rng.uniform(0.01, 0.99, n)
    z00, z10, z01, z11 = heights[r, c], heights[r, c + 1], heights[r + 1, c], heights[r + 1, c + 1]
    z = np.where(v <= u, z00 + (z10 - z00) * u + (z11 - z10) * v, z00 + (z11 - z01) * u + (z01 - z00) * v)
    spacing = x[1] - x[0]
    return np.column_stack([x[c] + u * spacing, y[r] + v * spacing, z])


def test_the_ray_cast_meets_the_pile_where_mj_ray_meets_its_hfield():
    rng = np.random.default_rng(7)
    x, y, z = _rough_pile(rng, 0.5)
    model, heights = _hfield_world(x, y, z)
    top = heights.max()
    n = 6000
    # Rays from above at random directions, 2 to 90 deg below the level, aimed at the yard floor on
    # and around the grid: those aimed beyond it miss the pile, unless they cross it first.
    elevation, azimuth = rng.uniform(2 * DEG, 90 * DEG, n), rng.uniform(0, 2 * np.pi, n)
    directions = np.column_stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                                  -np.sin(elevation)])
    floor = np.column_stack([rng.uniform(x[0] - 4, x[-1] + 4, n), rng.uniform(y[0] - 4, y[-1] + 4, n), np.zeros(n)])
    origins = floor - (rng.uniform(top + 0.1, 25, n) / np.sin(elevation))[:, None] * directions
    # Grazing rays: aimed at 0.05 to 10 deg at points of the surface within its triangles (a ray that
    # only touches a vertex or an edge and passes on above is a tie of no width, which either may call
    # a hit), from just above the top.
    elevation, azimuth = rng.uniform(0.001, 0.17, n), rng.uniform(0, 2 * np.pi, n)
    grazing = np.column_stack([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                               -np.sin(elevation)])
    aim = _points_on(x, y, heights, rng, n)
    origins = np.concatenate([origins, aim - ((top + 0.05 - aim[:, 2]) / np.sin(elevation))[:, None] * grazing])
    directions = np.concatenate([directions, grazing])
    directions /= np.linalg.norm(directions, axis=1)[:, None]

    ours = cast_rays(heights, x, y, origins, directions)
    theirs = _mj_ray(model, origins, directions)
    hit = ~np.isnan(theirs)
    np.testing.assert_array_equal(np.isnan(ours), ~hit)  # both miss where one misses
    assert hit[:n].sum() > 0.3 * n and (~hit[:n]).sum() > 0.3 * n and hit[n:].sum() > 0.95 * n
    np.testing.assert_allclose(ours[hit], theirs[hit], rtol=0, atol=1e-9)  # 5e-12 measured


def test_the_fan_meets_the_pile_the_twin_draws_in_the_machine_s_world():
    """The heavy scanner's fans, from where the machine stands, against the pile as
    bwr_twin.model.spec puts it in the machine's MuJoCo world, rays seeing the pile alone."""
    scene = load_scene(SCENES / "heavy_dig_pile.toml")
    surface = build_surface(scene.stockpile, scene.path)
    model = compile_model(HEAVY_MJCF, Edits(stockpile=surface))
    heights = model.hfield_data.astype(float).reshape(surface.z.shape) * model.hfield_size[0, 2]
    scanner = Machine(HEAVY_MJCF).scanners[0]
    q = np.array([[0.0, 22 * DEG, 5.2 * DEG], [0.0, 45 * DEG, 3 * DEG], [10.0, 64.5 * DEG, 5.2 * DEG]])
    position, rotation = scanner.mount.poses(q)
    directions = np.einsum("nij,rj->nri", rotation, scanner.directions).reshape(-1, 3)
    origins = np.repeat(position, scanner.rays, axis=0)
    ours = cast_rays(heights, surface.x, surface.y, origins, directions, scanner.max_range)
    theirs = _mj_ray(model, origins, directions, np.array([0, 1, 0, 0, 0, 0], dtype=np.uint8))
    theirs[theirs > scanner.max_range] = np.nan
    hit = ~np.isnan(theirs)
    np.testing.assert_array_equal(np.isnan(ours), ~hit)
    assert hit.mean() > 0.5
    np.testing.assert_allclose(ours[hit], theirs[hit], rtol=0, atol=1e-9)


def test_a_scan_walks_the_pile_s_section_once_and_finds_what_each_ray_s_whole_walk_finds():
    """In the loop a fan in a vertical plane begins each ray's walk where the ray below it met
    the pile (bwr_twin.sensing.scanning): its hits are those of every ray walked from the site,
    to the bit; a fan tilted out of the vertical walks every ray whole."""
    scene = load_scene(SCENES / "heavy_dig_pile.toml")
    surface = build_surface(scene.stockpile, scene.path)
    machine = Machine(HEAVY_MJCF)
    upright = dataclasses.replace(machine.scanners[0], noise=(0.0, 0.0), dropout=0.0)
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.3), -np.sin(0.3)], [0.0, np.sin(0.3), np.cos(0.3)]])
    tilted = dataclasses.replace(upright, mount=dataclasses.replace(upright.mount,
                                                                    rotation=upright.mount.rotation @ tilt))
    rng = np.random.default_rng(5)
    q = np.column_stack([rng.uniform(-10, 40, 40), rng.uniform(10, 80, 40) * DEG, rng.uniform(-2, 8, 40) * DEG])
    for scanner in (upright, tilted):
        scanning = Scanning([scanner], surface, [1], 0.04)
        heights = surface.z[None].copy()
        for k in range(len(q)):
            scanning.step(k, q[k:k + 1], heights, None)
        scanned = scanning.record(0).hits
        position, rotation = scanner.mount.poses(q)
        directions = np.einsum("nij,rj->nri", rotation, scanner.directions)
        whole = cast_rays(surface.z, surface.x, surface.y, np.repeat(position, scanner.rays, axis=0),
                          directions.reshape(-1, 3), scanner.max_range).reshape(len(q), scanner.rays)
        assert np.mean(~np.isnan(whole)) > 0.5
        np.testing.assert_array_equal(scanned, (position[:, None, :] + whole[..., None] * directions).astype(np.float32))


# -- the scanner in the MJCF ----------------------------------------------------------------------

def test_the_heavy_machine_carries_an_lms511_on_its_boom_and_the_paper_s_none():
    machine = Machine(HEAVY_MJCF)
    (scanner,) = machine.scanners
    assert scanner.name == "scanner_boom"
    assert np.degrees(scanner.fan) == pytest.approx((-20.0, 75.0))
    assert np.degrees(scanner.step) == pytest.approx(0.5)  # the LMS5xx's step at 25 Hz
    assert (scanner.rate, scanner.max_range, scanner.rays) == (25.0, 80.0, 191)
    assert scanner.noise == (0.004, 0.0004) and scanner.dropout == 0.01
    assert scanner.mount.joints == 3  # on the boom: travel, slew and luff move it
    assert Machine(PAPER_MJCF).scanners == ()


def test_the_scanner_stands_where_mujoco_puts_its_site():
    machine = Machine(HEAVY_MJCF)
    scanner = machine.scanners[0]
    data = mujoco.MjData(machine.model)
    rng = np.random.default_rng(3)
    q = rng.uniform(machine.envelope[:, 0], machine.envelope[:, 1], size=(50, 3))
    position, rotation = scanner.mount.poses(q)
    for i in range(len(q)):
        data.qpos[:] = q[i]
        mujoco.mj_kinematics(machine.model, data)
        np.testing.assert_allclose(position[i], data.site_xpos[scanner.site], rtol=0, atol=1e-9)
        np.testing.assert_allclose(rotation[i], data.site_xmat[scanner.site].reshape(3, 3), rtol=0, atol=1e-12)
    # At home the fan's 0 deg ray looks straight down, and +90 deg out along the boom.
    _, home = scanner.mount.poses(np.zeros(3))
    np.testing.assert_allclose(home[0] @ [0.0, 0.0, -1.0], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(home[0] @ [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace('<numeric name="scanner_boom_rate" data="25"/>', ""),
     r"scanner site 'scanner_boom' needs custom numeric 'scanner_boom_rate' \(scans a second, Hz\)"),
    (lambda t: t.replace('name="scanner_boom_fan" data="-0.3490658503988659 1.3089969389957472"',
                         'name="scanner_boom_fan" data="1.3 -0.3"'),
     r"'scanner_boom_fan' of scanner site 'scanner_boom' must hold start < end within \[-pi, pi\] rad"),
    (lambda t: t.replace('name="scanner_boom_step" data="0.008726646259971648"', 'name="scanner_boom_step" data="0.5"'),
     ("'scanner_boom_step' of scanner site 'scanner_boom' must be > 0 and divide the fan's 1.65806 rad into "
      "whole steps, got 0.5")),
    (lambda t: t.replace('name="scanner_boom_step" data="0.008726646259971648"',
                         'name="scanner_boom_step" data="0.00001745329251994"'),
     "'scanner_boom_step' of scanner site 'scanner_boom' gives 95001 rays a scan, more than 3600"),
    (lambda t: t.replace('name="scanner_boom_noise" data="0.004 0.0004"', 'name="scanner_boom_noise" data="0.004"'),
     (r"'scanner_boom_noise' of scanner site 'scanner_boom' must hold 2 finite values \(m, and a share of the "
      r"range\), got \[0.004\]")),
    (lambda t: t.replace('name="scanner_boom_noise" data="0.004 0.0004"', 'name="scanner_boom_noise" data="-0.01 0"'),
     "'scanner_boom_noise' of scanner site 'scanner_boom' must hold two values >= 0"),
    (lambda t: t.replace('name="scanner_boom_dropout" data="0.01"', 'name="scanner_boom_dropout" data="1"'),
     r"'scanner_boom_dropout' of scanner site 'scanner_boom' must lie in \[0, 1\), got 1.0"),
    (lambda t: t.replace('name="scanner_boom_range" data="80"', 'name="scanner_boom_range" data="0"'),
     "'scanner_boom_range' of scanner site 'scanner_boom' must be > 0 m, got 0.0"),
])
def test_bad_scanner_numerics_are_refused_naming_the_site_and_the_key(tmp_path, edit, message):
    path = tmp_path / "bwr_heavy.xml"
    path.write_text(edit(HEAVY_MJCF.read_text()))
    with pytest.raises(ModelError, match=rf"bwr_heavy.xml: .*{message}"):
        Machine(path)


# -- scans of piles known by hand -----------------------------------------------------------------

def _scanner(position=(0.0, 0.0, 12.0), fan=(-30.0, 30.0), step=1.5, rate=100.0, max_range=80.0,
             noise=(0.0, 0.0), dropout=0.0) -> Scanner:
    """A scanner fixed in the world at `position`, its frame the world's (angles in deg)."""
    mount = Mount(position=np.array(position, dtype=float), rotation=np.eye(3), joints=0,
                  anchor=np.zeros((3, 3)), axis=np.eye(3))
    return Scanner("scanner_test", 0, (fan[0] * DEG, fan[1] * DEG), step * DEG, rate, max_range, noise, dropout,
                   mount)


def _ramp(slope: float, base: float, spacing: float = 0.5, half: float = 30.0) -> Surface:
    """A plane z = base + slope x (m) over a square grid: flat for slope 0, a wedge else."""
    x = np.arange(-half, half + spacing / 2, spacing)
    return Surface(x, x.copy(), np.broadcast_to(base + slope * x[None, :], (len(x), len(x))).copy())


def _scan_once(scanner: Scanner, surface: Surface, seeds=(1,), period: float = 0.01) -> Scanning:
    scanning = Scanning([scanner], surface, list(seeds), period)
    heights = np.repeat(surface.z[None], len(seeds), axis=0)
    assert scanning.step(0, np.zeros((len(seeds), 3)), heights, None)
    return scanning


def test_a_scan_of_a_flat_pile_hits_where_the_geometry_says():
    """A scanner 12 m above a flat pile 2 m high: the ray at angle a meets it 10 m / cos a away,
    10 tan a m along x; beyond its 11 m range a ray is a miss."""
    scanner = _scanner(max_range=11.0)
    scanning = _scan_once(scanner, _ramp(0.0, 2.0))
    record = scanning.record(0)
    angles = scanner.angles
    reach = 10.0 / np.cos(angles) <= 11.0
    expected = np.column_stack([10.0 * np.tan(angles), np.zeros(len(angles)), np.full(len(angles), 2.0)])
    np.testing.assert_allclose(record.hits[0][reach], expected[reach], rtol=0, atol=1e-5)  # float32 hits
    assert np.isnan(record.hits[0][~reach]).all() and (~reach).sum() == 8  # |a| > 24.6 deg
    np.testing.assert_array_equal(record.origin[0], [0.0, 0.0, 12.0])
    assert scanning.metrics(0, _ramp(0.0, 2.0).z, 2400.0)["hit_share"] == pytest.approx(reach.mean())


def test_a_scan_of_a_wedge_hits_where_the_geometry_says():
    """A plane rising 0.3 m per m along x, 5 m high under a scanner 20 m up: the ray at angle a
    meets it 15 / (cos a + 0.3 sin a) m away."""
    scanner = _scanner(position=(0.0, 0.0, 20.0))
    record = _scan_once(scanner, _ramp(0.3, 5.0)).record(0)
    angles = scanner.angles
    distance = 15.0 / (np.cos(angles) + 0.3 * np.sin(angles))
    expected = np.column_stack([distance * np.sin(angles), np.zeros(len(angles)), 20.0 - distance * np.cos(angles)])
    np.testing.assert_allclose(record.hits[0], expected, rtol=0, atol=1e-5)


def test_noise_and_dropouts_are_what_the_numbers_say_and_the_seed_alone_decides_them():
    constant, share, dropout = 0.01, 0.002, 0.2
    scanner = _scanner(noise=(constant, share), dropout=dropout)
    surface = _ramp(0.0, 2.0)
    scans = 2000
    scanning = Scanning([scanner], surface, [11], 0.01)
    heights = surface.z[None].copy()
    for k in range(scans):
        scanning.step(k, np.zeros((1, 3)), heights, None)
    record = scanning.record(0)
    assert len(record.t) == scans
    hits = record.hits.astype(float)
    dropped = np.isnan(hits[..., 0])
    true_range = 10.0 / np.cos(scanner.angles)
    measured = np.linalg.norm(hits - record.origin[:, None, :], axis=-1)
    z_score = ((measured - true_range) / (constant + share * true_range))[~dropped]
    n = z_score.size
    assert abs(dropped.mean() - dropout) < 4 * np.sqrt(dropout * (1 - dropout) / dropped.size)
    assert abs(z_score.mean()) < 4 / np.sqrt(n)
    assert abs(z_score.std() - 1.0) < 4 / np.sqrt(2 * n)
    metrics = scanning.metrics(0, heights[0], 2400.0)
    assert metrics["dropped_share"] == pytest.approx(dropped.mean())
    # The same seed gives the same scans, alone and among other runs of a lockstep.
    together = Scanning([scanner], surface, [3, 11, 5], 0.01)
    stacked = np.repeat(heights, 3, axis=0)
    for k in range(scans):
        together.step(k, np.zeros((3, 3)), stacked, None)
    np.testing.assert_array_equal(together.record(1).hits, record.hits)
    assert not np.array_equal(together.record(0).hits, record.hits, equal_nan=True)


def test_a_scanner_scans_at_its_rate_on_the_control_period_grid():
    """30 Hz on a 0.01 s control period: scan n at the first period at or after n / 30 s."""
    scanning = Scanning([_scanner(rate=30.0)], _ramp(0.0, 2.0), [1], 0.01)
    heights = _ramp(0.0, 2.0).z[None].copy()
    made = [k for k in range(301) if scanning.step(k, np.zeros((1, 3)), heights, None)]
    expected = [math.ceil(n / 30 / 0.01 - 1e-9) for n in range(91)]
    assert made == expected
    np.testing.assert_allclose(scanning.record(0).t, np.array(expected) * 0.01)


# -- the pile known from its scans ----------------------------------------------------------------

def test_the_scanned_pile_takes_a_period_s_mean_and_then_the_latest():
    surface = _ramp(0.0, 0.0, spacing=1.0, half=2.0)  # grid points at -2 .. 2 m
    survey = Survey(surface, 1, 4)
    nan = np.nan
    survey.add(1.0, np.array([[[0.1, 0.2, 3.0], [-0.3, 0.4, 5.0], [2.2, -1.9, 7.0], [nan, nan, nan]]],
                             dtype=np.float32), np.array([0]))
    centre, corner = (2, 2), (0, 4)  # (iy, ix) of (0, 0) and (2, -2) m
    assert survey.z[0][centre] == pytest.approx(4.0) and survey.seen[0][centre] == 2
    assert survey.z[0][corner] == pytest.approx(7.0) and survey.last_seen[0][corner] == 1.0
    survey.add(2.0, np.array([[[0.0, 0.0, 6.0]] + [[nan] * 3] * 3], dtype=np.float32), np.array([0]))
    assert survey.z[0][centre] == 6.0 and survey.seen[0][centre] == 3 and survey.last_seen[0][centre] == 2.0
    unseen = survey.seen[0] == 0
    assert unseen.sum() == 23 and np.isnan(survey.z[0][unseen]).all() and np.isnan(survey.last_seen[0][unseen]).all()
    truth = np.full((5, 5), 5.0)
    tonnes = tonnes_against(survey.z[0], truth, 1.0, 2000.0)
    assert tonnes["scanned_t"] == pytest.approx((6.0 + 7.0) * 2.0)
    assert tonnes["true_t"] == pytest.approx(2 * 5.0 * 2.0) and tonnes["pile_t"] == pytest.approx(25 * 5.0 * 2.0)
    assert tonnes["footprint_seen_share"] == pytest.approx(2 / 25)


def _small_windrow_travel() -> Scene:
    """heavy_dig_pile's machine, boom square to the rail and level, travelling 60 m in 240 s past a
    small windrow 4 m high, its wheel (9 m at its lowest) clear of it: the boom's scanner sweeps
    its fan across the windrow."""
    machine = Machine(HEAVY_MJCF)
    start, end = (machine.fk(np.array([travel, 90 * DEG, 0.0])) for travel in (-10.0, 50.0))
    return load_scene(SCENES / "heavy_dig_pile.toml", {
        "path.via_points": [{"t": 0.0, "p": start.tolist()}, {"t": 240.0, "p": end.tolist()}],
        "stockpile.windrow": {"length": 20.0, "crest_width": 2.0, "height": 4.0, "angle_of_repose": 37.0,
                              "centre": [20.0, 57.0]},
        "stockpile.grid_spacing": 0.5,  # the fan's 0.5 deg rays land at most 0.42 m apart on the far flank
    })


def test_the_scanned_pile_converges_to_the_truth_as_the_machine_travels_past_it(tmp_path):
    scene = _small_windrow_travel()
    loop = Lockstep([scene], nthread=1)
    controller = controller_class(scene.controller.type)(loop.controller_context(), [scene.controller.settings])
    survey, density = loop.scanning.survey, scene.stockpile.bulk_density
    truth = loop.reclaim.cutter.heights[0]
    samples = []
    while not loop.done:
        q, qd = loop.measure()
        loop.advance(controller.compute(q, qd, *loop.reference_now(), loop.alive))
        if loop.k % 2000 == 0:  # every 20 s
            samples.append((float(loop.q_true[0, 0]), survey.tonnes(0, truth, density), survey.z[0].copy()))
    assert loop.reclaim.conveyor.dug[0] == 0.0  # the wheel stayed clear: the truth is the windrow as built
    seen = [s["footprint_seen_share"] for _, s, _ in samples]
    assert seen[0] == 0.0 and seen[-1] == 1.0 and all(b >= a for a, b in itertools.pairwise(seen))
    # The tonnes it knows rise to the whole pile's (1,864 t); over what it has seen they stay near
    # the truth: the latest scan of a cell on the windrow's rising end is at the cell's far edge,
    # 0.19 m above its centre, a bias the falling end takes back (docs/sensing.md).
    final = samples[-1][1]
    assert final["scanned_t"] == pytest.approx(final["pile_t"], rel=0.005)  # 0.07 % measured
    assert all(abs(s["error_share"]) < 0.03 for _, s, _ in samples if s["footprint_seen_share"] > 0.4)
    # Cells ahead of the scanner's plane (2.6 m behind the CP along the rail) are unknown, NaN.
    surface = loop.reclaim.surface
    passing = [(travel, known) for travel, s, known in samples if 0 < s["footprint_seen_share"] < 1]
    assert len(passing) == 4
    for travel, known in passing:
        ahead = surface.x > travel - 2.6 + 2.0
        assert ahead.any() and np.isnan(known[:, ahead]).all() and not np.isnan(known).all()
    result = loop.results()[0]
    metrics = result.metrics["scan"]
    assert metrics["scans"] == len(result.scan.t) == math.floor(loop.duration * 25 + 1e-9) + 1
    assert metrics["first_cut"] is None and metrics["footprint_seen_share"] == seen[-1]
    write_run(result, tmp_path / "run", plots=False)
    with np.load(tmp_path / "run" / "scans.npz") as scans, np.load(tmp_path / "run" / "survey.npz") as known:
        assert set(scans) == {"t", "origin", "hits"} and scans["hits"].shape == (metrics["scans"], 191, 3)
        assert scans["hits"].dtype == np.float32
        assert np.isnan(scans["hits"][..., 0]).mean() == pytest.approx(1 - metrics["hit_share"])
        assert set(known) == {"x", "y", "z", "seen", "last_seen", "t_end"}
        never = known["seen"] == 0
        np.testing.assert_array_equal(np.isnan(known["z"]), never)
        np.testing.assert_array_equal(np.isnan(known["last_seen"]), never)
        np.testing.assert_array_equal(known["z"], result.scan.z)


def test_a_lockstep_s_runs_scan_as_they_would_alone():
    scenes = [load_scene(SCENES / "heavy_dig_pile.toml", {"path.via_points": _short_cut(), "simulation.seed": seed})
              for seed in (1, 2)]
    together = simulate_lockstep(scenes)
    alone = simulate(scenes[1])
    np.testing.assert_array_equal(together[1].scan.hits, alone.scan.hits)
    np.testing.assert_array_equal(together[1].scan.z, alone.scan.z)
    assert together[1].metrics["scan"] == alone.metrics["scan"]
    first = alone.metrics["scan"]["first_cut"]  # it digs: the scanned pile as the wheel first cut
    assert 0 < first["time_s"] < 30 and abs(first["error_share"]) < 0.02


def _short_cut() -> list[dict]:
    """heavy_dig_pile's cut, shortened: from beside the windrow's flank into it, for 30 s."""
    return [{"t": 0.0, "p": [50.899, 29.387, 18.985]}, {"t": 30.0, "p": [48.323, 33.814, 18.985]}]


# -- the scene's [sensing] and the budget ---------------------------------------------------------

def test_a_scene_turns_the_scanners_off_or_asks_for_them_only_where_they_can_be():
    base = SCENES / "heavy_dig_pile.toml"
    off = load_scene(base, {"path.via_points": _short_cut(), "sensing.scanners": False})
    assert lockstep_key(off) != lockstep_key(load_scene(base, {"path.via_points": _short_cut()}))
    result = simulate(off)
    assert result.scan is None and "scan" not in result.metrics
    with pytest.raises(SceneError, match=r"paper_individual_gains.toml: 'sensing.scanners' is true, but the scene "
                                         r"has no \[stockpile\] to scan"):
        load_scene(SCENES / "paper_individual_gains.toml", {"sensing.scanners": True})
    with pytest.raises(SceneError, match=r"heavy_dig_pile.toml: 'sensing.scanners' must be true or false, got 'on'"):
        load_scene(base, {"sensing.scanners": "on"})
    asked = load_scene(base, {"sensing.scanners": True})
    assert [s.name for s in active_scanners(asked, Machine(HEAVY_MJCF))] == ["scanner_boom"]
    with pytest.raises(SceneError, match=r"heavy_dig_pile.toml: 'sensing.scanners' is true, but .*bwr.xml has no "
                                         r"scanner site"):
        active_scanners(asked, Machine(PAPER_MJCF))
    assert active_scanners(load_scene(SCENES / "paper_individual_gains.toml"), Machine(HEAVY_MJCF)) == ()


def test_the_budget_counts_the_scans_and_the_scanned_pile(monkeypatch, tmp_path):
    scene = load_scene(SCENES / "heavy_dig_pile.toml")
    on, off = estimate([scene]), estimate([load_scene(SCENES / "heavy_dig_pile.toml", {"sensing.scanners": False})])
    duration = scene.trajectory.via_points[-1].t
    scans = duration * 25 + 1
    cells = build_surface(scene.stockpile, scene.path).z.size
    expected = scans * (191 * HIT_BYTES + SCAN_BYTES) + cells * SURVEY_CELL_BYTES
    assert on.disk_bytes - off.disk_bytes == pytest.approx(expected)
    assert on.memory_bytes - off.memory_bytes == pytest.approx(expected)
    assert on.seconds > off.seconds
    # A disk with room for the run without its scans, not with them: refused before it starts.
    free = (off.disk_bytes + on.disk_bytes) / 2 / budget.MAX_DISK_SHARE
    monkeypatch.setattr(budget.shutil, "disk_usage", lambda path: types.SimpleNamespace(free=free))
    budget.check_estimate(off, where=scene.path, out_dir=tmp_path, force=False)
    with pytest.raises(BwrError, match=r"heavy_dig_pile.toml: would take more than the .* free on disk"):
        budget.check_estimate(on, where=scene.path, out_dir=tmp_path, force=False)
