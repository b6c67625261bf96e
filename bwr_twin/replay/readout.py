"""The numbers beside the picture: time and, per axis, desired, actual and error in engineering
units (travel in m, slew and luff in degrees). The live GUI shows them as a table; the HTML
export, which cannot record GUI elements, shows the same text as a scene label."""

from __future__ import annotations

from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.replay.recording import Instant

VALUE_DECIMALS = 3  # mm of travel, thousandths of a degree
ERROR_DECIMALS = 4  # errors are small: one digit more


def rows(instant: Instant) -> list[tuple[str, str, str, str]]:
    """(axis, desired, actual, error) per axis, formatted with units."""
    out = []
    for j, axis in enumerate(AXES):
        desired, actual, error = (
            to_display(j, float(v[j])) for v in (instant.q_desired, instant.q_actual, instant.q_error)
        )
        unit = UNITS[j]
        out.append(
            (
                axis,
                f"{desired:.{VALUE_DECIMALS}f} {unit}",
                f"{actual:.{VALUE_DECIMALS}f} {unit}",
                f"{error:+.{ERROR_DECIMALS}f} {unit}",
            )
        )
    return out


def as_markdown(instant: Instant, duration: float) -> str:
    lines = [
        f"**t = {instant.time:.1f} s** of {duration:g} s",
        "",
        "| axis | desired | actual | error |",
        "| --- | ---: | ---: | ---: |",
    ]
    lines += [
        f"| {axis} | {desired} | {actual} | {error} |" for axis, desired, actual, error in rows(instant)
    ]
    if instant.reclaim_rate is not None:
        lines += ["", f"reclaim rate **{instant.reclaim_rate:,.0f} t/h**"]
    if instant.stage is not None:
        lines += ["", f"plan: {instant.stage}"]
    return "\n".join(lines)


def as_text(instant: Instant, duration: float) -> str:
    """Plain text for a scene label: one line per axis, columns aligned."""
    lines = [f"t = {instant.time:.1f} s of {duration:g} s   (desired / actual / error)"]
    lines += [
        f"{axis:<6} {desired:>12} {actual:>12} {error:>13}" for axis, desired, actual, error in rows(instant)
    ]
    if instant.reclaim_rate is not None:
        lines.append(f"reclaim rate {instant.reclaim_rate:,.0f} t/h")
    if instant.stage is not None:
        lines.append(f"plan: {instant.stage}")
    return "\n".join(lines)
