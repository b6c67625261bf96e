"""How the twin reads the text files people write (scenes, tunings, rule bases, .fis, users files).

An editor on Windows may save UTF-8 with a byte-order mark and CRLF line ends; both are read as
if they were not there, so that a file means the same whatever saved it.
"""

from __future__ import annotations

from pathlib import Path


def decode(data: bytes) -> str:
    """UTF-8 text without its byte-order mark, its line ends as "\\n" (raises UnicodeDecodeError)."""
    text = data.decode("utf-8-sig")
    return text.replace("\r\n", "\n").replace("\r", "\n")


def read_text(path: str | Path) -> str:
    """A UTF-8 text file, as `decode` reads it (raises OSError, UnicodeDecodeError)."""
    return decode(Path(path).read_bytes())


def version(path: str | Path) -> tuple:
    """What tells a changed file from the one read before (modification time, size, inode), or ()
    if it cannot be read: a key for caching what was read from it."""
    try:
        stat = Path(path).stat()
    except OSError:
        return ()
    return (stat.st_mtime_ns, stat.st_size, stat.st_ino)
