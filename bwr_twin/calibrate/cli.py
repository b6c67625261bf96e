"""The command line of `python -m bwr_twin.calibrate` (its __main__ says what it does)."""

from __future__ import annotations

import argparse
import datetime
import json
from pathlib import Path

import numpy as np

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, exit_status

MAX_SECONDS = 3600.0  # s: a fit estimated to run longer is refused without --force
HOLDOUT_WINDOW = 60.0  # s: open-loop prediction windows of a held-out log


def main(argv: list[str] | None = None) -> int:
    from bwr_twin.calibrate.fit import MAX_ITERATIONS, WINDOW

    parser = CommandParser(prog="python -m bwr_twin.calibrate", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True)
    fit = commands.add_parser("fit", help="fit the MJCF's parameters to logs of the machine")
    fit.add_argument("logs", nargs="+", type=Path, help="run directories the twin wrote, or historian CSV or "
                     "Parquet files (with --columns)")
    fit.add_argument("--model", required=True, type=Path, help="the machine's MJCF to calibrate")
    fit.add_argument("--out", required=True, type=Path, help="output folder (must not exist)")
    fit.add_argument("--params", nargs="+", help="parameters to fit, e.g. slew_damping luff_frictionloss "
                     "boom_counterweight_mass travel_lag slew_offset (default: each axis's damping, "
                     "frictionloss, armature)")
    fit.add_argument("--holdout", type=Path, help="a log kept out of the fit, predicted over "
                     f"{HOLDOUT_WINDOW:g} s windows by the nominal and the calibrated model")
    fit.add_argument("--columns", type=Path, help="the TOML column map of historian logs (CSV or Parquet)")
    fit.add_argument("--window", type=float, default=WINDOW, help=f"s of each window (default {WINDOW:g})")
    fit.add_argument("--iterations", type=int, default=MAX_ITERATIONS, help="Gauss-Newton iterations at most")
    fit.add_argument("--overwrite", action="store_true", help="replace DIR, a calibration the twin wrote")
    fit.add_argument("--force", action="store_true", help="start a fit estimated to take longer than an hour")
    plan = commands.add_parser("plan", help="write a scene of a test motion to run on the machine")
    plan.add_argument("model", type=Path, help="the machine's MJCF")
    plan.add_argument("--out", required=True, type=Path, help="the scene TOML to write")
    plan.add_argument("--minutes", type=float, default=10.0, help="the test's length (default 10)")
    plan.add_argument("--overwrite", action="store_true", help="replace a test scene the twin wrote")
    args = parser.parse_args(argv)
    return exit_status(lambda: _fit(args) if args.command == "fit" else _plan(args))


def _plan(args: argparse.Namespace) -> int:
    from bwr_twin.calibrate.plan import write_plan

    write_plan(args.model, args.out, minutes=args.minutes, overwrite=args.overwrite)
    return 0


def _fit(args: argparse.Namespace) -> int:
    from bwr_twin.calibrate.fit import Problem, evaluations_needed, fit, seconds_per_evaluation
    from bwr_twin.calibrate.parameters import catalogue
    from bwr_twin.calibrate.reading import read_log
    from bwr_twin.model.machine import Machine
    from bwr_twin.ownership import check_output
    from bwr_twin.results.rundir import staged_directory

    check_output(args.out, "calibration", overwrite=args.overwrite,
                 inputs=[args.model, *args.logs, *([args.holdout] if args.holdout else [])])
    machine = Machine(args.model)
    knobs = catalogue(machine, args.params)
    logs = [read_log(path, machine, args.columns) for path in args.logs]
    holdout = read_log(args.holdout, machine, args.columns) if args.holdout else None
    problem = Problem(machine, knobs, logs, window=args.window)
    per = seconds_per_evaluation(problem)
    needed = evaluations_needed(knobs, args.iterations)
    if per * needed > MAX_SECONDS and not args.force:
        raise BwrError(f"{args.logs[0]}: fitting {len(knobs)} parameters to {len(problem.windows)} windows would take "
                       f"up to {per * needed / 3600:.1f} h ({needed} rollouts of {per:.2f} s); fit fewer "
                       "parameters or a shorter log, or pass --force")
    print(f"fitting {len(knobs)} parameters to {len(problem.windows)} windows of {args.window:g} s from "
          f"{len(logs)} log(s); at most {needed} rollouts of {per:.2f} s each, {per * needed:.0f} s")
    with _progress(needed) as progress:
        result = fit(problem, iterations=args.iterations, progress=progress)
    _check_same_machine(args.logs[0], args.model, result, problem.motion_rms())
    prediction = _holdout(machine, knobs, holdout, result) if holdout is not None else None
    text = calibrated_xml(args.model, args.logs, result)
    with staged_directory(args.out, overwrite=args.overwrite, kind="calibration") as staging:
        (staging / "calibrated.xml").write_text(text)
        Machine(staging / "calibrated.xml")  # it still meets the model contract
        (staging / "calibration.json").write_text(json.dumps(_summary(args, result, prediction), indent=2) + "\n")
        from bwr_twin.calibrate.report import write_report

        write_report(staging, result)
    _print(result, prediction)
    print(f"results in {args.out}/")
    return 0


MAX_UNEXPLAINED = 1.0  # of a log's motion: a model that predicts it worse than standing still is not its machine


