"""The calibration's report: PNG figures of the measured, nominal and calibrated traces per axis,
the residuals, and the parameters with their intervals."""

from __future__ import annotations

from pathlib import Path


def write_report(folder: Path, result, prediction) -> None:
    """Nothing yet beyond calibration.json."""
