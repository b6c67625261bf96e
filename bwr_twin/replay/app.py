"""The live replay: a viser server with the 3D scene, a timeline, a readout and charts.

One `Player` thread owns the timeline. GUI callbacks (which viser runs on its own threads) only
queue actions; the player applies them between frames, advances time while playing and sends
each frame in one atomic batch. The GUI is the server's, not a tab's: every open tab shows and
drives the same timeline.
"""

from __future__ import annotations

import contextlib
import io
import queue
import socket
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import viser

from bwr_twin.errors import BwrError
from bwr_twin.replay import readout
from bwr_twin.replay.charts import charts
from bwr_twin.replay.recording import Plan, Recording
from bwr_twin.replay.view import SceneView

if TYPE_CHECKING:
    from typing_extensions import Self

FRAME_RATE = 30.0  # Hz, scene and time slider
READOUT_PERIOD = 0.1  # s between readout updates while playing
PLAYER_STOP_WAIT = 5.0  # s for the player's thread to finish its frame when the replay stops
CHART_PERIOD = 0.5  # s between time-marker updates while playing (each re-sends the charts' data)
SPEEDS = (1, 100)  # x real time, the speed slider's range
INITIAL_SPEED = 10
LOCAL_ONLY = "127.0.0.1"
MARK_SPACING = 0.05  # of the run: a via point's mark closer than this to the last labelled one is unlabelled
PANEL_SHARE = 0.3  # of a typical window's width, covered by the (large) control panel


class ReplayServer:
    """Serves the replay of a plan (machine at its start pose, desired path; timeline once a
    recording is loaded) or of a recording, at `url` until `stop()`. A context manager.

    Args:
        source: a Recording to replay, or a Plan to show while its run is being simulated
            (then call `load` with the recording).
        host: interface to listen on; the default serves this machine only.
        port: TCP port; 0 picks a free one. A busy port is replaced by the next free one
            (`port` tells which).
        ghost: another run of the same path and its name, shown as a translucent machine.
    """

    def __init__(self, source: Plan | Recording, *, host: str = LOCAL_ONLY, port: int = 8080,
                 ghost: tuple[Recording, str] | None = None):
        plan = source.plan if isinstance(source, Recording) else source
        _check_listenable(host)
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; the caller prints the URL
            self.server = viser.ViserServer(
                host=host, port=port, label=f"BWR replay: {plan.title}", verbose=False
            )
        self.host = host
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        self.view = SceneView(self.server, plan, panel_share=PANEL_SHARE)
        self.player: Player | None = None
        if ghost is not None:
            self.view.add_ghost(*ghost)
            self.server.gui.add_markdown(f"Translucent: **{ghost[1]}**")
        self._waiting: list = []  # GUI elements shown while the run is being simulated
        if isinstance(source, Recording):
            self.load(source)
        else:
            note = self.server.gui.add_markdown(
                f"Simulating the {plan.duration:g} s reclaim; the timeline appears when it is done."
            )
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
        """Show a finished run: its trail, the timeline, the readout and the charts."""
        for element in self._waiting:
            element.remove()
        self._waiting = []
        self.view.attach(recording)
        self.player = Player(self.server, self.view, recording)

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


def via_point_marks(times, names) -> tuple[float | tuple[float, str], ...]:
    """Time slider marks at the via points, labelled with their names (P1, P2, ...) unless a
    label would print over the one before (the Jump buttons name the landmarks)."""
    marks: list[float | tuple[float, str]] = []
    labelled = -float("inf")
    spacing = MARK_SPACING * float(times[-1] - times[0])
    for t, name in zip(times, names):
        if name and t - labelled >= spacing:
            marks.append((float(t), name))
            labelled = t
        else:
            marks.append(float(t))
    return tuple(marks)


