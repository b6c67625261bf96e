"""`--out DIR`: a completed path's run directory, as `python -m bwr_twin.run` writes it.

Written off the event loop (the figures take seconds), only when the path was completed; a
later completion (after Reset) replaces it. Nothing is written for a path left unfinished.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path

from bwr_twin.errors import BwrError
from bwr_twin.ownership import check_output
from bwr_twin.results.rundir import write_run
from bwr_twin.sim.twin import Twin


class RunWriter:
    """Writes each completed run to `out` (replacing only what it or an earlier run wrote)."""

    def __init__(self, out: Path, *, overwrite: bool, plots: bool, inputs, log: Callable[[str], None]):
        """Raises BwrError at once if `out` may not be written (see bwr_twin.ownership)."""
        check_output(out, "run", overwrite=overwrite, inputs=inputs)
        self.out, self._overwrite, self._plots, self._log = out, overwrite, plots, log
        self._lock = asyncio.Lock()
        self._pending: set[asyncio.Task] = set()

    def __call__(self, twin: Twin) -> None:
        """The clock's `on_done`: take the run's result now, write it in the background."""
        try:
            result = twin.results()
        except BwrError as exc:
            self._log(f"error: {exc}; nothing written to {self.out}")
            return
        task = asyncio.get_running_loop().create_task(self._write(result))
        self._pending.add(task)
        task.add_done_callback(self._pending.discard)

    async def _write(self, result) -> None:
        async with self._lock:
            try:
                await asyncio.to_thread(write_run, result, self.out, overwrite=self._overwrite, plots=self._plots)
            except BwrError as exc:
                self._log(f"error: {exc}")
                return
            self._overwrite = True  # the folder is now this server's own run directory
            self._log(f"results in {self.out}/")

    async def finish(self) -> None:
        """Wait for the writes under way: a stopping server leaves no folder half-written."""
        if self._pending:
            await asyncio.gather(*self._pending)
