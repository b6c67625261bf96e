"""The live replay: a viser server with the 3D scene of one or several runs, a timeline, the
chooser of runs, a readout and charts.

The `Player` (bwr_twin.replay.player) owns what is shown and is the only thread that changes the
scene; the GUI panel (bwr_twin.replay.panel) only forwards what users do to it. The GUI is the
server's, not a tab's: every open tab shows and drives the same timeline.
"""

from __future__ import annotations

import contextlib
import io
import socket
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import viser

from bwr_twin.errors import BwrError
from bwr_twin.replay.player import Player
from bwr_twin.replay.recording import Plan, Recording
from bwr_twin.replay.runs import Run
from bwr_twin.replay.view import SceneView

if TYPE_CHECKING:
    from typing_extensions import Self

LOCAL_ONLY = "127.0.0.1"
PANEL_SHARE = 0.3  # of a typical window's width, covered by the (large) control panel


class ReplayServer:
    """Serves the replay of a plan (machine at its start pose, desired path; timeline once a
    recording is loaded) or of a recording, with other runs beside it, at `url` until `stop()`.
    A context manager.

    Args:
        source: a Recording to replay, or a Plan to show while its run is being simulated
            (then call `load` with the recording).
        host: interface to listen on; the default serves this machine only.
        port: TCP port; 0 picks a free one. A busy port is replaced by the next free one
            (`port` tells which).
        name: what the chooser calls the source's run (default: its scene's name).
        others: more runs to show with it (bwr_twin.replay.runs: at most MAX_RUNS in all, of its
            machine and path unless `side_by_side`).
        side_by_side: give each run its own rail, pile and path, in a row.
    """

    def __init__(self, source: Plan | Recording, *, host: str = LOCAL_ONLY, port: int = 8080,
                 name: str | None = None, others: Sequence[Run] = (), side_by_side: bool = False):
        plan = source.plan if isinstance(source, Recording) else source
        _check_listenable(host)
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; the caller prints the URL
            self.server = viser.ViserServer(
                host=host, port=port, label=f"BWR replay: {plan.title}", verbose=False
            )
        self.host = host
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        self.name = name or Path(plan.title).stem
        self.others = list(others)
        plans = [plan, *(run.recording.plan for run in self.others)]
        first = Run(source, self.name).label if isinstance(source, Recording) else self.name
        names = [first, *(run.label for run in self.others)]
        self.view = SceneView(self.server, plans, names=names, side_by_side=side_by_side, panel_share=PANEL_SHARE)
        for k, run in enumerate(self.others, start=1):
            self.view.attach(run.recording, k)
        self.player: Player | None = None
        self._waiting: list = []  # GUI elements shown while the run is being simulated
        if isinstance(source, Recording):
            self.load(source)
        else:
            reclaim = (f"the reclaim (its plan takes at most {plan.duration:g} s)"
                       if plan.via_stages and plan.activity == "reclaim" else f"the {plan.duration:g} s {plan.activity}")
            note = self.server.gui.add_markdown(f"Simulating {reclaim}; the timeline appears when it is done.")
            self._progress = self.server.gui.add_progress_bar(0.0, animated=True)
            self._waiting = [note, self._progress]

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        host = LOCAL_ONLY if self.host in ("0.0.0.0", "::", "") else self.host
        return f"http://{host}:{self.port}"

    def show_progress(self, share: float) -> None:
        """Show how much of the run is simulated, `share` from 0 to 1, until `load`."""
        if self._waiting and round(100 * share) != round(self._progress.value):
            self._progress.value = float(round(100 * share))

    def load(self, recording: Recording) -> None:
        """Show the finished run: its trail, the timeline, the chooser, the readout and the charts."""
        for element in self._waiting:
            element.remove()
        self._waiting = []
        self.view.attach(recording, 0)
        self.player = Player(self.server, self.view, [Run(recording, self.name), *self.others])

    def stop(self) -> None:
        """Stop the player and the server; the port is free when this returns."""
        if self.player is not None:
            self.player.stop()
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc_info) -> None:
        self.stop()


def _check_listenable(host: str) -> None:
    """Raise BwrError unless this machine can listen on `host` (viser would retry forever)."""
    try:
        family, kind, _, _, address = socket.getaddrinfo(host, 0, type=socket.SOCK_STREAM)[0]
        with socket.socket(family, kind) as probe:
            probe.bind(address)
    except OSError as exc:
        raise BwrError(f"cannot listen on host {host!r}: {exc.strerror or exc}") from None
