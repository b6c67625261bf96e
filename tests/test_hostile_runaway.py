"""Runaway work and plug-ins that would end or hang the twin (docs/reliability.md, classes 19 and 20).

`RUNAWAYS` (class 19): every entry point refuses, within about two seconds of its start, a scene
whose plan, faults, rings, grids or duration over timestep would run away, with exit status 2 and
one line naming the key and the estimate, and nothing written. `PLUGINS` (class 20): a plug-in
that calls sys.exit or os._exit at import or in a call, sleeps in compute() beyond the budget of
a call, or reports what JSON cannot hold, gets the same answer, naming its file and the call.
"""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest
from conftest import write_short_scene
from test_hostile import assert_refused, cli, edited, snapshot

from bwr_twin.shipped import MJCF, SCENES



def _shipped(tmp: Path, name: str, edit=None, file: str = "scene.toml") -> Path:
    """tmp/file: the shipped scene `name`, its own keys edited, extending what it extends."""
    text = (SCENES / f"{name}.toml").read_text().replace('"../mjcf/', f'"{MJCF}/')
    text = edit(text) if edit else text
    (tmp / file).write_text(text)
    return tmp / file


def _with(tmp: Path, table: str) -> Path:
    """The short scene with `table` appended."""
    write_short_scene(tmp, edit=lambda text: text + "\n" + table)
    return tmp / "short.toml"


_FAULT = '\n[[faults]]\nkind = "encoder_dropout"\naxis = "slew"\nstart = {start}.0\nduration = 1.0\n'
_NANOSECOND = edited(**{"timestep = 0.002 ": "timestep = 1e-9 "})
_LATE = '[[faults]]\nkind = "late_inputs"\nperiods = 1000000000\nstart = 1.0\n'


def _faults(count: int):
    return lambda text: text + "".join(_FAULT.format(start=i % 19) for i in range(count))


def _short(tmp: Path, edit=None) -> Path:
    write_short_scene(tmp, edit=edit)
    return tmp / "short.toml"


def _tuning(tmp: Path, scene: Path) -> Path:
    (tmp / "tune.toml").write_text(
        f'scene = "{scene.name}"\n'
        '[parameters]\n"controller.kp.travel" = { low = 1e3, high = 1e6 }\n'
        '"controller.kd.travel" = { low = 1e3, high = 1e6 }\n'
        '[seeds]\ntraining = [1]\nheld_out = [2]\n[objective]\nposition_error_max = 1.0\n[budget]\nevaluations = 4\n')
    return tmp / "tune.toml"


def _pid_short(tmp: Path, edit=None) -> Path:
    """The short path under pid_paper's controller, for tuning its gains."""
    pid = (SCENES / "pid_paper.toml").read_text()
    controller = pid[pid.index("[controller]"):]
    write_short_scene(tmp, edit=lambda text: (edit or (lambda t: t))(text[:text.index("[controller]")] + controller))
    return tmp / "short.toml"


