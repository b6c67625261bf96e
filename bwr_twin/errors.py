"""The project's one error hierarchy, and how a command line reports it.

Every message names what was wrong (a file, a key, a via point, an axis), the limit it broke
and the value it had, so that the command line can print it as one line and exit.
"""

import gc
import sys
from collections.abc import Callable
from typing import NoReturn


class BwrError(Exception):
    """Base class of every error this package raises on purpose."""


class ModelError(BwrError):
    """An MJCF file is missing, does not compile or breaks the model contract."""


class UnreachableError(BwrError):
    """A bucket wheel centre position that no joint configuration reaches."""


class EnvelopeError(BwrError):
    """A joint value outside the machine's operating envelope."""


class SceneError(BwrError):
    """A scene or sweep file that cannot be read or breaks a rule."""


class SimulationError(BwrError):
    """A run that diverged or that MuJoCo warned about."""


class PluginError(BwrError):
    """An engineer's controller or rate control raised, or returned what it may not."""


SHOWN_ITEMS = 4  # items of a list a message shows, before the count of them all
SHOWN_CHARACTERS = 80  # characters of a value a message shows


def shown_items(items, form=repr) -> str:
    """A list for a message, short however long it is: '(0.0, 1.0, 0.0, 0.0, ... 2,500,000 in all)'."""
    items = list(items)
    head = ", ".join(form(item) for item in items[:SHOWN_ITEMS])
    return f"({head}, ... {len(items):,} in all)" if len(items) > SHOWN_ITEMS else f"({head})"


def shown_text(text: str) -> str:
    """A value as a message quotes it: repr, cut to SHOWN_CHARACTERS with the length it has."""
    if len(text) <= SHOWN_CHARACTERS:
        return repr(text)
    return f"{text[:SHOWN_CHARACTERS]!r}... ({len(text):,} characters)"


def exit_status(command: Callable[[], int], *, interrupted: str = "interrupted: nothing written") -> int:
    """Run a command line's work and return its exit status: a BwrError is one line on stderr
    and status 2, Ctrl-C the `interrupted` note and 130."""
    try:
        return command()
    except BwrError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(interrupted, file=sys.stderr)
        return 130


def leave(status: int) -> NoReturn:
    """End a command line's process with `status`. What the process holds is frozen first
    (gc.freeze): the interpreter's last collections would walk every object once more as it ends,
    some 0.3 s after a run (tools/bench.py's cli ratio), and nothing held needs collecting then."""
    gc.freeze()
    sys.exit(status)
