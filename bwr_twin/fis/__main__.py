"""Evaluate, convert and plot MATLAB Fuzzy Logic Toolbox .fis files (type-1 Mamdani).

    python -m bwr_twin.fis evaluate tests/assets/tipper.fis 2 1
    python -m bwr_twin.fis evaluate tests/assets/tipper.fis --input points.csv
    python -m bwr_twin.fis convert scenes/rulebases/paper_table2.toml paper.fis
    python -m bwr_twin.fis convert paper.fis back.toml
    python -m bwr_twin.fis convert paper.fis paper.fcl    # IEC 61131-7 FCL, read back as well
    python -m bwr_twin.fis convert paper.fis paper.fll    # fuzzylite's FLL, written only
    python -m bwr_twin.fis surface tests/assets/tipper.fis --out tipper.png

FILE may also be a TOML rule base or an FCL file (by its suffix). Outputs are written atomically and never over
the input; an existing OUT is replaced only with --overwrite, and only if bwr_twin.fis wrote it
(its first line, or a picture's metadata, says so: bwr_twin.ownership). A bad file exits
with status 2 and one line on stderr, 'error: FILE:LINE: what is wrong (the limit)'; nothing is written.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import math
import os
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import SceneError, exit_status, leave
from bwr_twin.ownership import check_recorded, picture_metadata, text_mark, written_by

PLOT_SUFFIXES = (".png", ".svg", ".pdf")
# What a command samples at most, counted before anything is allocated: far beyond any use
# (evalfis samples an output range 101 times, gensurf an input 15 times), well within memory.
MAX_POINTS = 1_000_000  # samples of an output range
MAX_SURFACE_ROWS = 250_000  # points of a surface: 500 x 500 over two inputs; a 3-D plot of more crawls
MAX_SURFACE_VALUES = 100_000_000  # its points times the output samples: about a minute of inference
# What evaluate --input reads at most, checked while reading, before a number is parsed:
MAX_ROWS = 1_000_000  # rows of inputs (a header besides)
MAX_INPUT_BYTES = 100_000_000  # 1,000,000 rows of 100 characters
# ...and the inference it may take: rows x output samples x rules x outputs at the cost of one
# rule's implication at one output sample (measured: 100,000 rows of the paper's 49 rules at 101
# samples in 2.5 s on the project's 2-core machine).
SECONDS_PER_SAMPLE = 5e-9
MAX_EVALUATE_SECONDS = 600.0
STDIN = "<stdin>"  # how messages name --input -


def main(argv: list[str] | None = None) -> int:
    """The command line; returns the exit status (0 done, 2 bad input, 130 interrupted)."""
    parser = CommandParser(prog="python -m bwr_twin.fis", description=__doc__.split("\n\n")[0])
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    evaluate = commands.add_parser(
        "evaluate", help="print the outputs for a row of inputs, or for every row of a CSV file, as evalfis"
    )
    evaluate.add_argument("file", type=Path, help=".fis file (or TOML rule base)")
    evaluate.add_argument("values", nargs="*", metavar="X", help="one value per input, in the file's order")
    evaluate.add_argument(
        "--input", metavar="CSV", help="rows of inputs instead of X ...: a CSV file, or - for standard "
        "input; prints a CSV of the inputs and the outputs"
    )
    evaluate.add_argument(
        "--points", type=int, default=101, help="samples of each output range (evalfis: 101)"
    )
    evaluate.add_argument("--digits", type=int, default=4, help="decimals printed (MATLAB's format short: 4)")

    convert = commands.add_parser("convert", help="convert between .fis, FCL and TOML rule base, or to FLL, by the suffixes")
    convert.add_argument("input", type=Path, help="IN: .fis, .fcl or .toml")
    convert.add_argument("output", type=Path, help="OUT: .fis, .fcl, .fll or .toml (not the input; must not exist)")
    convert.add_argument("--overwrite", action="store_true", help="replace OUT if bwr_twin.fis wrote it")

    surface = commands.add_parser("surface", help="plot the control surface and the membership functions")
    surface.add_argument("file", type=Path, help=".fis file (or TOML rule base) with 1 or 2 inputs")
    surface.add_argument("--out", type=Path, required=True, help="picture: .png, .svg or .pdf")
    surface.add_argument("--overwrite", action="store_true", help="replace --out if bwr_twin.fis wrote it")
    surface.add_argument("--output", type=int, default=1, help="which output to plot (1-based)")
    surface.add_argument("--grid", type=int, default=31, help="samples per input")
    surface.add_argument("--points", type=int, default=101, help="samples of the output range")
    args = parser.parse_args(argv)
    if args.command == "evaluate" and bool(args.values) == (args.input is not None):
        evaluate.error("give one value per input (X ...) or --input CSV, not both" if args.values else
                       "give one value per input (X ...) or --input CSV")

    return exit_status(lambda: _command(args))


def _command(args: argparse.Namespace) -> int:
    with _warnings_as_lines():
        if args.command == "evaluate":
            if args.input is None:
                _evaluate(args.file, args.values, args.points, args.digits)
            else:
                _evaluate_rows(args.file, args.input, args.points, args.digits)
        elif args.command == "convert":
            _convert(args.input, args.output, args.overwrite)
        else:
            _surface(args.file, args.out, args.overwrite, args.output, args.grid, args.points)
    return 0


def _evaluate(path: Path, texts: list[str], points: int, digits: int) -> None:
    from bwr_twin.fis.inference import evaluate

    system = _evaluated_system(path, points, digits)
    if len(texts) != len(system.inputs):
        names = ", ".join(repr(v.name) for v in system.inputs)
        raise SceneError(
            f"{path}: the system has {len(system.inputs)} inputs ({names}), got {len(texts)} values"
        )
    values = [_value(text, i, variable, f"X{i} ") for i, (text, variable) in
              enumerate(zip(texts, system.inputs), start=1)]
    outputs = evaluate(system, [values], points=points)[0]
    print("output = " + "   ".join(f"{v:.{digits}f}" for v in outputs))


def _evaluate_rows(path: Path, source: str, points: int, digits: int) -> None:
    """Every row of the CSV `source` (a file, or - for stdin) evaluated at once, printed as CSV:
    the inputs as given, then the outputs, under a header of the .fis file's names."""
    import numpy as np

    from bwr_twin.fis.inference import evaluate

    system = _evaluated_system(path, points, digits)
    inputs = system.inputs
    name = STDIN if source == "-" else source
    lines = enumerate(_read_lines(source, name), start=1)
    numbered = [(number, line) for number, line in lines if line.strip()]  # blank lines are skipped
    if numbered and _is_header(_cells(numbered[0][1])):
        _check_header(name, numbered[0][0], _cells(numbered[0][1]), inputs)
        numbered = numbered[1:]
    if not numbered:
        raise SceneError(f"{name}: no rows of inputs (one row a point, one value per input: "
                         f"{', '.join(v.name for v in inputs)})")
    if len(numbered) > MAX_ROWS:
        raise SceneError(f"{name}: {len(numbered):,} rows of inputs; --input takes at most {MAX_ROWS:,}: "
                         "split the file")
    _check_work(name, len(numbered), system, points)
    x = np.empty((len(numbered), len(inputs)))
    for row, (number, line) in enumerate(numbered):
        cells = _cells(line)
        try:
            if len(cells) != len(inputs):
                raise ValueError
            x[row] = [float(cell) for cell in cells]
        except ValueError:
            _bad_row(f"{name}:{number}: row {row + 1}", cells, inputs)
    bad = np.argwhere(~np.isfinite(x))
    if len(bad):
        row, i = bad[0]
        number, line = numbered[row]
        _value(_cells(line)[i].strip(), i + 1, inputs[i], f"{name}:{number}: row {row + 1}, column {i + 1}: ")
    outputs = evaluate(system, x, points=points)
    header = io.StringIO()
    csv.writer(header, lineterminator="\n").writerow([v.name for v in (*inputs, *system.outputs)])
    try:
        sys.stdout.write(header.getvalue())
        block = 10_000
        for start in range(0, len(numbered), block):
            rows = zip(numbered[start : start + block], outputs[start : start + block])
            sys.stdout.write("".join(
                ",".join([*(cell.strip() for cell in _cells(line)), *(f"{v:.{digits}f}" for v in values)])
                + "\n" for (_, line), values in rows
            ))
        sys.stdout.flush()
    except BrokenPipeError:  # the reader stopped reading (| head): nothing more to say
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        raise SystemExit(1) from None


