"""Hostile files: a pile, survey or run file is checked before anything believes it (docs/reliability.md,
classes 16-18).

Every array read from a file goes through one loader (bwr_twin/arrays.py), which checks each
member's header (keys, dtype, shape, bytes) before its data; what the arrays mean (counts against
the arrays they index, physical ranges) is checked before any kernel sees them. Each case here is
refused with one line naming the file and the key or limit: through `python -m bwr_twin.run
--pile` (status 2, nothing written) where that is cheap, through the readers otherwise.
"""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, SCENES

from bwr_twin.arrays import Member, load_npz, read_lines
from bwr_twin.config.sections import StockpileSection
from bwr_twin.errors import BwrError, SceneError
from bwr_twin.pile.stacked_file import stacked_arrays
from bwr_twin.pile.surface import MAX_SURVEY_POINTS, build_surface
from bwr_twin.results.run_files import COLUMNS, MAX_TIMESERIES_ROWS, read_timeseries
from bwr_twin.stockpile.history import PileHistory
from bwr_twin.stockpile.layers import LayeredPile

ENV = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
# A reclaim of a stacked pile, and a dig of a windrow, given their pile with --pile.
STACKED_SCENE = 'extends = "{}"\n[stockpile]\ngrid_spacing = 0.5\n'.format(SCENES / "heavy_stack_and_reclaim.toml")
SURVEY_SCENE = SCENES / "heavy_dig_pile.toml"


def run_with_pile(tmp_path: Path, pile: Path, stacked: bool = False) -> str:
    """`python -m bwr_twin.run SCENE --pile PILE --out OUT`, which must refuse it: status 2, one
    line, no traceback, no output folder and the folder as it was. Returns the line."""
    scene = SURVEY_SCENE
    if stacked:
        scene = tmp_path / "reclaim.toml"
        scene.write_text(STACKED_SCENE)
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.run", str(scene), "--pile", str(pile),
                           "--out", str(tmp_path / "out"), "--no-plots"], cwd=tmp_path, env=ENV,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in proc.stderr, proc.stderr
    assert not (tmp_path / "out").exists() and sorted(p.name for p in tmp_path.iterdir()) == before
    return lines[0]


def stacked_pile(ny: int = 12, nx: int = 16, room: int = 64) -> dict[str, np.ndarray]:
    """A small stacked pile as a stacking's pile.npz holds it: three layers of grade on a ridge."""
    x, y = np.arange(nx) * 0.5, 20.0 + np.arange(ny) * 0.5
    pile = LayeredPile(x, y, room)
    ridge = np.clip(2.0 - np.abs(y - y.mean())[:, None] * 0.5 + 0 * x, 0.0, None)
    for grade in (61.0, 62.5, 60.5):
        pile.deposit(ridge / 3, grade)
    return dict(x=x, y=y, z_start=np.zeros_like(pile.z), z_end=pile.z.copy(), layer_thickness=pile.thickness,
                layer_grade=pile.grade, layer_count=pile.count, deposit_grade=np.array([61.0, 62.5, 60.5]),
                deposit_tonnes=np.array([100.0, 100.0, 100.0]), bulk_density=np.array(2400.0),
                grade_name=np.array("Fe %"), layers=np.array(3), equivalent_layers=np.array(3.0),
                pattern=np.array("chevron"), grade_band=np.array([60.0, 63.0]))


def survey(nx: int = 41, ny: int = 41) -> dict[str, np.ndarray]:
    """A surveyed cone 10 m high beside the heavy machine's rail, 0.5 m a grid line."""
    x, y = 40.0 + np.arange(nx) * 0.5, 30.0 + np.arange(ny) * 0.5
    r = np.hypot(x[None, :] - x.mean(), y[:, None] - y.mean())
    return dict(x=x, y=y, z=np.clip(10.0 - r, 0.0, None))


def saved(path: Path, **arrays) -> Path:
    np.savez_compressed(path, **arrays)
    return path