# (id, command, arguments(tmp) -> list, pattern of the one error line)
RUNAWAYS = [
    ("fmu-nanosecond-timestep", "export", lambda t: ["fmu", _short(t, _NANOSECOND), "--out", t / "a.fmu"],
     r"short.toml: would take more than 12 h: .*most of it 'simulation.timestep' gives [\d.e+]+ physics steps"),
    ("serve-nanosecond-timestep", "serve", lambda t: [_short(t, _NANOSECOND), "--endpoint",
                                                      f"opc.tcp://127.0.0.1:{_free_port()}"],
     r"short.toml: would take more than 12 h: .*'simulation.timestep'"),
    ("serve-nodeset-nanosecond-timestep", "serve", lambda t: [_short(t, _NANOSECOND), "--nodeset", t / "n.xml"],
     r"short.toml: would take more than 12 h: .*'simulation.timestep'"),
    ("plc-grid-1201", "export", lambda t: ["plc", "paper_individual_gains", "--grid", "1201", "--out", t / "plc"],
     r"--grid 1201: 2.88e\+06 points of the control surface, beyond the limit of 250,000 points: about \d+ min, "
     r".* GB of memory .*; the largest --grid within it is 349"),
    ("plc-grid-12001", "export", lambda t: ["plc", "paper_individual_gains", "--grid", "12001", "--out", t / "plc"],
     r"--grid 12001: 2.88e\+08 points of the control surface, beyond the limit .*about [\d.]+ h, [\d.]+ (GB|TB) of memory"),
    ("stacking-grid-of-five-millimetres", "run", lambda t: [_shipped(t, "heavy_chevron_stack", edited(
        **{"grid_spacing = 0.5 ": "grid_spacing = 0.005 "})), "--out", t / "o"],
     r"scene.toml: would take more than 12 h and more than 50% of the .* of memory.*: .*most of it "
     r"'stacking.grid_spacing' gives [\d,]+ cells of the stacked pile, [\d.,]+ (h|days) a run"),
    ("stacking-grid-of-two-centimetres", "run", lambda t: [_shipped(t, "heavy_chevron_stack", edited(
        **{"grid_spacing = 0.5 ": "grid_spacing = 0.02 "})), "--out", t / "o"],
     r"scene.toml: would take more than 12 h: .*most of it 'stacking.grid_spacing' gives 8,494,087 cells"),
    ("hundred-thousand-faults", "run", lambda t: [_short(t, _faults(100_000)), "--out", t / "o"],
     r"short.toml: 'faults' holds 100,000 \[\[faults\]\] tables, more than the 10,000 a scene may hold"),
    ("two-thousand-faults", "run", lambda t: [_short(t, _faults(2_000)), "--out", t / "o"],
     r"short.toml: 'faults' gives 2,000 \[\[faults\]\] tables, more than 1,000 a run takes without --force: about"),
    ("millimetre-cut-depth", "run", lambda t: [_shipped(t, "heavy_bench_reclaim", edited(
        **{"cut_depth = 1.0 ": "cut_depth = 0.001 "})), "--out", t / "o"],
     r"scene.toml: 'reclaim.cut_depth' gives 10,000 passes .*, more than 5,000 a run takes without --force: about 17 s"),
    ("a-million-layers", "run", lambda t: [_shipped(t, "heavy_chevron_stack", edited(
        **{"layers = 32 ": "layers = 1000000 "})), "--out", t / "o"],
     r"scene.toml: 'stacking.layers' gives 1,000,000 passes of the chevron pattern, more than 5,000"),
    ("late-inputs-of-a-billion-periods", "run", lambda t: [_with(t, _LATE), "--out", t / "o"],
     r"short.toml: would take more than 50% of the .* of memory: .*most of it 'faults\[0\].periods' gives "
     r"1e\+09 control periods of late readings held, 24 GB of memory a run"),
    ("report-delay-of-a-billion-seconds", "run", lambda t: [_shipped(t, "heavy_two_machines", edited(
        **{"report_delay = 0.5 ": "report_delay = 1e9 "})), "--out", t / "o"],
     r"scene.toml: would take more than 50% .*most of it 'neighbour.report_delay' gives 1e\+11 control periods"),
    ("encoder-window-of-a-billion-seconds", "run", lambda t: [_shipped(t, "heavy_two_machines_interlocked", edited(
        **{"encoder_window = 1.0 ": "encoder_window = 1e9 "})), "--out", t / "o"],
     r"scene.toml: would take more than 50% .*most of it 'interlock.encoder_window' gives 1e\+11 control periods"),
    # every other entry point, on one of them
    ("batch-of-a-million-layers", "batch", lambda t: [_sweep(t, _shipped(t, "heavy_chevron_stack", edited(
        **{"layers = 32 ": "layers = 1000000 "}))), "--out", t / "b"], r"'stacking.layers' gives 1,000,000 passes"),
    ("compare-of-a-millimetre-cut", "compare", lambda t: [_shipped(t, "heavy_bench_reclaim", edited(
        **{"cut_depth = 1.0 ": "cut_depth = 0.001 "})), "--controllers", "pid_heavy", "computed_torque_heavy", "--seeds", "2", "--out", t / "c"],
     r"'reclaim.cut_depth' gives 10,000 passes"),
    ("tune-of-late-inputs", "tune", lambda t: [_tuning(t, _pid_short(t, lambda text: text + "\n" + _LATE)),
                                                "--out", t / "tuned"], r"'faults\[0\].periods' gives 1e\+09"),
    ("replay-of-two-thousand-faults", "replay", lambda t: [_short(t, _faults(2_000)), "--export", t / "a.html"],
     r"'faults' gives 2,000 \[\[faults\]\] tables"),
]


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _sweep(tmp: Path, scene: Path) -> Path:
    (tmp / "sweep.toml").write_text(f'scene = "{scene.name}"\nseeds = [1]\n')
    return tmp / "sweep.toml"


@pytest.mark.parametrize("case", RUNAWAYS, ids=[case[0] for case in RUNAWAYS])
def test_runaway_work_is_refused_at_once_with_the_key_and_the_estimate(tmp_path, case):
    _, command, arguments, pattern = case
    args = arguments(tmp_path)
    before = snapshot(tmp_path)
    proc = cli(command, *args, cwd=tmp_path)
    assert_refused(proc, pattern)  # the estimate's refusal: it is made before the work starts
    assert snapshot(tmp_path) == before  # nothing written