def _bad_row(where: str, cells: list[str], inputs) -> None:
    """Raise the SceneError naming what is wrong with a row: its number of values, or the first
    that is not a number."""
    if len(cells) != len(inputs):
        names = ", ".join(repr(v.name) for v in inputs)
        raise SceneError(f"{where} has {_count(len(cells), 'value')}; the system has "
                         f"{_count(len(inputs), 'input')} ({names}), one value each, separated by commas")
    for i, (cell, variable) in enumerate(zip(cells, inputs), start=1):
        _value(cell.strip(), i, variable, f"{where}, column {i}: ")


def _evaluated_system(path: Path, points: int, digits: int):
    from bwr_twin.fis.convert import load_system

    _check_points(points)
    if not 0 <= digits <= 15:
        raise SceneError(f"--digits must be 0..15, got {digits}")
    system = load_system(path)
    _check_work(str(path), 1, system, points)
    return system


def _value(text: str, i: int, variable, where: str) -> float:
    """The number `text` for input i, or a SceneError saying where it is and what the input takes."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        low, high = variable.range
        raise SceneError(f"{where}{text!r} is not a finite number (input {i} {variable.name!r}, "
                         f"range [{low:g} {high:g}])")
    return value


def _read_lines(source: str, name: str) -> list[str]:
    """The lines of a file of inputs (or stdin), read as any user's text file (bwr_twin.textfile);
    refused as soon as it holds more than MAX_ROWS rows and a header, or MAX_INPUT_BYTES."""
    from bwr_twin.textfile import decode

    data = bytearray()
    try:
        with contextlib.nullcontext(sys.stdin.buffer) if source == "-" else open(source, "rb") as stream:
            lines = 0
            while chunk := stream.read(1 << 20):
                data += chunk
                lines += chunk.count(b"\n")
                if lines > MAX_ROWS + 1:
                    raise SceneError(f"{name}: more than {MAX_ROWS + 1:,} lines; --input takes at most "
                                     f"{MAX_ROWS:,} rows of inputs and a header: split the file")
                if len(data) > MAX_INPUT_BYTES:
                    raise SceneError(f"{name}: more than {MAX_INPUT_BYTES:,} bytes; --input takes at most "
                                     f"{MAX_ROWS:,} rows of {MAX_INPUT_BYTES // MAX_ROWS} characters: "
                                     "split the file")
    except FileNotFoundError:
        raise SceneError(f"{name}: file of inputs not found") from None
    except OSError as exc:
        raise SceneError(f"{name}: cannot read the file of inputs: {exc.strerror or exc}") from None
    try:
        return decode(bytes(data)).split("\n")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{name}: not a UTF-8 text file (byte {exc.start + 1}); save it as UTF-8 CSV") \
            from None


def _cells(line: str) -> list[str]:
    """One CSV line's cells; quotes (as spreadsheets write them) only where the line has one."""
    return next(csv.reader([line])) if '"' in line else line.split(",")


