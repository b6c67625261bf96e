"""An engineer's controller or rate control, called so that its failures are its own.

Whatever a plug-in raises (SystemExit included) becomes one line that names its class, its file
and the call, what it raised and when (simulated time): a `PluginError`; so does an `os._exit()`
and a call that runs beyond its time budget (bwr_twin.config.plugin_guard). What it returns is
checked before it reaches the plant: the wrong shape, None, strings or complex numbers fail the
lockstep the same way; a non-finite value fails only the runs it was returned for (the loop
stops them, `Lockstep.advance`).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np

from bwr_twin.config import plugin_guard
from bwr_twin.config.plugin_guard import BUDGET_VARIABLE, Exited, Overrun, watch
from bwr_twin.config.plugins import is_file_reference
from bwr_twin.errors import PluginError


def describe(type_name: str, cls: type) -> str:
    """How a message names a plug-in: 'my_pid.py:MyPid' as the scene does, or 'pid (PidController)'."""
    return type_name if is_file_reference(type_name) else f"{type_name} ({cls.__name__})"


def construct(label: str, cls: type, *args: Any) -> Any:
    """cls(*args); PluginError naming `label` if its __init__ raises, exits or overruns the budget.
    Starts the guard of the calls that follow (bwr_twin.config.plugin_guard)."""
    plugin_guard.start()
    return call(label, cls, f"{cls.__name__}.__init__", None, *args)


def call(label: str, method: Callable, name: str, time: float | None, *args: Any) -> Any:
    """method(*args); PluginError naming `label`, the call and the simulated `time` (s; None:
    before the run) if it raises, exits or runs beyond the budget of a call."""
    watch.call = (label, name, time)  # what the watchdog sees: all the guard costs a call
    try:
        return method(*args)
    except Overrun:
        raise PluginError(_overrun(label, name, time)) from None
    except Exited as exc:
        raise PluginError(f"{label}: {name}() called os._exit({exc.code}){_at(time)}") from None
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - an engineer's code: say whose and where
        raise PluginError(f"{label}: {name}() raised {_raised(exc)}{_at(time)}") from None
    finally:
        watch.call = None


def _at(time: float | None) -> str:
    return "" if time is None else f" at t = {time:.2f} s"


def reported(label: str, name: str, value: Any) -> Any:
    """`value`, a plug-in's report for metrics.json, if JSON can hold it; PluginError naming what
    it cannot (a set, an object, a dict with keys that are not strings)."""
    try:
        json.dumps(value)
    except (TypeError, ValueError, RecursionError) as exc:
        raise PluginError(f"{label}: its {name} cannot be written as JSON ({exc}); report numbers, strings, "
                          f"booleans, None, lists and dicts with string keys: {_short(value)}") from None
    return value


def _overrun(label: str, name: str, time: float | None) -> str:
    return (f"{label}: {name}() ran longer than its budget of {watch.budget:g} s a call{_at(time)} and was stopped; "
            f"set {BUDGET_VARIABLE} (s, 0 for none) to give it longer")


def checked(label: str, name: str, value: Any, shape: tuple[int, ...], time: float) -> np.ndarray:
    """`value` as a float64 array of `shape`; PluginError naming what it was instead."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == shape:
        return value  # the way every well-behaved plug-in returns
    what = None
    if value is None:
        what = "None"
    else:
        try:
            array = np.asarray(value)
        except Exception:  # noqa: BLE001 - whatever it is, it is not an array of numbers
            array = None
        if array is None or array.dtype.kind not in "fiu":
            kind = "complex numbers" if array is not None and array.dtype.kind == "c" else type(value).__name__
            what = f"{kind} ({_short(value)})"
        elif array.shape != shape:
            what = f"an array of shape {array.shape}"
        else:
            return array.astype(np.float64)
    expected = "x".join(map(str, shape))
    raise PluginError(f"{label}: {name}() returned {what} at t = {time:.2f} s; it must return a "
                      f"({expected}) array of numbers")


def _raised(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
