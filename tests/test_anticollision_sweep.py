"""The interlock at scale: a few hundred random two-machine scenarios on the batch engine, the
same ones with and without the built-in interlock (tools/anticollision_sweep.py runs 10,000)."""

from __future__ import annotations

import csv

import pytest

from bwr_twin.batch.cli import main as batch
from bwr_twin.batch.report import SUMMARY_FILE
from bwr_twin.collision.scenarios import Draws, write_sweeps
from bwr_twin.config.sweep import load_sweep

SCHEDULES = 12  # x 3 paths x 2 report delays x 2 fault classes: 144 scenarios a side
DRAWS = Draws.shipped()


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory):
    """Each side's summary rows by run, and the stop zone."""
    folder = tmp_path_factory.mktemp("anticollision")
    paths = write_sweeps(folder, SCHEDULES, seed=7)
    rows = []
    for path in paths:
        assert batch([str(path), "--out", str(folder / path.stem), "--workers", "2"]) == 0
        with open(folder / path.stem / SUMMARY_FILE, newline="") as f:
            rows.append({row["run"]: row for row in csv.DictReader(f)})
    stop = load_sweep(paths[1]).runs[0].scene.interlock.stop
    return rows[0], rows[1], stop, paths


def test_the_same_seed_draws_the_same_scenarios(sweeps, tmp_path):
    *_, paths = sweeps
    again = write_sweeps(tmp_path, SCHEDULES, seed=7)
    assert [p.read_text() for p in again] == [p.read_text() for p in paths]
    assert len(load_sweep(again[0]).runs) == SCHEDULES * len(DRAWS.paths) * len(DRAWS.report_delays) * len(DRAWS.faults)


def test_without_the_interlock_the_scenarios_collide_and_are_counted(sweeps):
    without, _, _, _ = sweeps
    collided = [row for row in without.values() if int(row["collision.contacts"]) > 0]
    assert len(collided) >= 10
    assert all(float(row["collision.neighbour_clearance_min_m"]) <= 0.0 for row in collided)


def test_with_the_interlock_no_scenario_collides(sweeps):
    """With true encoders or the machine's slew encoder stuck, late reports or not, no scenario
    collides and none comes within the stop zone: a stuck encoder parts from its drive's speed,
    and the interlock quick-stops the drives (docs/anticollision.md)."""
    without, with_, stop, _ = sweeps
    assert all(row["status"] == "ok" for row in with_.values())
    assert all(int(row["collision.contacts"]) == 0 for row in with_.values())
    assert min(float(row["collision.neighbour_clearance_min_m"]) for row in with_.values()) >= stop
    for faults in ("[]", DRAWS.faults[1]):  # the interlock stopped scenarios that collide without it, of each class
        saved = [run for run, row in without.items()
                 if (row["faults"] == "[]") == (faults == "[]") and int(row["collision.contacts"]) > 0]
        assert saved