def test_force_passes_a_count_beyond_the_limit(tmp_path):
    """1,001 faults are refused without --force and run with it."""
    scene = _short(tmp_path, _faults(1_001))
    assert_refused(cli("run", scene, "--out", tmp_path / "o", "--no-plots", cwd=tmp_path), "more than 1,000")
    proc = cli("run", scene, "--out", tmp_path / "o", "--no-plots", "--force", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o" / "metrics.json").is_file()


def test_a_gym_environment_refuses_a_runaway_scene(tmp_path):
    gymnasium = pytest.importorskip("gymnasium")
    from bwr_twin.errors import BwrError
    from bwr_twin.gym import ENV_ID

    scene = _with(tmp_path, _LATE)
    with pytest.raises(BwrError, match=r"'faults\[0\].periods' gives 1e\+09 control periods of late readings"):
        gymnasium.make(ENV_ID, scene=str(scene)).reset(seed=1)


# --- plug-ins ----------------------------------------------------------------------------------------

_PLUGIN = '''import os, sys, time
from bwr_twin.control.pid import PidController


class Exits(PidController):
    def compute(self, *args):
        sys.exit(0)


class OsExits(PidController):
    def compute(self, *args):
        os._exit(0)


class Sleeps(PidController):
    def compute(self, *args):
        try:
            time.sleep(600)
        except Exception:  # an engineer's catch-all does not swallow the budget
            pass
        return super().compute(*args)
'''

_INTERLOCK = '''import numpy as np
from bwr_twin.collision.interlock import ZoneInterlock


class Unwritable(ZoneInterlock):
    def __init__(self, settings, runs, period, parts, levers):
        super().__init__(settings, runs, period, parts, levers)
        for run in range(runs):
            self.interventions[run].append({"kind": "note", "time_s": 0.0, "shapes": {"boom", "wheel"}})
'''


def _plugin_scene(tmp: Path, reference: str, source: str = _PLUGIN, file: str = "mine.py") -> Path:
    (tmp / file).write_text(source)
    return _pid_short(tmp, lambda text: text.replace('type = "pid"', f'type = "{file}:{reference}"'))


def _interlocked(tmp: Path) -> Path:
    (tmp / "lock.py").write_text(_INTERLOCK)
    (tmp / "scene.toml").write_text(
        'extends = "heavy_boom_interlocked"\n[path]\nframe = "world"\nvia_points = [\n'
        '  { t = 0.0, p = [56.473, 15.132, 21.655] },\n  { t = 2.0, p = [56.4, 15.2, 21.655] },\n]\n'
        '[interlock]\ntype = "lock.py:Unwritable"\n')
    return tmp / "scene.toml"


# (id, arguments(tmp) -> run's arguments, environment, pattern of the one error line)
PLUGINS = [
    ("sys-exit-0-at-import", lambda t: [_plugin_scene(t, "X", "import sys\nsys.exit(0)\n"), "--out", t / "o"], {},
     r"mine.py: importing it called sys.exit\(0\) \('controller.type'\): a plug-in must not end the twin"),
    ("sys-exit-3-at-import", lambda t: [_plugin_scene(t, "X", "import sys\nsys.exit(3)\n"), "--out", t / "o"], {},
     r"mine.py: importing it called sys.exit\(3\)"),
    ("os-exit-at-import", lambda t: [_plugin_scene(t, "X", "import os\nos._exit(0)\n"), "--out", t / "o"], {},
     r"mine.py: importing it called os._exit\(0\)"),
    ("sys-exit-in-compute", lambda t: [_plugin_scene(t, "Exits"), "--out", t / "o"], {},
     r"controller .*mine.py:Exits: compute\(\) raised SystemExit: 0 at t = 0.00 s"),
    ("os-exit-in-compute", lambda t: [_plugin_scene(t, "OsExits"), "--out", t / "o"], {},
     r"controller .*mine.py:OsExits: compute\(\) called os._exit\(0\) at t = 0.00 s"),
    ("compute-sleeps-beyond-its-budget", lambda t: [_plugin_scene(t, "Sleeps"), "--out", t / "o"],
     {"BWR_TWIN_CALL_BUDGET": "1"},
     r"mine.py:Sleeps: compute\(\) ran longer than its budget of 1 s a call at t = 0.00 s and was stopped; set "
     r"BWR_TWIN_CALL_BUDGET"),
    ("interlock-report-json-cannot-hold", lambda t: [_interlocked(t), "--out", t / "o", "--no-plots"], {},
     r"interlock .*lock.py:Unwritable: its interventions of run 0 cannot be written as JSON"),
]


@pytest.mark.parametrize("case", PLUGINS, ids=[case[0] for case in PLUGINS])
def test_a_plugin_that_exits_hangs_or_reports_the_unwritable_gets_a_clear_error(tmp_path, case):
    _, arguments, environment, pattern = case
    args = arguments(tmp_path)
    before = snapshot(tmp_path)
    proc = cli("run", *args, cwd=tmp_path, env={**os.environ, **environment})
    assert_refused(proc, pattern)
    assert snapshot(tmp_path) == before  # nothing written

