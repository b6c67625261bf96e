"""Arrays and rows from the files a user gives, checked before they are believed.

A file is hostile until checked: an .npz is a zip archive whose members each declare their dtype
and shape in a short header, and decompressing a member allocates what its header claims (a 32 MB
file can ask for 27 GiB). So `load_npz` opens the archive with zipfile, reads every wanted
member's header first (numpy.lib.format) and refuses a missing key, an object array, another dtype
kind, another number of dimensions or shape, and an array beyond its byte cap, all before a byte
of data is read; members nobody asked for are never read. A truncated, empty or foreign file is
one clean error naming it. `read_lines` streams a text file (a CSV) and refuses it as soon as it
holds more rows than its cap, before a number is parsed.

What the arrays mean (counts against the arrays they index, physical ranges) is checked by each
reader; `check_real`, `check_index` and `check_within` say it the same way everywhere. Every
message is one line, `{what}: ...`, naming the file (and the scene key that named it), the array
and the limit it broke.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.textfile import decode

MAX_ARRAY_BYTES = 1 << 30  # a member of an .npz file, unless its reader says less: 1 GiB
_KINDS = {"f": "real numbers", "i": "whole numbers", "u": "whole numbers", "U": "text", "b": "true or false",
          "c": "complex numbers"}
_HEADERS = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}


@dataclass(frozen=True)
class Member:
    """What one array of an .npz file must be.

    Attributes:
        kinds: the numpy dtype kinds it may have ("fiu": any real number; "iu": whole numbers;
            "U": text).
        shape: its shape, an int a fixed length and None any length (so its length gives the
            number of dimensions); None: any shape.
        max_bytes: the most its data may take in memory.
        required: whether the file must hold it.
    """

    kinds: str = "fiu"
    shape: tuple[int | None, ...] | None = None
    max_bytes: int = MAX_ARRAY_BYTES
    required: bool = True


SCALAR = Member(shape=())
TEXT = Member("U", (), max_bytes=4096)


def npz_keys(path: str | Path) -> frozenset[str]:
    """The arrays an .npz file names (none for a file that is not one), without reading any."""
    try:
        with zipfile.ZipFile(path) as archive:
            return frozenset(name.removesuffix(".npy") for name in archive.namelist() if name.endswith(".npy"))
    except (OSError, zipfile.BadZipFile, ValueError):
        return frozenset()


def load_npz(path: str | Path, spec: Mapping[str, Member], *, what: str, error: type[BwrError] = BwrError,
             mmap: bool = False, missing: str = "") -> dict[str, np.ndarray]:
    """The arrays of the .npz file at `path` that `spec` names, each checked against its Member
    by its header before any data is read; `error` (a BwrError) names `what` and the limit
    otherwise, adding `missing` to the message for an array the file lacks. With `mmap`, an
    array stored uncompressed is memory-mapped (read from disk as it is used), not read."""
    path = Path(path)
    try:
        with zipfile.ZipFile(path) as archive, open(path, "rb") as raw:
            members = {info.filename.removesuffix(".npy"): info for info in archive.infolist()
                       if info.filename.endswith(".npy")}
            absent = [key for key, member in spec.items() if member.required and key not in members]
            if absent:
                raise error(f"{what}: has no array '{absent[0]}'{missing}")
            wanted = [key for key in spec if key in members]
            headers = {key: _header(archive, members[key], key, spec[key], what, error) for key in wanted}
            return {key: _data(archive, raw, members[key], headers[key], mmap, key, what, error)
                    for key in wanted}
    except FileNotFoundError:
        raise error(f"{what}: no such file") from None
    except IsADirectoryError:
        raise error(f"{what}: is a folder, not an .npz file") from None
    except zipfile.BadZipFile as exc:
        raise error(f"{what}: not an .npz file, or a damaged or truncated one ({exc})") from None
    except (EOFError, zlib.error) as exc:
        raise error(f"{what}: a damaged or truncated .npz file ({exc or 'it ends early'})") from None
    except (NotImplementedError, RuntimeError) as exc:  # another compression, an encrypted member
        raise error(f"{what}: an .npz file numpy does not write ({exc})") from None
    except OSError as exc:
        raise error(f"{what}: cannot read it ({exc.strerror or exc})") from None


def _header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, key: str, member: Member, what: str,
            error: type[BwrError]) -> tuple[tuple[int, ...], bool, np.dtype]:
    """The member's (shape, Fortran order, dtype), refused unless `member` allows them."""
    with archive.open(info) as stream:
        try:
            version = np.lib.format.read_magic(stream)
            read = _HEADERS.get(version)
            if read is None:
                raise ValueError(f"array format version {version}")
            shape, fortran, dtype = read(stream)
        except ValueError as exc:
            raise error(f"{what}: array '{key}' has no readable .npy header ({exc})") from None
    if dtype.hasobject:
        raise error(f"{what}: array '{key}' holds Python objects ({dtype}), which are never read from a file; "
                    f"it must hold {_wanted(member.kinds)}")
    if dtype.kind not in member.kinds or dtype.fields is not None:
        raise error(f"{what}: array '{key}' holds {_KINDS.get(dtype.kind, 'values')} ({dtype}); "
                    f"it must hold {_wanted(member.kinds)}")
    if member.shape is not None and (len(shape) != len(member.shape) or any(
            want is not None and got != want for got, want in zip(shape, member.shape))):
        wanted = str(tuple("n" if n is None else n for n in member.shape)).replace("'", "")
        raise error(f"{what}: array '{key}' has the shape {shape}; it must be {wanted}")
    size = math.prod(shape) * dtype.itemsize
    if size > member.max_bytes:
        raise error(f"{what}: array '{key}' of shape {shape} ({dtype}) would take {size:,} bytes, more than the "
                    f"{member.max_bytes:,} it may take")
    return shape, fortran, dtype


