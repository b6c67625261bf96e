"""An engineer's controller or rate control that misbehaves: every failure is one line that names
its file, class and call, what it raised or returned and when; a traceback never; in a
lockstep only the runs it failed stop (docs/reliability.md, "An engineer's controller or rate control")."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import write_short_scene

from bwr_twin.config.scene import load_scene
from bwr_twin.errors import PluginError, SimulationError
from bwr_twin.sim.lockstep import simulate_lockstep

MISBEHAVING = '''
from dataclasses import dataclass

import numpy as np

from bwr_twin.control import Controller


@dataclass(frozen=True)
class Settings:
    mode: str = "ok"
    poison: float = 0.0  # > 0: this run's slew force turns NaN after 0.5 s

    def validate(self):
        if self.mode == "validate":
            1 / 0


class Misbehaving(Controller):
    Settings = Settings

    def __init__(self, context, settings):
        super().__init__(context, settings)
        if settings[0].mode == "init":
            raise RuntimeError("no licence server")
        self.mode = settings[0].mode
        self.poison = self.per_run("poison")[:, 0] > 0
        self.belief = context.belief
        self.gain = np.array([28000.0, 7262500.0, 5000000.0])
        self.t = 0.0

    def compute(self, q, qd, q_ref, qd_ref, qdd_ref, ids):
        self.t += self.context.control_period
        if self.mode == "raise" and self.t > 1.0:
            raise KeyError("gain")
        if self.mode == "exit":
            raise SystemExit(3)
        returns = {"none": None, "shape": np.zeros(3), "strings": [["a", "b", "c"]],
                   "complex": np.zeros((len(q), 3)) + 1j}
        if self.mode in returns:
            return returns[self.mode]
        self.belief.update(q, qd, ids)
        force = self.belief.bias + self.gain * (q_ref - q) + self.gain * (qd_ref - qd)
        if self.mode == "nan" and self.t > 0.5:
            force[self.poison, 1] = np.nan
        return force
'''

VIA_POINTS = [{"t": 0.0, "p": [0.0, -11.0, 55.0]}, {"t": 2.0, "p": [-0.3, -11.0, 54.9]}]


def scene_with(folder, mode: str):
    (folder / "misbehaving.py").write_text(MISBEHAVING)

    def edit(text: str) -> str:
        start = text.index("[controller]")
        end = text.find("\n[", start + 1)
        table = f'[controller]\ntype = "misbehaving.py:Misbehaving"\nmode = "{mode}"\n'
        return text[:start] + table + ("" if end < 0 else text[end:])

    return write_short_scene(folder, VIA_POINTS, edit=edit)


@pytest.mark.parametrize("mode, said", [
    ("init", r"Misbehaving.__init__\(\) raised RuntimeError: no licence server$"),
    ("validate", r"Settings.validate\(\) raised ZeroDivisionError: division by zero$"),
    ("raise", r"compute\(\) raised KeyError: 'gain' at t = (0\.99|1\.00) s$"),
    ("exit", r"compute\(\) raised SystemExit: 3 at t = 0.00 s$"),
    ("none", r"compute\(\) returned None at t = 0.00 s; it must return a \(1x3\) array of numbers$"),
    ("shape", r"compute\(\) returned an array of shape \(3,\) at t = 0.00 s"),
    ("strings", r"compute\(\) returned list \(\[\['a', 'b', 'c'\]\]\) at t = 0.00 s"),
    ("complex", r"compute\(\) returned complex numbers \(.*\) at t = 0.00 s"),
    ("nan", r"compute\(\) gave nan for slew, near t = 0\.(49|50) s; the run stopped there$"),
])
def test_a_misbehaving_controller_is_named_in_one_line_and_writes_nothing(tmp_path, mode, said):
    scene = scene_with(tmp_path, mode)
    if mode == "nan":
        scene.write_text(scene.read_text().replace('mode = "nan"\n', 'mode = "nan"\npoison = 1.0\n'))
    proc = subprocess.run([sys.executable, "-m", "bwr_twin.run", str(scene), "--out", str(tmp_path / "out"),
                           "--no-plots"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.strip().splitlines()
    assert "Traceback" not in proc.stderr
    assert line.startswith(f"error: {scene}: ") and "misbehaving.py:Misbehaving" in line, line
    assert re.search(said, line), line
    assert not (tmp_path / "out").exists()


def test_in_a_lockstep_only_the_runs_given_non_finite_forces_stop(tmp_path):
    scene = scene_with(tmp_path, "nan")
    scenes = [load_scene(scene, {"controller.poison": poison, "simulation.seed": seed})
              for seed, poison in ((1, 0.0), (2, 1.0), (3, 0.0))]
    results = simulate_lockstep(scenes)
    assert isinstance(results[1], SimulationError) and "gave nan for slew" in str(results[1])
    for result in (results[0], results[2]):
        assert not isinstance(result, Exception)
        assert np.isfinite(result.drive_force_command).all() and result.time[-1] == pytest.approx(2.0)


def test_a_misbehaving_rate_control_is_named_with_its_call_and_time(tmp_path):
    from conftest import SCENES

    (tmp_path / "bad_rate.py").write_text(
        "from bwr_twin.control import RateControl\n\n"
        "class BadRate(RateControl):\n"
        "    def trim(self, signals):\n"
        "        return [float('nan')] * len(self.target)\n")
    scene = load_scene(SCENES / "heavy_bench_reclaim.toml",
                       {"reclaim.rate_control.type": str(tmp_path / "bad_rate.py") + ":BadRate"})
    with pytest.raises(PluginError, match=r"rate control .*bad_rate.py:BadRate: trim\(\) returned \[nan\] at t = 0.00 s"):
        simulate_lockstep([scene])