class Player:
    """The timeline's one owner: time, play state and speed live here and change only on its thread."""

    def __init__(self, server: viser.ViserServer, view: SceneView, recording: Recording):
        self.server = server
        self.view = view
        self.recording = recording
        plan = recording.plan
        self.start, self.end = float(plan.time[0]), float(plan.time[-1])
        self.time = self.start
        self.playing = False
        self.speed = float(INITIAL_SPEED)
        self._actions: queue.Queue[Callable[[], None]] = queue.Queue()
        self._stopped = threading.Event()
        self._build_gui()
        self._readout_at = self._charts_at = float("-inf")  # wall times of the last updates
        self._scene_shows = self._readout_shows = self._charts_shows = None  # the replay times they show
        self._draw(time.perf_counter())
        self._thread = threading.Thread(target=self._run, name="replay-player", daemon=True)
        self._thread.start()

    # -- GUI: callbacks only queue actions ------------------------------------------------------

    def _build_gui(self) -> None:
        gui = self.server.gui
        plan = self.recording.plan
        step = float(plan.time[1] - plan.time[0])
        with gui.add_folder("Timeline"):
            self.play_button = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY)
            self.time_slider = gui.add_slider(
                "Time [s]",
                min=self.start,
                max=self.end,
                step=step,
                initial_value=self.start,
                marks=via_point_marks(plan.via_times, plan.names),
            )
            self.speed_slider = gui.add_slider(
                "Speed [x]",
                min=SPEEDS[0],
                max=SPEEDS[1],
                step=1,
                initial_value=INITIAL_SPEED,
                marks=(1, 10, 50, 100),
            )
            landmarks = dict(plan.landmarks)
            self.jump = gui.add_button_group("Jump to", list(landmarks))
        with gui.add_folder("Readout"):
            self.readout = gui.add_markdown("")
        with gui.add_folder("Charts"):
            self.charts = charts(self.recording)
            self.chart_handles = [
                gui.add_uplot(
                    chart.data(self.start),
                    chart.series,
                    title=chart.title,
                    scales=chart.scales,
                    axes=chart.axes,
                    aspect=1.6,
                )
                for chart in self.charts
            ]

        @self.play_button.on_click
        def _(_) -> None:
            self.toggle()

        @self.time_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            if event.client is not None:  # a user's drag, not the player's own update
                self.seek(float(self.time_slider.value))

        @self.speed_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            if event.client is not None:
                self.set_speed(float(self.speed_slider.value))

        @self.jump.on_click
        def _(event: viser.GuiEvent) -> None:
            self.seek(landmarks[event.target.value])

    # -- commands: safe from any thread, applied by the player's thread between frames ----------

    def toggle(self) -> None:
        """Play, or pause; Play at the end starts over."""
        self._actions.put(self._toggle)

    def seek(self, t: float) -> None:
        """Jump to time t (s), clamped to the run."""
        self._actions.put(lambda: self._seek(t))

    def set_speed(self, speed: float) -> None:
        """Play at `speed` times real time."""
        self._actions.put(lambda: self._set_speed(speed))

    def _toggle(self) -> None:
        if not self.playing and self.time >= self.end:
            self.time = self.start
        self._set_playing(not self.playing)

    def _set_playing(self, playing: bool) -> None:
        self.playing = playing
        self.play_button.label = "Pause" if playing else "Play"
        self.play_button.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def _set_speed(self, speed: float) -> None:
        self.speed = min(max(float(speed), SPEEDS[0]), SPEEDS[1])
        self.speed_slider.value = self.speed

    def _seek(self, t: float) -> None:
        self.time = min(max(t, self.start), self.end)

    # -- the loop --------------------------------------------------------------------------------

    def _run(self) -> None:
        period = 1.0 / FRAME_RATE
        last = time.perf_counter()
        while not self._stopped.is_set():
            deadline = last + period
            while (remaining := deadline - time.perf_counter()) > 0:
                try:
                    self._actions.get(timeout=remaining)()
                except queue.Empty:
                    break
            now = time.perf_counter()
            if self.playing:
                self.time = min(self.time + (now - last) * self.speed, self.end)
                if self.time >= self.end:
                    self._set_playing(False)
            last = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        """Send what changed: the scene and slider every frame, readout and charts less often."""
        t = self.time
        if t != self._scene_shows:
            with self.server.atomic():
                self.view.show(t)
                self.time_slider.value = t
            self._scene_shows = t
        if t != self._readout_shows and (not self.playing or now - self._readout_at >= READOUT_PERIOD):
            self.readout.content = readout.as_markdown(self.recording.at(t), self.recording.plan.duration)
            self._readout_at, self._readout_shows = now, t
        if t != self._charts_shows and (not self.playing or now - self._charts_at >= CHART_PERIOD):
            for chart, handle in zip(self.charts, self.chart_handles):
                handle.data = chart.data(t)
            self._charts_at, self._charts_shows = now, t

    def stop(self) -> None:
        self._stopped.set()
        self._thread.join(timeout=PLAYER_STOP_WAIT)  # a daemon: a frame stuck in viser must not hold the exit
