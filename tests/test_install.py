"""The package as a user installs it: mjcf/ and scenes/ sit at the top of the checkout and ship
inside the package, so the wheel holds every machine and scene file, and a shipped scene runs
by name from any folder with the package installed from that wheel alone.

The wheel is built offline from a copy of the sources with the test environment's setuptools,
and installed without dependencies into a fresh virtual environment; that environment borrows
the test environment's site-packages folders for mujoco, numpy and the rest through a path
file, whose lines add the folders to sys.path without running the editable install there.
"""

import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from pathlib import Path

from conftest import ROOT

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

# What the build reads; the rest of the checkout is not the package's.
SOURCES = ("pyproject.toml", "README.md", "bwr_twin", "mjcf", "scenes")
# Where pyproject.toml maps a package outside bwr_twin/.
MAPPED = {"mjcf": "bwr_twin.mjcf", "scenes": "bwr_twin.scenes"}
SKIP = shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc")
TIMEOUT = 300  # s, for each step; the whole test takes well under a minute


def folders(top: Path, package: str) -> set[str]:
    """The dotted names of `top` and every folder under it, as `package` and its sub-packages."""
    names = {package}
    for path in top.rglob("*"):
        parts = path.relative_to(top).parts
        if path.is_dir() and not any(p == "__pycache__" or p.startswith(".") for p in parts):
            names.add(".".join((package, *parts)))
    return names


def test_pyproject_lists_every_folder_the_package_ships():
    """A mapped package needs the packages listed: a folder of code or data left off the list is
    missing from the wheel, while the editable install still finds it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    expected = folders(ROOT / "bwr_twin", "bwr_twin")
    for folder, package in MAPPED.items():
        expected |= folders(ROOT / folder, package)
        assert config["package-dir"][package] == folder
    assert set(config["packages"]) == expected


def run(*command, cwd: Path, env: dict | None = None) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in command], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=TIMEOUT)
    assert proc.returncode == 0, f"{' '.join(map(str, command))}\n{proc.stdout}\n{proc.stderr}"
    return proc


def test_a_shipped_scene_runs_by_name_from_the_installed_wheel(tmp_path):
    source = tmp_path / "source"  # a copy: building in the checkout would leave build/ there
    source.mkdir()
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, source / name, ignore=SKIP)
        else:
            shutil.copy2(path, source / name)
    dist = tmp_path / "dist"
    run(sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation", "--no-index",
        "--wheel-dir", dist, source, cwd=tmp_path)
    (wheel,) = dist.glob("bwr_twin-*.whl")

    # The wheel: the package alone, with every machine and scene file inside it.
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    assert all(n.startswith(("bwr_twin/", "bwr_twin-")) for n in names), sorted(names)
    for folder, package in MAPPED.items():
        inside = package.replace(".", "/")
        shipped = {f"{inside}/{p.relative_to(ROOT / folder).as_posix()}" for p in (ROOT / folder).rglob("*")
                   if p.suffix in (".xml", ".md", ".toml")}
        assert shipped and shipped <= names, sorted(shipped - names)

    # A fresh environment with the package from the wheel, and the dependencies borrowed.
    environment = tmp_path / "env"
    venv.EnvBuilder(with_pip=False).create(environment)
    python = environment / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    run(sys.executable, "-m", "pip", "--python", python, "install", "--quiet", "--no-deps", "--no-index", wheel,
        cwd=tmp_path)
    purelib = Path(run(python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))",
                       cwd=tmp_path).stdout.strip())
    borrowed = [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")]
    (purelib / "borrowed_dependencies.pth").write_text("\n".join(borrowed) + "\n")

    elsewhere = tmp_path / "elsewhere"  # no bwr_twin/, mjcf/ or scenes/ beside the command
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSAFEPATH")}
    where = json.loads(run(python, "-c", "import json, sys, bwr_twin.shipped as s; print(json.dumps({"
                           "'package': s.__file__, 'mjcf': str(s.MJCF), 'scenes': str(s.SCENES), "
                           "'finders': [getattr(f, '__name__', type(f).__name__) for f in sys.meta_path]}))",
                           cwd=elsewhere, env=env).stdout)
    package = (purelib / "bwr_twin").resolve()
    assert Path(where["package"]).resolve().parent == package  # the wheel's copy, not the checkout
    assert "_EditableFinder" not in where["finders"]  # the editable install is not in play
    assert Path(where["mjcf"]).resolve() == package / "mjcf"
    assert Path(where["scenes"]).resolve() == package / "scenes"

    out = elsewhere / "out"
    proc = run(python, "-m", "bwr_twin.run", "pid_paper", "--out", out, "--no-plots", cwd=elsewhere, env=env)
    assert "pid_paper.toml" in proc.stdout, proc.stdout
    metrics = json.loads((out / "metrics.json").read_text())
    assert Path(metrics["run"]["mjcf"]).resolve() == package / "mjcf" / "bwr.xml"  # the shipped machine
    assert {"travel", "slew", "luff"} <= set(metrics)
