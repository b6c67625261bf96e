"""When the twin's control periods pass: on the client's `Step(n)` (lockstep mode) or on the wall
clock (real-time mode), with the drive setpoints, the watchdog and the methods that steer it.

A path of duration T at period h is T / h control periods to a client (`PeriodsLeft`, the start
text): the one that brings SimTime to T is its last. The twin's run has one more, the period
that starts at T (bwr_twin.sim.lockstep, as every run of the scene): it is advanced with that
last one, under the same setpoints, so that the run is complete when SimTime reads T.

The physics runs in the server's event loop, a period at a time (about 0.1 ms for one run on
this machine, docs/opcua.md): a Step of many periods gives the loop a turn every
`YIELD_AFTER` seconds of computing, so that the server keeps answering other clients.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable

import numpy as np
from asyncua import ua

from bwr_twin.opcua.methods import refuse_argument, status
from bwr_twin.serve import DEFAULT_WATCHDOG_PERIODS, LOCKSTEP, REALTIME
from bwr_twin.serve.address_space import AddressSpace
from bwr_twin.serve.machinery import item_state
from bwr_twin.sim.twin import Twin

YIELD_AFTER = 0.002  # s of computing in one go before the event loop gets a turn (real time: a pause as long)

Log = Callable[[str], None]


class Watchdog:
    """Real-time mode's watchdog: trips when no setpoint was written for `periods` control periods.

    Attributes:
        periods: control periods without a DriveSetpoint write that trip it; 0: no watchdog.
        tripped: latched until Reset, as a drive's fault.
        fed_at: the control period of the last setpoint write.
    """

    def __init__(self, periods: int, k: int):
        self.periods = periods
        self.clear(k)

    def clear(self, k: int) -> None:
        self.tripped = False
        self.fed_at = k

    def starved(self, k: int) -> bool:
        """At control period k: no write for `periods` periods (never without a watchdog)."""
        return bool(self.periods) and k - self.fed_at >= self.periods


class Clock:
    """The twin's time and drives: setpoints, modes, watchdog, overruns, and the methods.

    Attributes:
        setpoint: (3,) drive forces the drives hold, N, N m, N m (the DriveSetpoint nodes).
        running: real-time mode: the clock runs.
        watchdog: real-time mode: trips without a setpoint write in time.
        overruns: real-time mode: control periods computed later than the next one was due.
    """

    def __init__(self, twin: Twin, *, mode: str = LOCKSTEP, speed: float = 1.0,
                 watchdog_periods: int = DEFAULT_WATCHDOG_PERIODS, log: Log = print,
                 on_done: Callable[[Twin], None] | None = None):
        """`speed`: simulated seconds per wall-clock second; `watchdog_periods` 0: no watchdog."""
        self.twin, self.mode, self.speed = twin, mode, speed
        self.watchdog = Watchdog(watchdog_periods, twin.k)
        self._log, self._on_done = log, on_done
        self.space: AddressSpace | None = None
        self.listeners: list = []  # more publishers of the readings (the Machinery state, the alarms)
        self._lock = asyncio.Lock()  # one Step or Reset at a time
        self._task: asyncio.Task | None = None
        self._internal_write = False  # the server itself writes DriveSetpoint: not a PLC's write
        self._clear()

    def _clear(self) -> None:
        self.setpoint = np.zeros(3)
        self.running = False
        self.overruns = 0
        self.watchdog.clear(self.twin.k)

    # -- publishing and writes ---------------------------------------------------------------

    def readings(self) -> dict[str, object]:
        """Every published value by variable name (see address_space), and the MachineryItemState."""
        twin = self.twin
        state = item_state(mode=self.mode, running=self.running, started=twin.k > 0, done=twin.done,
                           diverged=twin.failure is not None, tripped=self.watchdog.tripped)
        return {**twin.reading, "PeriodsLeft": self.periods_left, "ControlPeriod": twin.period,
                "Running": self.running, "Mode": self.mode,
                "WatchdogTripped": self.watchdog.tripped, "Overruns": self.overruns, "MachineryItemState": state}

    @property
    def path_periods(self) -> int:
        """The control periods from SimTime 0 to the path's end (of a bench plan, the most it may take)."""
        return self.twin.samples - 1

    @property
    def periods_left(self) -> int:
        """The control periods until SimTime reads the path's end; 0 there."""
        return max(self.twin.periods_left - 1, 0)

    def _advance(self, setpoint: np.ndarray) -> None:
        """One control period; the one that brings SimTime to the path's end completes the run."""
        twin = self.twin
        twin.advance(setpoint)
        if twin.periods_left == 1 and twin.failure is None:
            twin.advance(setpoint)  # the run's period that starts at the end: nothing a client reads

    async def publish(self, *, setpoint: bool = False) -> None:
        """Publish the readings, with the limit switches that changed since the last time; with
        `setpoint`, the DriveSetpoint nodes too (after a Reset or trip)."""
        readings = {**self.readings(), "LimitSwitches": self.twin.take_limit_switches()}
        await self.space.publish(readings)
        for listener in self.listeners:
            await listener.publish(readings)
        if setpoint:
            self._internal_write = True
            try:
                await self.space.publish({"DriveSetpoint": self.setpoint})
            finally:
                self._internal_write = False

    def setpoint_setter(self, axis: int) -> Callable:
        """asyncua's value setter of axis's DriveSetpoint node: takes a PLC's write, or refuses it."""

        def setter(node_data, attribute, data_value: ua.DataValue) -> None:
            if not self._internal_write:
                value = data_value.Value.Value
                if not isinstance(value, float) or not math.isfinite(value):
                    raise ua.uaerrors.BadOutOfRange  # this node's result (bwr_twin.serve.writes)
                if self.watchdog.tripped:
                    raise ua.uaerrors.BadInvalidState  # latched until Reset, as a drive's fault
                self.setpoint[axis] = value
                self.watchdog.fed_at = self.twin.k
            node_data.attributes[attribute].value = data_value

        return setter

    # -- methods -----------------------------------------------------------------------------

    def methods(self) -> dict[str, Callable]:
        return {"Start": self.start, "Stop": self.stop, "Reset": self.reset, "Step": self.step}

    async def start(self, parent=None):
        if self.mode != REALTIME:
            return status(ua.StatusCodes.BadNotSupported)
        # Tripped, the clock may still run (at zero drive force): Start does not clear a trip, Reset does.
        if self._finished() or self.watchdog.tripped or self._lock.locked():  # the last: a Step under way
            return status(ua.StatusCodes.BadInvalidState)
        if self.running:
            return []
        self.running = True
        self._task = asyncio.create_task(self._run())
        await self.publish()
        return []

    async def stop(self, parent=None):
        if self.mode != REALTIME:
            return status(ua.StatusCodes.BadNotSupported)
        await self._stop_task()
        await self.publish()
        return []

    async def reset(self, parent=None):
        async with self._lock:
            await self._stop_task()
            self.twin.reset()
            self._clear()
            await self.publish(setpoint=True)
        return []

    async def step(self, parent, periods: ua.Variant):
        """Step(n): n control periods under the setpoints as they are now; SimTime after them."""
        n = periods.Value  # a UInt32 (bwr_twin.opcua.methods checked its type)
        if n < 1:
            return refuse_argument([ua.StatusCodes.BadOutOfRange])
        if self.running:
            return status(ua.StatusCodes.BadInvalidState)
        async with self._lock:
            if self._finished() or n > self.periods_left:
                return status(ua.StatusCodes.BadInvalidState)
            setpoint = self.setpoint.copy()  # a write during the Step counts from the next one
            computed_since = time.perf_counter()
            for _ in range(n):
                self._advance(setpoint)
                if time.perf_counter() - computed_since > YIELD_AFTER:
                    await asyncio.sleep(0)
                    computed_since = time.perf_counter()
            await self._after_periods()
        return [ua.Variant(self.twin.reading["SimTime"], ua.VariantType.Double)]

    # -- real time ---------------------------------------------------------------------------

    async def _run(self) -> None:
        """Advance a period every period / speed of wall-clock time until Stop or the path's end."""
        try:
            await self._tick_until_done()
        except Exception as exc:  # noqa: BLE001 - a clock that dies says so; the server goes on
            self.running = False
            self._log(f"error: the real-time clock stopped at SimTime {self.twin.reading['SimTime']:g} s: {exc!r}")
            await self.publish()

    async def _tick_until_done(self) -> None:
        twin = self.twin
        wall_period = twin.period / self.speed
        started = burst = time.perf_counter()  # burst: since the loop last had time to itself
        ticks = 0
        self.watchdog.fed_at = twin.k
        while not self._finished():
            ticks += 1
            due = started + ticks * wall_period
            now = time.perf_counter()
            if due > now:
                await asyncio.sleep(due - now)
                burst = time.perf_counter()
            elif now - burst > YIELD_AFTER:  # behind for a while: the server still gets half the time
                await asyncio.sleep(YIELD_AFTER)
                burst = time.perf_counter()
            else:
                await asyncio.sleep(0)
            if self.watchdog.starved(twin.k):
                await self._trip()
            self._advance(self.setpoint)
            if self._finished():
                self.running = False
            await self._after_periods()
            if time.perf_counter() > due + wall_period:  # computed and published after the next was due
                self.overruns += 1  # published with the next period

    async def _trip(self) -> None:
        if self.watchdog.tripped:
            return
        self.watchdog.tripped = True
        self.setpoint[:] = 0.0
        self._log(f"watchdog: no DriveSetpoint write for {self.watchdog.periods} control periods at "
                  f"SimTime {self.twin.reading['SimTime']:.2f} s; drives at zero until Reset")
        await self.publish(setpoint=True)

    async def _stop_task(self) -> None:
        self.running = False
        task, self._task = self._task, None
        if task is not None and task is not asyncio.current_task():
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    def _finished(self) -> bool:
        return self.twin.done or self.twin.failure is not None

    async def _after_periods(self) -> None:
        await self.publish()
        if self.twin.failure is not None:
            self.running = False
            self._log(f"error: the simulation diverged ({self.twin.failure}); Reset starts the path again")
        elif self.twin.done:
            self._log(f"path completed: its last control period, at SimTime {self.twin.reading['SimTime']:g} s, "
                      "advanced; Reset starts it again")
            if self._on_done is not None:
                self._on_done(self.twin)

    async def close(self) -> None:
        """Stop the real-time clock, if it runs."""
        await self._stop_task()
