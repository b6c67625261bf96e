"""What the twin may replace: only what it wrote itself, never an input of the same command.

Every directory the twin writes (a run, a batch) holds a marker file, `.bwr_twin`, saying what
it is. Every file it writes carries its writer's mark in one fixed place and form, which a file
the twin did not write does not hold by chance (`written_by`): the first line of a .fis, .toml or
.fll is exactly `% written by WRITER` or `# written by WRITER`, of an .fcl `(* written by WRITER
*)`; a PNG has a text chunk `Software` of exactly WRITER; an SVG's leading metadata has WRITER as
its creator, a PDF's document information as its Creator; an HTML export's <head> opens with the
generator tag; an FMU's or an AASX package's zip archive comment is exactly WRITER; an XML file's
line after its declaration is `<!-- written by WRITER -->`; an MP4 video's comment tag (the value of its
moov/udta/meta/ilst/(c)cmt box, where ffmpeg's `-metadata comment=WRITER` puts it) is exactly
WRITER. Text that merely mentions the writer anywhere else does not count. `check_output` is
asked before any work starts and again just before anything is replaced, so that a refusal costs
nothing and loses nothing; `write_atomically` then puts a file in place whole or not at all.

A mark says who wrote a file, not that it is unchanged: the manifest says that. A folder's marker
lists every file the twin wrote in it (`record_folder`, `record_file`), by path, with its size and
sha256; a single output (an HTML export, a video, an FMU, a .fis, a picture) has its own beside it,
the hidden `.NAME.bwr_twin`. An output is replaced only if everything in it is what its manifest
records (`check_manifest`): an entry the twin did not write (an engineer's notes, a subfolder) or a
file changed since (another sha256) is refused, named, and left alone with everything else. A
writer first removes the temporary files its output's earlier writers left when killed
(`remove_stale_partials`): only names of the twin's own pattern, `.NAME.partial-PID` (a folder:
`.NAME.partial-PID-XXXX`, holding a marker), and only if process PID is gone.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import struct
import zipfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from bwr_twin.errors import BwrError

MARKER_FILE = ".bwr_twin"
RESUMABLE = ("batch", "tuning")  # kinds of output that the same command continues rather than replaces
BATCH_LOCK_FILE = ".lock"  # a batch's flock, taken before its folder is marked
HTML_GENERATOR = '<meta name="generator" content="{}">'  # the first thing in an HTML file's <head>
HTML_TAG = HTML_GENERATOR.format("bwr_twin.replay")
FMU_WRITER = "bwr_twin.export fmu"  # an FMU's zip archive comment
AAS_WRITER = "bwr_twin.export aas"  # an AASX package's zip archive comment
NODESET_WRITER = "bwr_twin.serve"  # a UA NodeSet2 file's comment after the XML declaration
VIDEO_WRITER = "bwr_twin.replay video"  # an MP4's comment tag
# The single files the twin writes, by kind of output: (suffix, what marks them as the twin's,
# whether replacing one needs --overwrite).
_FILE_KINDS = {"export": (".html", "bwr_twin.replay", False), "fmu": (".fmu", FMU_WRITER, True),
               "aas": (".aasx", AAS_WRITER, True),
               "nodeset": (".xml", NODESET_WRITER, True), "video": (".mp4", VIDEO_WRITER, False)}
_HEAD_WITHIN = 4096  # bytes from the start of a file where its mark sits (all but a PDF's)
COMMENT_SIGNS = {".fis": "%", ".toml": "#", ".fll": "#", ".fcl": "(*"}  # the text files the twin writes, by suffix
_COMMENT_ENDS = {".fcl": " *)"}  # where a comment must be closed on its line
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_MP4_COMMENT = (b"moov", b"udta", b"meta", b"ilst", b"\xa9cmt", b"data")  # the boxes down to the comment
_MP4_FULL_BOXES = (b"meta",)  # boxes whose children follow 4 bytes of version and flags
_MP4_DATA_HEAD = 8  # a data box's type and locale, before its value
_MP4_VALUE_MAX = 4096  # bytes of a comment read: a mark is short


def text_mark(writer: str, suffix: str) -> str:
    """The first line of a text file `writer` writes, without its line end."""
    return f"{COMMENT_SIGNS[suffix.lower()]} written by {writer}{_COMMENT_ENDS.get(suffix.lower(), '')}"


def picture_metadata(writer: str, suffix: str) -> dict[str, str]:
    """Matplotlib's savefig metadata that marks a picture as `writer`'s."""
    return {"Software" if suffix.lower() == ".png" else "Creator": writer}


def written_by(path: Path, writer: str, *, suffix: str | None = None) -> bool:
    """Whether the file `path` holds `writer`'s mark in its place (see the module's docstring);
    `suffix` tells the kind of file where its name does not (a temporary name)."""
    suffix = (suffix or path.suffix).lower()
    if suffix in (".fmu", ".aasx"):
        return _zip_comment(path) == writer.encode()
    if suffix == ".xml":
        return _xml_comment(path) == writer.encode()
    if suffix == ".mp4":
        return _mp4_comment(path) == writer.encode()
    try:
        with path.open("rb") as f:
            data = f.read() if suffix == ".pdf" else f.read(_HEAD_WITHIN)
    except OSError:
        return False
    if suffix in COMMENT_SIGNS:
        first = data.split(b"\n", 1)[0].removeprefix(b"\xef\xbb\xbf").rstrip(b"\r")
        return first == text_mark(writer, suffix).encode()
    if suffix == ".png":
        return _png_text(data).get(b"Software") == writer.encode()
    if suffix == ".svg":
        return re.match(rb"<\?xml[^>]*\?>\s*(?:<!DOCTYPE[^>]*>\s*)?<svg[^>]*>\s*<metadata>(?:(?!</metadata>).)*?"
                        rb"<dc:creator>\s*<cc:Agent>\s*<dc:title>" + re.escape(writer.encode()) + rb"</dc:title>",
                        data, re.DOTALL) is not None
    if suffix == ".pdf":
        return _pdf_creator(data) == writer.encode()
    if suffix == ".html":
        head = data.find(b"<head>")
        return head >= 0 and data.startswith(HTML_GENERATOR.format(writer).encode(), head + len(b"<head>"))
    return False


def xml_mark(writer: str) -> str:
    """The line right after the XML declaration of an XML file `writer` writes."""
    return f"<!-- written by {writer} -->"


def _xml_comment(path: Path) -> bytes | None:
    """The writer named in an XML file's comment line right after its declaration, or None."""
    try:
        with path.open("rb") as f:
            head = f.read(_HEAD_WITHIN).removeprefix(b"\xef\xbb\xbf")
    except OSError:
        return None
    found = re.match(rb"<\?xml[^>]*\?>\r?\n<!-- written by (.+?) -->\r?\n", head)
    return found.group(1) if found else None