def _check_same_machine(log: Path, model: Path, result, motion: np.ndarray) -> None:
    """Refuse a fit that leaves more than MAX_UNEXPLAINED of an axis's measured motion unexplained:
    a residual far beyond any noise is a log of another machine, or of signals mapped wrong."""
    for column, left, moved in zip(result.columns, result.rms_after, motion, strict=True):
        if "position" in column and moved > 0 and left > MAX_UNEXPLAINED * moved:
            raise BwrError(f"{log}: the {column} residual after the fit, {left:.4g} {_unit(column)} RMS, is "
                           f"{left / moved:.0%} of the motion logged ({moved:.4g}): not a log of {model} "
                           "(another machine, or columns mapped wrong); nothing written")


class _progress:
    """A progress line of rollouts done out of the most the fit needs, with tqdm's estimate."""

    def __init__(self, total: int):
        self.total = total

    def __enter__(self):
        import sys

        from tqdm import tqdm

        self.bar = tqdm(total=self.total, desc="fitting", unit=" rollouts", leave=False,
                        disable=not sys.stderr.isatty())
        return lambda done: self.bar.update(min(done, self.total) - self.bar.n)

    def __exit__(self, *exc):
        self.bar.close()


def _holdout(machine, knobs, log, result) -> dict:
    """RMS per compared column of the held-out log, open loop over HOLDOUT_WINDOW windows."""
    from bwr_twin.calibrate.fit import Problem

    problem = Problem(machine, knobs, [log], window=HOLDOUT_WINDOW)
    before = problem.column_rms(problem.params.as_nominal_vector())
    after = problem.column_rms(result.x)
    return {"log": str(log.path), "window_s": HOLDOUT_WINDOW, "windows": len(problem.windows),
            "rms": {c: {"nominal": float(b), "calibrated": float(a), "unit": _unit(c)}
                    for c, b, a in zip(problem.columns, before, after, strict=True)}}


def _unit(column: str) -> str:
    axis, what = column.split()
    linear = axis == "travel"
    return ("m" if linear else "rad") + ("" if what == "position" else "/s")


def calibrated_xml(model: Path, logs: list[Path], result) -> str:
    """The text of `model` with the fit's identified parameters written in, each with a comment
    giving its nominal value and interval; BwrError naming the file if it cannot be edited."""
    from bwr_twin.calibrate.mjcf_edit import edit

    date = datetime.date.today().isoformat()
    source = ", ".join(str(p) for p in logs)
    changes = []
    for e in result.estimates:
        k = e.knob
        if not e.identifiable or k.kind in ("lag", "offset"):
            continue
        comment = (f"{k.kind} was {k.nominal:.6g} {k.unit}, 95 % interval [{e.interval[0]:.6g}, "
                   f"{e.interval[1]:.6g}] {k.unit}")
        if k.kind in ("damping", "frictionloss", "armature"):
            changes.append(("joint", k.element, k.kind, 0, f"{e.fitted:.6g}", comment))
        elif k.kind == "mass":
            changes.append(("body", k.element, "mass", 0, f"{e.fitted:.6g}", comment))
        else:
            changes.append(("body", k.element, "pos", 0, f"{e.fitted:.6g}", comment))
    try:
        text = model.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise BwrError(f"{model}: cannot be read as text: {exc}") from None
    try:
        return edit(text, changes, prefix=f"calibrated from {source} on {date}: ")
    except BwrError as exc:
        raise BwrError(f"{model}: {exc}") from None


def _summary(args, result, prediction) -> dict:
    return {
        "model": str(args.model), "logs": [str(p) for p in args.logs], "window_s": args.window,
        "fit_seconds": round(result.seconds, 2), "rollouts": result.evaluations,
        "parameters": {e.knob.name: {
            "unit": e.knob.unit, "nominal": e.knob.nominal, "fitted": e.fitted,
            "standard_error": _number(e.standard_error), "interval_95": [_number(v) for v in e.interval],
            "bounds": [e.knob.low, e.knob.high], "identifiable": e.identifiable,
            **({} if e.identifiable else {"left_at_nominal": True, "test_motion": e.knob.motion})}
            for e in result.estimates},
        "residual_rms": {c: {"nominal": float(b), "calibrated": float(a), "unit": _unit(c)}
                         for c, b, a in zip(result.columns, result.rms_before, result.rms_after, strict=True)},
        "holdout": prediction,
    }


def _number(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _print(result, prediction) -> None:
    for e in result.estimates:
        k = e.knob
        if e.identifiable:
            print(f"{k.name:28s} {k.nominal:12.5g} -> {e.fitted:12.5g} {k.unit:10s} +- {e.standard_error:.3g} "
                  f"(95 %: {e.interval[0]:.5g} to {e.interval[1]:.5g})")
        else:
            print(f"{k.name:28s} {k.nominal:12.5g} {k.unit:10s} not determined by these logs: left as it was; "
                  f"to determine it, record {k.motion}")
    for c, b, a in zip(result.columns, result.rms_before, result.rms_after, strict=True):
        print(f"residual RMS {c:16s} {b:.4g} -> {a:.4g} {_unit(c)}")
    if prediction is not None:
        for c, v in prediction["rms"].items():
            print(f"held-out RMS {c:16s} {v['nominal']:.4g} -> {v['calibrated']:.4g} {v['unit']} "
                  f"({v['nominal'] / max(v['calibrated'], 1e-300):.1f}x)")