def _is_header(cells: list[str]) -> bool:
    """A first row that holds no number is a header."""
    for cell in cells:
        try:
            float(cell)
        except ValueError:
            continue
        return False
    return True


def _check_header(name: str, number: int, cells: list[str], inputs) -> None:
    names = [v.name for v in inputs]
    expected = f"a header names the inputs in the .fis file's order: {','.join(names)}"
    if len(cells) != len(names):
        raise SceneError(f"{name}:{number}: a first row without a number is a header, and this one has "
                         f"{_count(len(cells), 'column')} for the system's {_count(len(names), 'input')} "
                         f"({expected}; values are separated by commas)")
    for i, (cell, wanted) in enumerate(zip(cells, names), start=1):
        if cell.strip() != wanted:
            raise SceneError(f"{name}:{number}: header column {i} {cell.strip()!r} is not input {i} "
                             f"{wanted!r} ({expected})")


def _check_work(name: str, rows: int, system, points: int) -> None:
    """Refuse an evaluation whose estimate is beyond MAX_EVALUATE_SECONDS, before it is begun."""
    rules, outputs = max(len(system.rules), 1), len(system.outputs)
    seconds = rows * points * rules * outputs * SECONDS_PER_SAMPLE
    if seconds > MAX_EVALUATE_SECONDS:
        raise SceneError(
            f"{name}: {_count(rows, 'row')} x {points:,} output samples x {_count(rules, 'rule')} x "
            f"{_count(outputs, 'output')}: about {_duration(seconds)} of inference, beyond the limit of "
            f"{_duration(MAX_EVALUATE_SECONDS)}; choose a smaller --points or split the rows"
        )


def _duration(seconds: float) -> str:
    for unit, size in (("d", 86_400), ("h", 3_600), ("min", 60)):
        if seconds >= size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"


def _convert(source: Path, out: Path, overwrite: bool) -> None:
    from bwr_twin.control.rulebase import RuleBase
    from bwr_twin.fis.convert import OUTPUT_SUFFIXES, fis_to_rulebase, load_system, output_text

    if out.suffix.lower() not in OUTPUT_SUFFIXES:
        raise SceneError(f"{out}: unknown output suffix {out.suffix!r} (known: {', '.join(OUTPUT_SUFFIXES)})")
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


WRITER = "bwr_twin.fis"  # the mark of every file convert and surface write (bwr_twin.ownership)


def _count(n: int, noun: str) -> str:
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


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
        check_recorded(out, None, "output")  # and unchanged since: its manifest beside it
    elif not out.parent.is_dir():
        raise SceneError(f"{out}: the directory {out.parent} does not exist")


def _write(out: Path, write) -> None:
    from bwr_twin.ownership import write_atomically

    try:
        write_atomically(out, write, record=True, option="output")
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
    leave(main())