def _zip_comment(path: Path) -> bytes | None:
    """The archive comment of a zip file (an FMU), or None if it is not one."""
    try:
        with zipfile.ZipFile(path) as archive:
            return archive.comment
    except (OSError, zipfile.BadZipFile):
        return None


def _mp4_comment(path: Path) -> bytes | None:
    """The comment tag of an MP4 file, or None if it is not an MP4 file or has none. Reads the
    box headers and seeks past the rest: the video data is never read."""
    try:
        with path.open("rb") as f:
            end = f.seek(0, os.SEEK_END)
            f.seek(4)
            if f.read(4) != b"ftyp":
                return None
            return _mp4_box(f, 0, end, _MP4_COMMENT)
    except (OSError, struct.error):  # unreadable, or a box header cut short
        return None


def _mp4_box(f, start: int, end: int, path: tuple[bytes, ...]) -> bytes | None:
    """The value at the end of the box `path` among the boxes between `start` and `end`."""
    at = start
    while at + 8 <= end:
        f.seek(at)
        size, kind = struct.unpack(">I4s", f.read(8))
        head = 8
        if size == 1:  # a 64-bit size follows the type
            size, head = struct.unpack(">Q", f.read(8))[0], 16
        elif size == 0:  # the box runs to the end of its parent
            size = end - at
        if size < head or at + size > end:
            return None
        if kind == path[0]:
            body = at + head + (4 if kind in _MP4_FULL_BOXES else 0)
            if len(path) > 1:
                return _mp4_box(f, body, at + size, path[1:])
            f.seek(body)
            return f.read(min(at + size - body, _MP4_VALUE_MAX))[_MP4_DATA_HEAD:]
        at += size
    return None