def npz_claiming(path: Path, key: str, shape: tuple[int, ...], dtype: str = "<f8") -> Path:
    """An .npz whose member `key` declares an array of `shape` in its header and holds no data."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": dtype, "fortran_order": False, "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(f"{key}.npy", header.getvalue())  # the magic string and the header alone
    return path


# --- 1. files that could corrupt memory: counts checked against the arrays they index ------------


def test_a_valid_stacked_pile_is_read_as_it_was_written(tmp_path):
    arrays = stacked_pile()
    read = stacked_arrays(saved(tmp_path / "pile.npz", **arrays), "pile")
    for key, value in read.items():
        assert value.dtype == arrays[key].dtype and np.array_equal(value, arrays[key]), key


@pytest.mark.parametrize("count, message", [
    (200, r"array 'layer_count' holds 200 at \[5, 7\], outside \[0, 64\] \(a column holds 0 to the 64 layers"),
    (65, r"array 'layer_count' holds 65 at \[5, 7\], outside \[0, 64\]"),
    (-1, r"array 'layer_count' holds -1 at \[5, 7\], outside \[0, 64\]"),
    (5, r"array 'layer_thickness' holds 0 at \[5, 7, 3\] with 'layer_count' 5 there; it must be > 0 m"),
], ids=["far-beyond", "one-beyond", "negative", "beyond-its-layers"])
def test_a_layer_count_beyond_the_layers_is_refused_not_a_crash(tmp_path, count, message):
    """A count the layer kernels would index beyond their arrays with (glibc aborted, or a
    ZeroDivisionError at 65) is refused as the pile is read, before the run starts."""
    arrays = stacked_pile()
    arrays["layer_count"][5, 7] = count
    line = run_with_pile(tmp_path, saved(tmp_path / "pile.npz", **arrays), stacked=True)
    assert "pile.npz" in line and "'stockpile.surface_file'" in line
    assert re.search(message, line), line


@pytest.mark.parametrize("edit, message", [
    (lambda a: a.update(layer_grade=a["layer_grade"][:, :, :32]),
     r"arrays 'layer_thickness' \(12, 16, 64\) and 'layer_grade' \(12, 16, 32\) must both be"),
    (lambda a: a.update(layer_count=a["layer_count"][:, :8]), r"array 'layer_count' has the shape \(12, 8\); the grid"),
    (lambda a: a.update(layer_count=a["layer_count"].astype(float)), r"array 'layer_count' holds real numbers "
     r"\(float64\); it must hold whole numbers"),
    (lambda a: a.pop("layer_count"), r"has no array 'layer_count'"),
], ids=["layers-of-two-shapes", "counts-of-another-grid", "counts-not-whole", "no-counts"])
def test_layers_of_another_shape_than_the_grid_are_refused(tmp_path, edit, message):
    arrays = stacked_pile()
    edit(arrays)
    with pytest.raises(SceneError, match=r"pile.npz: " + message):
        stacked_arrays(saved(tmp_path / "pile.npz", **arrays), f"{tmp_path / 'pile.npz'}")


def test_a_run_history_whose_frames_index_beyond_the_grid_is_refused(tmp_path):
    """The replay's pile.npz: frames that slice past their cells, or cells off the grid."""
    grid = survey(4, 3)
    arrays = dict(x=grid["x"], y=grid["y"], z_start=grid["z"], z_end=grid["z"], frame_time=np.array([1.0, 2.0]),
                  frame_offsets=np.array([0, 2, 3]), frame_cells=np.array([0, 5, 11], np.int32),
                  frame_heights=np.ones(3, np.float32))
    assert PileHistory.read(saved(tmp_path / "pile.npz", **arrays), 2.0).cells.tolist() == [0, 5, 11]
    for key, value, message in [
        ("frame_cells", np.array([0, 5, 12], np.int32), r"array 'frame_cells' holds 12 at \[2\], outside \[0, 11\]"),
        ("frame_offsets", np.array([0, 2, 9]), r"array 'frame_cells' holds 3 values, and 'frame_offsets' ends at 9"),
        ("frame_offsets", np.array([0, 3, 2]), r"array 'frame_offsets' must rise from 0"),
        ("z_end", np.ones((4, 3)), r"array 'z_end' has the shape \(4, 3\); the grid lines x, y make it \(3, 4\)"),
    ]:
        with pytest.raises(BwrError, match=r"pile.npz: " + message):
            PileHistory.read(saved(tmp_path / "pile.npz", **{**arrays, key: value}), 2.0)


# --- 2. files that could take the memory before they are checked --------------------------------


