"""Evaluate, convert and plot MATLAB Fuzzy Logic Toolbox .fis files (type-1 Mamdani).

    python -m bwr_twin.fis evaluate tests/assets/tipper.fis 2 1
    python -m bwr_twin.fis convert scenes/rulebases/paper_table2.toml paper.fis
    python -m bwr_twin.fis convert paper.fis back.toml
    python -m bwr_twin.fis surface tests/assets/tipper.fis --out tipper.png

FILE may also be a TOML rule base (by its suffix). Outputs are written atomically and never over
the input; an existing OUT is replaced only with --overwrite, and only if bwr_twin.fis wrote it
(its first line, or a picture's metadata, says so: bwr_twin.results.ownership). A bad file exits
with status 2 and one line on stderr, 'error: FILE:LINE: what is wrong (the limit)'; nothing is written.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import SceneError, exit_status
from bwr_twin.results.ownership import picture_metadata, text_mark, written_by

PLOT_SUFFIXES = (".png", ".svg", ".pdf")
# What a command samples at most, counted before anything is allocated: far beyond any use
# (evalfis samples an output range 101 times, gensurf an input 15 times), well within memory.
MAX_POINTS = 1_000_000  # samples of an output range
MAX_SURFACE_ROWS = 250_000  # points of a surface: 500 x 500 over two inputs; a 3-D plot of more crawls
MAX_SURFACE_VALUES = 100_000_000  # its points times the output samples: about a minute of inference


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    parser = CommandParser(prog="python -m bwr_twin.fis", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    evaluate = commands.add_parser("evaluate", help="print the outputs for one row of inputs, as evalfis")
    evaluate.add_argument("file", type=Path, help=".fis file (or TOML rule base)")
    evaluate.add_argument("values", nargs="+", metavar="X", help="one value per input, in the file's order")
    evaluate.add_argument(
        "--points", type=int, default=101, help="samples of each output range (evalfis: 101)"
    )
    evaluate.add_argument("--digits", type=int, default=4, help="decimals printed (MATLAB's format short: 4)")

    convert = commands.add_parser("convert", help="convert between .fis and TOML rule base, by the suffixes")
    convert.add_argument("input", type=Path, help="IN: .fis or .toml")
    convert.add_argument("output", type=Path, help="OUT: .fis or .toml (not the input; must not exist)")
    convert.add_argument("--overwrite", action="store_true", help="replace OUT if bwr_twin.fis wrote it")

    surface = commands.add_parser("surface", help="plot the control surface and the membership functions")
    surface.add_argument("file", type=Path, help=".fis file (or TOML rule base) with 1 or 2 inputs")
    surface.add_argument("--out", type=Path, required=True, help="picture: .png, .svg or .pdf")
    surface.add_argument("--overwrite", action="store_true", help="replace --out if bwr_twin.fis wrote it")
    surface.add_argument("--output", type=int, default=1, help="which output to plot (1-based)")
    surface.add_argument("--grid", type=int, default=31, help="samples per input")
    surface.add_argument("--points", type=int, default=101, help="samples of the output range")
    args = parser.parse_args(argv)

    return exit_status(lambda: _command(args))


def _command(args: argparse.Namespace) -> int:
    with _warnings_as_lines():
        if args.command == "evaluate":
            _evaluate(args.file, args.values, args.points, args.digits)
        elif args.command == "convert":
            _convert(args.input, args.output, args.overwrite)
        else:
            _surface(args.file, args.out, args.overwrite, args.output, args.grid, args.points)
    return 0


def _evaluate(path: Path, texts: list[str], points: int, digits: int) -> None:
    from bwr_twin.fis.convert import load_system
    from bwr_twin.fis.inference import evaluate

    _check_points(points)
    if not 0 <= digits <= 15:
        raise SceneError(f"--digits must be 0..15, got {digits}")
    system = load_system(path)
    if len(texts) != len(system.inputs):
        names = ", ".join(repr(v.name) for v in system.inputs)
        raise SceneError(
            f"{path}: the system has {len(system.inputs)} inputs ({names}), got {len(texts)} values"
        )
    values = []
    for i, (text, variable) in enumerate(zip(texts, system.inputs), start=1):
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            low, high = variable.range
            raise SceneError(
                f"X{i} {text!r} is not a finite number (input {i} {variable.name!r}, "
                f"range [{low:g} {high:g}])"
            )
        values.append(value)
    outputs = evaluate(system, [values], points=points)[0]
    print("output = " + "   ".join(f"{v:.{digits}f}" for v in outputs))


def _convert(source: Path, out: Path, overwrite: bool) -> None:
    from bwr_twin.control.rulebase import RuleBase
    from bwr_twin.fis.convert import SUFFIXES, fis_to_rulebase, load_system, output_text

    if out.suffix.lower() not in SUFFIXES:
        raise SceneError(f"{out}: unknown output suffix {out.suffix!r} (known: {', '.join(SUFFIXES)})")
    _check_destination(source, out, overwrite)
    system = load_system(source)
    text = f"{text_mark(WRITER, out.suffix)}\n{output_text(system, out, str(source))}"
    expected = fis_to_rulebase(system).digest() if out.suffix.lower() == ".toml" else None

    def write(temporary: Path) -> None:
        temporary.write_text(text, encoding="utf-8")
        # Read the TOML back before it takes OUT's name: a file that would not give the same rule
        # base is never left behind.
        if expected is not None and RuleBase.from_toml(temporary).digest() != expected:
            raise SceneError(f"{out}: the written rule base does not read back equal (nothing written)")

    _write(out, write)
    counts = (
        _count(len(system.inputs), "input"),
        _count(len(system.outputs), "output"),
        _count(len(system.rules), "rule"),
    )
    print(f"{source} -> {out}: {', '.join(counts)}")


def _surface(path: Path, out: Path, overwrite: bool, output: int, grid: int, points: int) -> None:
    from bwr_twin.fis.convert import load_system

    if out.suffix.lower() not in PLOT_SUFFIXES:
        raise SceneError(f"{out}: unknown picture suffix {out.suffix!r} (known: {', '.join(PLOT_SUFFIXES)})")
    _check_points(points)
    if grid < 2:
        raise SceneError(f"--grid must be 2 or more samples per input, got {grid}")
    _check_destination(path, out, overwrite)
    system = load_system(path)
    rows = grid ** min(len(system.inputs), 2)
    if rows > MAX_SURFACE_ROWS or rows * points > MAX_SURFACE_VALUES:
        raise SceneError(f"--grid {grid}: {rows:.3g} points of the surface ({grid} per input) x {points} output "
                         f"samples, beyond the limit of {MAX_SURFACE_ROWS:,} points and {MAX_SURFACE_VALUES:.0e} "
                         "samples; choose a smaller --grid or --points")

    from bwr_twin.fis.surface import surface_figure

    figure = surface_figure(system, output=output, grid=grid, points=points)
    # The format is named because the temporary file's suffix is not the picture's.
    kind = out.suffix.lower()[1:]
    metadata = picture_metadata(WRITER, out.suffix)  # what --overwrite looks for
    _write(out, lambda temporary: figure.savefig(temporary, format=kind, dpi=110, metadata=metadata))
    print(f"{out}: control surface of {system.name!r}, output {output} {system.outputs[output - 1].name!r}")


WRITER = "bwr_twin.fis"  # the mark of every file convert and surface write (bwr_twin.results.ownership)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _check_points(points: int) -> None:
    if points < 2:
        raise SceneError(f"--points must be 2 or more samples of the output range, got {points}")
    if points > MAX_POINTS:
        raise SceneError(f"--points {points}: more samples of the output range than the limit of {MAX_POINTS:,} "
                         "(evalfis takes 101)")


def _check_destination(source: Path, out: Path, overwrite: bool) -> None:
    """Refuse OUT if it is the input, a directory, exists (without overwrite, or not written by
    bwr_twin.fis) or has no folder."""
    if out.exists():
        with contextlib.suppress(OSError):
            if out.samefile(source):
                raise SceneError(f"{out}: is the input file itself; choose another output")
        if out.is_dir():
            raise SceneError(f"{out}: is a directory; name a file")
        if not overwrite:
            raise SceneError(f"{out}: already exists; choose another output or pass --overwrite")
        if not written_by(out, WRITER):  # the twin replaces only what it wrote
            raise SceneError(f"{out}: exists and was not written by bwr_twin.fis; it is left alone, "
                             "choose another output")
    elif not out.parent.is_dir():
        raise SceneError(f"{out}: the directory {out.parent} does not exist")


def _write(out: Path, write) -> None:
    from bwr_twin.results.rundir import write_atomically

    try:
        write_atomically(out, write)
    except OSError as exc:
        raise SceneError(f"{out}: cannot write: {exc.strerror or exc} (nothing written)") from None


@contextlib.contextmanager
def _warnings_as_lines() -> Iterator[None]:
    """Warnings (an input clipped, nothing fired) as 'warning: ...' lines, without source lines."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"warning: {message}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


if __name__ == "__main__":
    sys.exit(main())