def _png_text(data: bytes) -> dict[bytes, bytes]:
    """The tEXt chunks before the image data of a PNG's first bytes: keyword -> text."""
    found, at = {}, len(_PNG_SIGNATURE)
    if not data.startswith(_PNG_SIGNATURE):
        return found
    while at + 8 <= len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        if kind == b"IDAT":
            break
        if kind == b"tEXt":
            keyword, _, text = data[at + 8:at + 8 + length].partition(b"\0")
            found[keyword] = text
        at += 12 + length  # length, type, data, CRC
    return found


def _pdf_creator(data: bytes) -> bytes | None:
    """The Creator of a PDF's document information, the object its last trailer names as /Info."""
    trailer = re.search(rb"trailer\s*<<[^>]*/Info (\d+) 0 R[^>]*>>\s*startxref\s*\d+\s*%%EOF\s*$", data[-1024:])
    if not data.startswith(b"%PDF-") or trailer is None:
        return None
    info = re.search(rb"(?:^|\n)" + trailer[1] + rb" 0 obj\s*<<(.*?)>>\s*endobj", data, re.DOTALL)
    creator = re.search(rb"/Creator \(([^)]*)\)", info[1]) if info else None
    return creator[1] if creator else None


def mark(folder: Path, kind: str, **details: object) -> None:
    """Leave the marker that lets the twin recognise `folder` as its own `kind` of output, its
    manifest empty (written under a temporary name, then renamed: never half there)."""
    _write_marker(folder, {"written_by": "bwr_twin", "kind": kind, **details, FILES: {}})


def _write_marker(folder: Path, data: dict, name: str = MARKER_FILE) -> None:
    partial = folder / f"{name}.partial-{os.getpid()}"
    partial.write_text(json.dumps(data) + "\n")
    os.replace(partial, folder / name)


def marker(folder: Path) -> dict | None:
    """The marker of a directory the twin wrote, or None."""
    return _read_marker(folder / MARKER_FILE)


