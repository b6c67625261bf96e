"""Shared paths and fixtures."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAPER_MJCF = ROOT / "mjcf" / "bwr.xml"
VARIANT_MJCF = ROOT / "tests" / "assets" / "bwr_variant.xml"
SCENES = ROOT / "scenes"

# The paper's via points in frame 0 (Sec. 4), typed in unchanged, with their times in s.
PAPER_VIA_POINTS = [
    (0.0, (0.0, -11.0, 55.0)),
    (200.0, (-35.0, -11.0, 32.0)),
    (300.0, (-55.0, -11.0, 2.0)),
    (500.0, (-38.5, -20.0, 50.0)),
    (700.0, (0.0, -11.0, 55.0)),
]


@pytest.fixture(scope="session")
def paper_machine():
    from bwr_twin import Machine

    return Machine(PAPER_MJCF)


@pytest.fixture(scope="session", params=[PAPER_MJCF, VARIANT_MJCF], ids=["paper", "variant"])
def any_machine(request):
    from bwr_twin import Machine

    return Machine(request.param)
