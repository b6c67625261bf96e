"""The guard around an engineer's code: a time budget a call, and exits that become errors.

A plug-in runs inside the twin's process, so it could end or hang it: `sys.exit()` at import or
in a method, `os._exit()`, a `compute()` that sleeps. The guard turns what can be caught into a
`PluginError` naming the file and the call (bwr_twin.config.plugins for the import,
bwr_twin.config.plugin_calls for the calls):

- `SystemExit` is caught where the plug-in's code is run;
- `os._exit`, looked up while a plug-in's code runs on the twin's main thread, raises `Exited`
  instead of ending the process (a direct `posix._exit` or a C library's `exit()` cannot be
  stopped: nothing in a process outlives them);
- a call that runs longer than the budget, `BWR_TWIN_CALL_BUDGET` s (10 s unless set; 0 turns
  the budget off), is interrupted: a watchdog thread that looks at the call in progress a few
  times a budget sends the main thread SIGALRM, whose handler raises `Overrun` there. A call
  blocked in C code (one long numpy operation) is interrupted when it returns to Python.

The budget holds on the main thread of a process that leaves SIGALRM to the twin (every command
line and a Gymnasium environment made in the main thread); elsewhere the calls run unwatched.
What a call costs the loop: one tuple and two attribute stores (`call`).
"""

from __future__ import annotations

import os
import signal
import threading
import time

BUDGET_VARIABLE = "BWR_TWIN_CALL_BUDGET"
DEFAULT_BUDGET_S = 10.0  # s a single call may take: a control period's work is some microseconds


class Overrun(BaseException):
    """Raised in the main thread when a plug-in's call runs beyond the budget (a BaseException, so
    that a plug-in's own `except Exception` does not swallow it)."""


class Exited(BaseException):
    """Raised in place of `os._exit(code)` while a plug-in's code runs."""

    def __init__(self, code):
        super().__init__(code)
        self.code = code


class _Watch:
    """The call in progress on the main thread, as (label, name, time), and what the watchdog saw."""

    call: tuple | None = None
    overrun: tuple | None = None
    budget: float = DEFAULT_BUDGET_S
    started = 0  # the id of the process that started the guard: a forked worker starts its own


watch = _Watch()
_real_exit = os._exit
_pid = os.getpid()


def budget() -> float:
    """The budget of one call in s (0: none), from BWR_TWIN_CALL_BUDGET."""
    text = os.environ.get(BUDGET_VARIABLE, "")
    try:
        value = float(text) if text.strip() else DEFAULT_BUDGET_S
    except ValueError:
        value = DEFAULT_BUDGET_S
    return value if value > 0 and value == value else 0.0


def start() -> None:
    """Watch the plug-ins' calls on this process's main thread: the os._exit guard, the SIGALRM
    handler and the watchdog thread, once a process. Does nothing off the main thread, or where
    SIGALRM already has a handler of someone else's."""
    global _pid
    if watch.started == os.getpid() or threading.current_thread() is not threading.main_thread():
        return
    watch.started = _pid = os.getpid()
    os._exit = _guarded_exit
    watch.budget = budget()
    if watch.budget <= 0 or signal.getsignal(signal.SIGALRM) not in (signal.SIG_DFL, None, _on_alarm):
        return
    signal.signal(signal.SIGALRM, _on_alarm)
    threading.Thread(target=_watchdog, args=(watch.budget, threading.get_ident()), name="bwr_twin plug-in watchdog",
                     daemon=True).start()


def _guarded_exit(code):
    if os.getpid() == _pid and watch.call is not None and threading.current_thread() is threading.main_thread():
        raise Exited(code)
    _real_exit(code)


def _on_alarm(signum, frame) -> None:
    current = watch.call
    if current is not None and current is watch.overrun:
        raise Overrun()


def _watchdog(limit: float, main: int) -> None:
    """Every `limit` / 10 s (at most 1 s): a call seen in progress for `limit` s is interrupted."""
    poll = min(max(limit / 10, 0.01), 1.0)
    seen, since = None, 0.0
    while True:
        time.sleep(poll)
        current = watch.call
        if current is None or current is not seen:
            seen, since = current, time.monotonic()
        elif time.monotonic() - since >= limit and watch.overrun is not current:
            watch.overrun = current
            signal.pthread_kill(main, signal.SIGALRM)