def _read_marker(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and data.get("written_by") == "bwr_twin" else None


# --- the manifest: what the twin wrote, file by file ------------------------------------------------

FILES = "files"  # the marker's key of the manifest: {path relative to the folder: [size, sha256]}
PENDING = "pending"  # the same of a file about to take its name: either is the twin's, if killed between
_TEMPORARY = re.compile(r"\..+\.(?:partial|old)-[^/]+")  # the twin's temporary names, never recorded
_HASH_CHUNK = 1 << 20


def file_record(path: Path) -> list:
    """[size in bytes, sha256 in hex] of a file."""
    digest = hashlib.sha256()
    with path.open("rb") as f:
        while chunk := f.read(_HASH_CHUNK):
            digest.update(chunk)
    return [path.stat().st_size, digest.hexdigest()]


def sidecar(path: Path) -> Path:
    """The manifest of a single output `path`: the hidden `.NAME.bwr_twin` beside it."""
    return path.parent / f".{path.name}{MARKER_FILE}"


def _walk(folder: Path, *, nested: bool, top: bool = True) -> Iterator[tuple[Path, str]]:
    """(path, path relative to `folder`) of every entry under `folder`, parents first, but for its
    marker, a batch's lock and the twin's temporary names; without `nested`, a subfolder with a
    marker of its own (a batch's run) is given but not entered."""
    for entry in sorted(folder.iterdir()):
        if _TEMPORARY.fullmatch(entry.name) or (top and entry.name in (MARKER_FILE, BATCH_LOCK_FILE)):
            continue
        yield entry, entry.name
        if entry.is_dir() and not entry.is_symlink() and (nested or marker(entry) is None):
            yield from ((path, f"{entry.name}/{relative}") for path, relative in _walk(entry, nested=True, top=False))


def record_folder(folder: Path) -> None:
    """List every file under the marked `folder` in its marker, with its size and sha256."""
    files = {relative: file_record(path) for path, relative in _walk(folder, nested=True) if path.is_file()}
    _write_marker(folder, {**(marker(folder) or {}), FILES: files})


def record_file(path: Path, owner: Path | None = None, *, entry: list | None = None, pending: bool = False) -> None:
    """Record the file `path` the twin just wrote (or, `pending`, the `entry` of the file about to
    replace it): in the marker of the folder `owner` that holds it, or in its own manifest beside it."""
    entry = entry or file_record(path)
    if owner is None:
        found = (_read_marker(sidecar(path)) or {}) if pending else {}
        relative, store, name = path.name, path.parent, sidecar(path).name
    else:
        found = marker(owner) or {}
        relative, store, name = path.relative_to(owner).as_posix(), owner, MARKER_FILE
    files, waiting = _dict(found.get(FILES)), _dict(found.get(PENDING))
    if pending:
        waiting[relative] = entry
    else:
        files[relative] = entry
        waiting.pop(relative, None)
    _write_marker(store, {**found, "written_by": "bwr_twin", FILES: files, PENDING: waiting}, name)


def _dict(value: object) -> dict:
    return dict(value) if isinstance(value, dict) else {}


def check_manifest(folder: Path, *, option: str = "--out", nested: bool = True, repairs: Iterable[str] = ()) -> None:
    """Refuse (BwrError, naming it) the first entry under the marked `folder` that its manifest
    does not record as it is: a file or folder the twin did not write, or a file changed since.
    A recorded file that is gone loses nothing. Without `nested` a subfolder with its own marker
    is not looked into (a batch's run: it is checked when replaced); `repairs` are files whose
    change the writer repairs (a batch's damaged metrics.json)."""
    found = marker(folder) or {}
    files = found.get(FILES)
    if not isinstance(files, dict):
        raise BwrError(f"{folder}: holds no record of the files the twin wrote in it (an earlier version wrote "
                       f"it); move it away, or choose another {option}")
    known = {**_dict(found.get(PENDING)), **files}
    folders = {"/".join(relative.split("/")[:k]) for relative in known for k in range(1, relative.count("/") + 1)}
    for path, relative in _walk(folder, nested=nested):
        if path.is_dir() and not path.is_symlink():
            if relative in folders or (not nested and marker(path) is not None):
                continue
        elif path.is_file() and not path.is_symlink() and relative in known:
            if relative in repairs or _unchanged(path, found, relative):
                continue
            raise _not_as_written(path, folder / MARKER_FILE, option, changed=True)
        raise _not_as_written(path, folder / MARKER_FILE, option, changed=False)


def _not_as_written(path: Path, manifest: Path, option: str, *, changed: bool) -> BwrError:
    why = (f"changed since the twin wrote it (its size or sha256 is not the one in {manifest})" if changed
           else f"was not written by the twin (not in {manifest})")
    return BwrError(f"{path}: {why}; the twin replaces only what it wrote: move it away, or choose another {option}")


def check_resumed(folder: Path, option: str = "--out") -> None:
    """Refuse to continue a batch or tuning in `folder` if it holds anything its manifest does not
    record as it is (check_manifest), but for the marked folders of its runs, each checked when it
    is replaced. A folder marked before the twin kept manifests is resumed as before."""
    if FILES in (marker(folder) or {}):
        check_manifest(folder, option=option, nested=False)


def _unchanged(path: Path, found: dict, relative: str) -> bool:
    """Whether the manifest `found` records the file `path` (at `relative`) as it is."""
    recorded = [_dict(found.get(key)).get(relative) for key in (FILES, PENDING)]
    recorded = [entry for entry in recorded if isinstance(entry, list) and len(entry) == 2]
    return any(path.stat().st_size == entry[0] for entry in recorded) and file_record(path) in recorded


def check_recorded(path: Path, owner: Path | None, option: str) -> None:
    """Refuse to replace the existing file `path` unless its manifest (the marker of the folder
    `owner`, or its own beside it) records it as it is. A folder marked before the twin kept
    manifests (no list in its marker) is resumed as before."""
    if not path.exists() and not path.is_symlink():
        return
    if owner is None:
        found = _read_marker(sidecar(path)) or {}
        where, relative = sidecar(path), path.name
        if not isinstance(found.get(FILES), dict):
            raise BwrError(f"{path}: holds no record of what the twin wrote (no {where.name} beside it); move "
                           f"it away, or choose another {option}")
    else:
        found = marker(owner) or {}
        where, relative = owner / MARKER_FILE, path.relative_to(owner).as_posix()
        if not isinstance(found.get(FILES), dict):
            return
    known = {**_dict(found.get(PENDING)), **found[FILES]}
    if relative not in known or not path.is_file() or path.is_symlink():
        raise _not_as_written(path, where, option, changed=False)
    if not _unchanged(path, found, relative):
        raise _not_as_written(path, where, option, changed=True)


def remove_stale_partials(path: Path) -> None:
    """Remove what killed writers of the output `path` left beside it: files `.NAME.partial-PID`
    and marked folders `.NAME.partial-PID-XXXX` whose process PID is gone. Nothing else: not a name
    of another pattern, not one of a process still running (it may be writing)."""
    pattern = re.compile(rf"\.{re.escape(path.name)}\.partial-(\d+)(?:-[A-Za-z0-9_]+)?")
    try:
        entries = list(path.parent.iterdir())
    except OSError:
        return
    for entry in entries:
        found = pattern.fullmatch(entry.name)
        if found is None or entry.is_symlink() or _running(int(found[1])):
            continue
        if entry.is_dir():
            if (entry / MARKER_FILE).is_file():
                shutil.rmtree(entry, ignore_errors=True)
        elif entry.is_file():
            entry.unlink(missing_ok=True)


def _running(pid: int) -> bool:
    """Whether process `pid` exists (this one, another user's or a zombie too)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return pid > 0
    return True


def check_output(path: Path, kind: str, *, overwrite: bool = False, inputs: Iterable[Path] = (),
                 option: str = "--out", repairs: Iterable[str] = ()) -> None:
    """Refuse (BwrError, one line) to write the output `path` of `kind` ("run", "batch", "export",
    "video", ...) where that would replace something the twin did not write, an input of the same
    command, or the working directory; or where the folder cannot be written.

    An existing output of the same kind is replaced only with `overwrite`, or resumed if RESUMABLE,
    and only if it holds nothing but what its manifest records (`check_manifest`; `repairs` are
    files changed by damage the writer repairs).
    """
    target = path.resolve()
    cwd = Path.cwd().resolve()
    if target == cwd or target in cwd.parents:
        raise BwrError(f"{path}: is the working directory or holds it; {option} must name a new folder")
    for source in inputs:
        source = source.resolve()
        if source == target or target in source.parents:
            raise BwrError(f"{path}: is an input of this command ({source}); {option} must name another path")
    single_file = kind in _FILE_KINDS
    if path.exists() and not path.is_dir() and not single_file:
        raise BwrError(f"{path}: exists and is not a folder the twin wrote; {option} must name a folder")
    if single_file:
        _check_file(path, *_FILE_KINDS[kind], overwrite, option)
    elif path.exists():
        _check_folder(path, kind, overwrite, option, repairs)
    _check_writable(path.parent if single_file or not path.exists() else path, option)


def _check_file(path: Path, suffix: str, writer: str, needs_overwrite: bool, overwrite: bool, option: str) -> None:
    if path.suffix.lower() != suffix:
        raise BwrError(f"{path}: {option} must name an {suffix} file")
    if path.is_dir():
        raise BwrError(f"{path}: is a folder; {option} must name an {suffix} file")
    if not path.parent.is_dir():
        raise BwrError(f"{path}: the folder {path.parent} does not exist")
    if path.exists():
        if not written_by(path, writer):
            raise BwrError(f"{path}: exists and was not written by the twin; it is left alone, "
                           f"choose another {option}")
        if needs_overwrite and not overwrite:
            raise BwrError(f"{path}: already exists; choose another {option} or pass --overwrite")
        check_recorded(path, None, option)


def _check_folder(path: Path, kind: str, overwrite: bool, option: str, repairs: Iterable[str]) -> None:
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
    if kind not in RESUMABLE:  # one RESUMABLE is checked by check_resumed once it is known to be the same work's
        check_manifest(path, option=option, repairs=repairs)


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


def write_atomically(path: Path, write: Callable[[Path], None], *, owner: Path | None = None,
                     record: bool = False, option: str = "--out") -> None:
    """Call write(temporary path), then rename the file into place; no partial file is left, and
    those killed writers of `path` left are removed first (remove_stale_partials). With `owner`
    (the marked folder holding `path`) or `record` (a single output, its manifest beside it), an
    existing `path` is replaced only if its manifest records it as it is, and the new file is
    recorded."""
    remove_stale_partials(path)
    temporary = path.parent / f".{path.name}.partial-{os.getpid()}"
    try:
        write(temporary)
        if owner is not None or record:
            check_recorded(path, owner, option)
            entry = file_record(temporary)
            record_file(path, owner, entry=entry, pending=True)  # killed before the rename or after: either is known
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
    if owner is not None or record:
        record_file(path, owner, entry=entry)
