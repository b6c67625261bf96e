"""The numbers beside the picture: time and, per axis, desired, actual and error in engineering
units (travel in m, slew and luff in degrees); of several runs, each run's errors. The live GUI
shows them as a table; the HTML export, which cannot record GUI elements, shows the same text as
a scene label."""

from __future__ import annotations

from collections.abc import Sequence

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


def errors(instant: Instant, *, units: bool = True) -> list[str]:
    """Each axis's error (desired - actual), formatted, with its unit unless the caller gives them."""
    return [f"{to_display(j, float(instant.q_error[j])):+.{ERROR_DECIMALS}f}" + (f" {UNITS[j]}" if units else "")
            for j in range(len(AXES))]


def runs_markdown(t: float, instants: Sequence[Instant], names: Sequence[str], colours: Sequence[str],
                  duration: float) -> str:
    """Several runs at time t (s): per run (in its colour), each axis's error; the reclaim rate
    and where a bench plan stands, when the runs have them. A run that has ended holds its last."""
    if not instants:
        return f"**t = {t:.1f} s** of {duration:g} s; no run shown: tick one under Runs"
    rates = any(instant.reclaim_rate is not None for instant in instants)
    head = ["run", *(f"{axis} [{unit}]" for axis, unit in zip(AXES, UNITS)), *(["rate [t/h]"] if rates else [])]
    lines = [
        f"**t = {t:.1f} s** of {duration:g} s; error = desired - actual",
        "",
        "| " + " | ".join(head) + " |",
        "| --- |" + " ---: |" * (len(head) - 1),
    ]
    for instant, name, colour in zip(instants, names, colours):
        rate = [f"{instant.reclaim_rate:,.0f}" if instant.reclaim_rate is not None else ""] if rates else []
        cells = errors(instant, units=False) + rate
        lines.append(f'| <span style="color:{colour}">&#9632;</span> {name} | ' + " | ".join(cells) + " |")
    stages = [(name, instant.stage) for name, instant in zip(names, instants) if instant.stage is not None]
    if stages:
        lines += [""] + [f"plan: {stage} ({name})" for name, stage in stages]
    return "\n".join(lines)

