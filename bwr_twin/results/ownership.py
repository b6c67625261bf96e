"""What the twin may replace: only what it wrote itself, never an input of the same command.

Every directory the twin writes (a run, a batch) holds a marker file, `.bwr_twin`, saying what
it is; every HTML export carries a generator tag. `check_output` is asked before any work starts
and again just before anything is replaced, so that a refusal costs nothing and loses nothing.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable
from pathlib import Path

from bwr_twin.errors import BwrError

MARKER_FILE = ".bwr_twin"
RESUMABLE = ("batch", "tuning")  # kinds of output that the same command continues rather than replaces
BATCH_LOCK_FILE = ".lock"  # a batch's flock, taken before its folder is marked
HTML_TAG = '<meta name="generator" content="bwr_twin.replay">'
_HTML_TAG_WITHIN = 4096  # bytes from the start of an export where its tag sits


def mark(folder: Path, kind: str, **details: object) -> None:
    """Leave the marker that lets the twin recognise `folder` as its own `kind` of output
    (written under a temporary name, then renamed: never half there)."""
    partial = folder / f"{MARKER_FILE}.partial-{os.getpid()}"
    partial.write_text(json.dumps({"written_by": "bwr_twin", "kind": kind, **details}) + "\n")
    os.replace(partial, folder / MARKER_FILE)


def marker(folder: Path) -> dict | None:
    """The marker of a directory the twin wrote, or None."""
    try:
        data = json.loads((folder / MARKER_FILE).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("written_by") == "bwr_twin" else None


def check_output(path: Path, kind: str, *, overwrite: bool = False, inputs: Iterable[Path] = (),
                 option: str = "--out") -> None:
    """Refuse (BwrError, one line) to write the output `path` of `kind` ("run", "batch" or
    "export") where that would replace something the twin did not write, an input of the same
    command, or the working directory; or where the folder cannot be written.

    An existing output of the same kind is replaced only with `overwrite`, or resumed if RESUMABLE.
    """
    target = path.resolve()
    cwd = Path.cwd().resolve()
    if target == cwd or target in cwd.parents:
        raise BwrError(f"{path}: is the working directory or holds it; {option} must name a new folder")
    for source in inputs:
        source = source.resolve()
        if source == target or target in source.parents:
            raise BwrError(f"{path}: is an input of this command ({source}); {option} must name another path")
    if path.exists() and not path.is_dir() and kind != "export":
        raise BwrError(f"{path}: exists and is not a folder the twin wrote; {option} must name a folder")
    if kind == "export":
        _check_export(path, option)
    elif path.exists():
        _check_folder(path, kind, overwrite, option)
    _check_writable(path.parent if kind == "export" or not path.exists() else path, option)


def _check_export(path: Path, option: str) -> None:
    if path.suffix.lower() != ".html":
        raise BwrError(f"{path}: {option} must name an .html file")
    if path.is_dir():
        raise BwrError(f"{path}: is a folder; {option} must name an .html file")
    if not path.parent.is_dir():
        raise BwrError(f"{path}: the folder {path.parent} does not exist")
    if path.exists():
        with path.open("rb") as f:
            own = HTML_TAG.encode() in f.read(_HTML_TAG_WITHIN)
        if not own:
            raise BwrError(f"{path}: exists and was not exported by the twin; it is left alone, "
                           f"choose another {option}")


def _check_folder(path: Path, kind: str, overwrite: bool, option: str) -> None:
    found = marker(path)
    if found is None:
        if kind == "batch" and all(entry.name == BATCH_LOCK_FILE for entry in path.iterdir()):
            return  # an empty folder made for the batch, or one a starting batch has locked
        raise BwrError(f"{path}: exists and holds files the twin did not write (no {MARKER_FILE} marker); "
                       f"it is left alone, choose another {option}")
    if found.get("kind") != kind:
        raise BwrError(f"{path}: holds the results of a {found.get('kind')}, not of a {kind}; "
                       f"choose another {option}")
    if kind not in RESUMABLE and not overwrite:
        raise BwrError(f"{path}: already exists; choose another {option} or pass --overwrite")


def _check_writable(folder: Path, option: str) -> None:
    """The nearest existing folder on the way to `folder` must be writable: the twin makes the rest."""
    while not folder.exists():
        if folder.parent == folder:
            break
        folder = folder.parent
    if not folder.is_dir():
        raise BwrError(f"{folder}: is a file, so {option} cannot be made inside it")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise BwrError(f"{folder}: is not writable (permission denied); choose another {option}")
