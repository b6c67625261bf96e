"""Shared paths and fixtures."""

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from bwr_twin.shipped import MJCF, SCENES

# numpy's floating-point warnings are errors in every command the tests start, as pyproject's
# filterwarnings makes them in the tests' own process: none may reach an engineer's terminal.
NUMPY_WARNINGS = ",".join(f"error:{kind} encountered:RuntimeWarning"
                          for kind in ("invalid value", "overflow", "divide by zero"))
os.environ["PYTHONWARNINGS"] = ",".join(filter(None, (os.environ.get("PYTHONWARNINGS"), NUMPY_WARNINGS)))

ROOT = Path(__file__).resolve().parents[1]  # the checkout: tests run commands from there
PAPER_MJCF = MJCF / "bwr.xml"
HEAVY_MJCF = MJCF / "bwr_heavy.xml"
VARIANT_MJCF = Path(__file__).resolve().parent / "assets" / "bwr_variant.xml"

# The paper's via points in frame 0 (Sec. 4), typed in unchanged, with their times in s.
PAPER_VIA_POINTS = [
    (0.0, (0.0, -11.0, 55.0)),
    (200.0, (-35.0, -11.0, 32.0)),
    (300.0, (-55.0, -11.0, 2.0)),
    (500.0, (-38.5, -20.0, 50.0)),
    (700.0, (0.0, -11.0, 55.0)),
]

# The first 20 s of a reclaim towards the paper's p_int1: the paper scene in seconds, not minutes.
SHORT_VIA_POINTS = [{"t": 0.0, "p": [0.0, -11.0, 55.0]}, {"t": 20.0, "p": [-3.0, -11.0, 54.0]}]


def unrated_paper_mjcf(folder: Path) -> Path:
    """folder/bwr_unrated.xml: the paper's machine without its (assumed) drive ratings, for
    physics the ratings forbid: pushes that leave the envelope, forces that make MuJoCo fail."""
    text = PAPER_MJCF.read_text()
    text = re.sub(r'\s+forcerange="[^"]*"', "", text)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "bwr_unrated.xml").write_text(text)
    return folder / "bwr_unrated.xml"


def path_table(via_points) -> str:
    """A scene file's [path] table for via points in the paper's frame."""
    rows = "".join(f"  {{ t = {v['t']:.1f}, p = [{', '.join(f'{x:.1f}' for x in v['p'])}] }},\n" for v in via_points)
    return f'[path]\nframe = "paper"\nvia_points = [\n{rows}]\n'


def write_short_scene(folder: Path, via_points=SHORT_VIA_POINTS, edit=None) -> Path:
    """folder/short.toml: the individual-gains scene over `via_points`, its file paths absolute,
    its text passed through `edit` if given."""
    text = (SCENES / "paper_individual_gains.toml").read_text()
    start, end = text.index("[path]"), text.index("[simulation]")
    text = text[:start] + path_table(via_points) + "\n" + text[end:]
    text = text.replace('"../mjcf/', f'"{MJCF}/').replace('"rulebases/', f'"{SCENES}/rulebases/')
    if edit:
        text = edit(text)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "short.toml").write_text(text)
    return folder / "short.toml"


@pytest.fixture(scope="session")
def paper_machine():
    from bwr_twin import Machine

    return Machine(PAPER_MJCF)


@pytest.fixture(scope="session", params=[PAPER_MJCF, VARIANT_MJCF], ids=["paper", "variant"])
def any_machine(request):
    from bwr_twin import Machine

    return Machine(request.param)


# Run by FMPy in a fresh environment: validate each FMU named, simulate 2 s, print what it gave.
FMPY_CHECK = textwrap.dedent("""
    import sys
    from fmpy import simulate_fmu
    from fmpy.validation import validate_fmu
    for path in sys.argv[1:]:
        problems = validate_fmu(path)
        assert problems == [], problems
        result = simulate_fmu(path, stop_time=2.0, output=["Travel.EncoderPosition", "PeriodsLeft"])
        print(path, len(result), result["PeriodsLeft"][-1], result["Travel.EncoderPosition"][-1])
""")


@pytest.fixture(scope="session")
def fmpy_alone(tmp_path_factory):
    """FMPy installed alone in a fresh virtual environment, as an engineer's other PC has it (needs
    PyPI; pip's cache keeps a second run offline). Called with FMU paths, it validates each and
    simulates 2 s in that environment, and returns a row per FMU: (samples, PeriodsLeft at the
    end, Travel.EncoderPosition at the end)."""
    folder = tmp_path_factory.mktemp("fmpy_alone")
    venv = folder / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    pip = subprocess.run([str(python), "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "fmpy"],
                         capture_output=True, text=True, timeout=600, check=False)
    assert pip.returncode == 0, f"pip install fmpy (needs PyPI): {pip.stderr[-2000:]}"
    lacks = subprocess.run([str(python), "-c", "import bwr_twin"], capture_output=True, cwd=folder, check=False)
    assert lacks.returncode != 0  # the project is not there

    def check(*fmus: Path) -> list[tuple[int, float, float]]:
        done = subprocess.run([str(python), "-c", FMPY_CHECK, *map(str, fmus)], capture_output=True, text=True,
                              cwd=folder, timeout=300, check=False)
        assert done.returncode == 0, done.stderr[-3000:]
        rows = [line.rsplit(" ", 3)[1:] for line in done.stdout.splitlines()]
        assert len(rows) == len(fmus), done.stdout
        return [(int(samples), float(left), float(position)) for samples, left, position in rows]

    return check