def test_a_tiny_npz_claiming_a_huge_array_is_refused_by_its_header(tmp_path):
    """A few hundred bytes claiming 8e12 bytes: refused from the header, nothing allocated (the
    member holds no data behind its header: reading it would fail otherwise)."""
    bomb = npz_claiming(tmp_path / "bomb.npz", "z", (1_000_000, 1_000_000))
    assert bomb.stat().st_size < 1000
    with pytest.raises(BwrError, match=r"bomb.npz: array 'z' of shape \(1000000, 1000000\) \(float64\) would take "
                                       r"8,000,000,000,000 bytes, more than the 1,073,741,824 it may take"):
        load_npz(bomb, {"z": Member()}, what=str(bomb))
    grid = survey()
    with zipfile.ZipFile(bomb, "a") as archive:
        for key in "xy":
            archive.writestr(f"{key}.npy", _npy(grid[key]))
    line = run_with_pile(tmp_path, bomb)
    assert re.search(r"bomb.npz: array 'z' of shape \(1000000, 1000000\) \(float64\) would take 8,000,000,000,000 "
                     r"bytes, more than the 160,000,000 it may take", line), line


def _npy(array: np.ndarray) -> bytes:
    out = io.BytesIO()
    np.save(out, array)
    return out.getvalue()


@pytest.mark.parametrize("damage, message", [
    (lambda data: data[: len(data) // 2], r"not an \.npz file, or a damaged or truncated one"),
    (lambda data: b"", r"not an \.npz file, or a damaged or truncated one"),
    (lambda data: np.random.default_rng(7).bytes(4096), r"not an \.npz file, or a damaged or truncated one"),
], ids=["truncated", "empty", "random-bytes"])
def test_a_damaged_npz_is_one_line_naming_the_file(tmp_path, damage, message):
    data = saved(tmp_path / "good.npz", **survey()).read_bytes()
    (tmp_path / "bad.npz").write_bytes(damage(data))
    line = run_with_pile(tmp_path, tmp_path / "bad.npz")
    assert re.search(r"'stockpile.surface_file' \S*bad.npz: " + message, line), line
    assert "pickle" not in line and "unsafe" not in line


def test_a_member_cut_short_inside_a_whole_archive_is_refused(tmp_path):
    """A zip that is whole but whose array holds fewer bytes than its header says."""
    grid = survey()
    with zipfile.ZipFile(tmp_path / "short.npz", "w") as archive:
        for key in "xy":
            archive.writestr(f"{key}.npy", _npy(grid[key]))
        archive.writestr("z.npy", _npy(grid["z"])[:-800])
    with pytest.raises(BwrError, match=r"short.npz: array 'z' holds 12,648 of its 13,448 bytes \(a truncated"):
        load_npz(tmp_path / "short.npz", {"z": Member()}, what=str(tmp_path / "short.npz"))


def test_an_object_array_is_refused_as_such(tmp_path):
    grid = survey()
    np.savez(tmp_path / "objects.npz", x=grid["x"], y=grid["y"], z=np.array([{"a": 1}, None], dtype=object))
    line = run_with_pile(tmp_path, tmp_path / "objects.npz")
    assert re.search(r"objects.npz: array 'z' holds Python objects \(object\), which are never read from a file; "
                     r"it must hold real numbers or whole numbers", line), line
    assert "pickle" not in line


def test_a_survey_past_the_row_cap_is_refused_while_it_is_read(tmp_path):
    """MAX_SURVEY_POINTS points and a header are read; one more line is refused, naming the cap,
    before a number is parsed: the malformed row beyond the cap is never reached."""
    rows = MAX_SURVEY_POINTS + 2
    (tmp_path / "cloud.csv").write_bytes(b"x,y,z\n" + b"1,2,3\n" * (rows - 1) + b"not,a,row\n")
    with pytest.raises(SceneError, match=r"cloud.csv: more than 1,000,001 lines, the most it may hold: a survey of at "
                                         r"most 1,000,000 points and a header \(thin the cloud\)"):
        build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, surface_file=tmp_path / "cloud.csv"), tmp_path)