def _data(archive: zipfile.ZipFile, raw, info: zipfile.ZipInfo, header: tuple, mmap: bool, key: str, what: str,
          error: type[BwrError]) -> np.ndarray:
    """The member's data, its header checked: read, or memory-mapped when stored uncompressed."""
    shape, fortran, dtype = header
    count, order = math.prod(shape), "F" if fortran else "C"
    with archive.open(info) as stream:
        version = np.lib.format.read_magic(stream)
        _HEADERS[version](stream)
        start = stream.tell()
        if mmap and info.compress_type == zipfile.ZIP_STORED and count > 0:
            raw.seek(info.header_offset)
            local = raw.read(30)  # the member's local header: its name and extra field follow
            offset = info.header_offset + 30 + int.from_bytes(local[26:28], "little") + int.from_bytes(
                local[28:30], "little") + start
            if offset + count * dtype.itemsize > Path(raw.name).stat().st_size:
                raise error(f"{what}: array '{key}' ends beyond the file (a truncated .npz file)")
            return np.memmap(raw.name, dtype=dtype, mode="r", offset=offset, shape=shape, order=order)
        data = stream.read(count * dtype.itemsize)
    if len(data) != count * dtype.itemsize:
        raise error(f"{what}: array '{key}' holds {len(data):,} of its {count * dtype.itemsize:,} bytes "
                    "(a truncated .npz file)")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order=order).copy()


def _wanted(kinds: str) -> str:
    return " or ".join(dict.fromkeys(_KINDS[k] for k in kinds))


def first_false(ok: np.ndarray) -> tuple[int, ...] | None:
    """The index of the first False of `ok` (in C order), or None if all are True."""
    bad = np.flatnonzero(~np.asarray(ok).ravel())
    return tuple(int(i) for i in np.unravel_index(bad[0], np.shape(ok))) if bad.size else None


def check_real(what: str, key: str, array: np.ndarray, error: type[BwrError] = BwrError) -> None:
    """`error` unless every value of the array `key` is a finite number."""
    at = first_false(np.isfinite(array))
    if at is not None:
        raise error(f"{what}: array '{key}' holds {array[at]} at {list(at)}, not a finite number")


def check_within(what: str, key: str, array: np.ndarray, low: float, high: float, limit: str,
                 error: type[BwrError] = BwrError) -> None:
    """`error` unless every value of the array `key` lies in [low, high]; `limit` says why."""
    at = first_false((array >= low) & (array <= high))
    if at is not None:
        raise error(f"{what}: array '{key}' holds {array[at]:g} at {list(at)}, outside [{low:g}, {high:g}] "
                    f"({limit})")


def check_index(what: str, key: str, array: np.ndarray, size: int, indexed: str,
                error: type[BwrError] = BwrError) -> None:
    """`error` unless every value of the array `key` indexes one of `size` items of `indexed`."""
    check_within(what, key, array, 0, size - 1, f"it indexes the {size:,} {indexed}", error)


def read_lines(path: str | Path, *, what: str, max_rows: int, max_bytes: int, error: type[BwrError] = BwrError,
               why: str = "") -> list[str]:
    """The lines of a UTF-8 text file (bwr_twin.textfile: without a byte-order mark, CRLF read as
    LF), streamed and refused as soon as it holds more than `max_rows` lines or `max_bytes`
    (`why`, if given, ends the message: what the limit is for)."""
    data = bytearray()
    try:
        with open(path, "rb") as stream:
            lines = 0
            while chunk := stream.read(1 << 20):
                data += chunk
                lines += chunk.count(b"\n")
                if lines > max_rows:
                    raise error(f"{what}: more than {max_rows:,} lines, the most it may hold{why}")
                if len(data) > max_bytes:
                    raise error(f"{what}: more than {max_bytes:,} bytes, the most it may hold{why}")
    except FileNotFoundError:
        raise error(f"{what}: no such file") from None
    except OSError as exc:
        raise error(f"{what}: cannot read it ({exc.strerror or exc})") from None
    try:
        return decode(bytes(data)).splitlines()
    except UnicodeDecodeError as exc:
        raise error(f"{what}: not a UTF-8 text file (byte {exc.start + 1})") from None