def test_a_time_series_past_the_row_cap_is_refused(tmp_path, monkeypatch):
    """The cap (MAX_TIMESERIES_ROWS, 5,000,000 rows) would take a 2 GB file to reach; the reader
    is the same with a smaller cap."""
    import bwr_twin.results.run_files as run_files

    assert MAX_TIMESERIES_ROWS == 5_000_000
    monkeypatch.setattr(run_files, "MAX_TIMESERIES_ROWS", 10)
    header, row = ",".join(COLUMNS) + "\n", ",0" * (len(COLUMNS) - 1) + "\n"
    (tmp_path / "timeseries.csv").write_text(header + "".join(f"{i}{row}" for i in range(11)))
    with pytest.raises(BwrError, match=r"timeseries.csv: more than 11 lines, the most it may hold: a time series of "
                                       r"at most 10 rows and a header"):
        read_timeseries(tmp_path / "timeseries.csv")
    (tmp_path / "timeseries.csv").write_text(header + "".join(f"{i}{row}" for i in range(10)))
    assert len(read_timeseries(tmp_path / "timeseries.csv").time) == 10


def test_a_text_file_past_its_bytes_is_refused_without_reading_it_whole(tmp_path):
    (tmp_path / "long.csv").write_bytes(b"1" * (3 << 20))
    with pytest.raises(BwrError, match=r"long.csv: more than 2,097,152 bytes, the most it may hold"):
        read_lines(tmp_path / "long.csv", what=str(tmp_path / "long.csv"), max_rows=10, max_bytes=2 << 20)


# --- 3. pile physics that cannot be --------------------------------------------------------------


@pytest.mark.parametrize("edit, message", [
    (lambda z: np.where(z > 0, 1e9, z), r"array 'z' holds 1e\+09 at \[\d+, \d+\], outside \[-5, 100\] \(metres above "
                                        r"the yard floor: open stockpiles stand at most some 30 m\)"),
    (lambda z: z * 1e6, r"array 'z' holds 37570.6 at \[1, 14\], outside \[-5, 100\]"),  # its foot
    (lambda z: z - 50.0, r"array 'z' holds -50 at \[0, 0\], outside \[-5, 100\]"),
    (lambda z: z + 1j, r"array 'z' holds complex numbers \(complex128\); it must hold real numbers or whole numbers"),
], ids=["a-billion-metres", "millimetres-for-metres", "below-the-floor", "complex"])
def test_survey_heights_that_cannot_be_are_refused(tmp_path, edit, message):
    grid = survey()
    line = run_with_pile(tmp_path, saved(tmp_path / "survey.npz", x=grid["x"], y=grid["y"], z=edit(grid["z"])))
    assert re.search(r"'stockpile.surface_file' \S*survey.npz: " + message, line), line


def test_a_point_survey_with_a_height_that_cannot_be_is_refused_naming_the_row(tmp_path):
    (tmp_path / "points.csv").write_text("x,y,z\n0,0,1\n1,0,2\n0,1,1e9\n")
    with pytest.raises(SceneError, match=r"points.csv: data row 3: z 1e\+09 m lies outside \[-5, 100\] \(metres above"):
        build_surface(StockpileSection(bulk_density=2400.0, grid_spacing=0.5, surface_file=tmp_path / "points.csv"), tmp_path)


def _negative_thickness(a):
    a["layer_thickness"][5, 7, 0] *= -1


def _nan_grade(a):
    a["layer_grade"][5, 7, 1] = np.nan


@pytest.mark.parametrize("edit, message", [
    (_negative_thickness, r"array 'layer_thickness' holds -0.\d+ at \[5, 7, 0\] with 'layer_count' 3 there; it must "
                          r"be > 0 m in each of a column's 'layer_count' layers"),
    (_nan_grade, r"array 'layer_grade' holds nan at \[5, 7, 1\], not a finite number"),
    (lambda a: a.update(z_end=a["z_end"] * 3), r"array 'z_end' holds [\d.]+ m at \[\d+, \d+\], but the layers there "
                                                r"sum to [\d.]+ m: a column's height is its layers' thickness"),
    (lambda a: a.update(bulk_density=np.array(2.4)), r"array 'bulk_density' holds 2.4 at \[\], outside \[150, 5000\]"),
    (lambda a: a.update(deposit_tonnes=-a["deposit_tonnes"]), r"array 'deposit_tonnes' holds -100 at \[0\]"),
], ids=["negative-thickness", "nan-grade", "heights-x3", "density-in-t-per-m3", "negative-tonnes"])
def test_stacked_layers_that_contradict_the_heights_are_refused(tmp_path, edit, message):
    arrays = stacked_pile()
    edit(arrays)
    line = run_with_pile(tmp_path, saved(tmp_path / "pile.npz", **arrays), stacked=True)
    assert re.search(r"'stockpile.surface_file' \S*pile.npz: " + message, line), line

