"""The player: the one owner of what the replay shows, on a thread of its own.

Time, play state and speed, which runs are shown and how the machines are painted live here and
change only on this thread. GUI callbacks (which viser runs on its own threads) only queue actions
through the commands below; the player applies them between frames, advances time while playing
and sends each frame in one atomic batch.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Sequence

import viser

from bwr_twin.replay.panel import INITIAL_SPEED, SPEEDS, Panel
from bwr_twin.replay.pile import PILE_COLOURS
from bwr_twin.replay.runs import Run
from bwr_twin.replay.scan_view import PILE_SHOWN
from bwr_twin.replay.view import SceneView

FRAME_RATE = 30.0  # Hz, scene and time slider (the charts' cursor follows the slider)
READOUT_PERIOD = 0.1  # s between readout updates while playing
PLAYER_STOP_WAIT = 5.0  # s for the player's thread to finish its frame when the replay stops


class Playhead:
    """Replay time, kept between the runs' start and end, and whether and how fast it advances;
    like `Shown`, changed only on the player's thread."""

    def __init__(self, start: float, end: float):
        self.start, self.end = start, end
        self.time = start
        self.playing = False
        self.speed = float(INITIAL_SPEED)

    def seek(self, t: float) -> None:
        self.time = min(max(t, self.start), self.end)

    def advance(self, seconds: float) -> None:
        """Move on by `seconds` of wall time at the speed; stop playing at the end."""
        self.time = min(self.time + seconds * self.speed, self.end)
        if self.time >= self.end:
            self.playing = False


class Shown:
    """What the view shows: which runs, with a run that scanned which pile ("true" or "scanned")
    and its fan, and with a pile of grade its colours (by "ore" or by its top layer's "grade")."""

    def __init__(self, runs: int):
        self.runs = [True] * runs
        self.pile, self.fan = "true", True
        self.pile_colour = "ore"


class Player:
    """Plays `runs` in `view` and its GUI panel on `server`; commands are safe from any thread.

    `time`, `playing`, `speed`, `start` and `end` read its `Playhead`; `shown`, `pile_shown`,
    `fan_shown` and `pile_colour` what it shows.
    """

    def __init__(self, server: viser.ViserServer, view: SceneView, runs: Sequence[Run]):
        self.server, self.view, self.runs = server, view, list(runs)
        self._head = Playhead(min(float(run.recording.plan.time[0]) for run in self.runs),
                              max(float(run.recording.plan.time[-1]) for run in self.runs))
        self._shown = Shown(len(self.runs))
        self._actions: queue.Queue[Callable[[], None]] = queue.Queue()
        self._stopped = threading.Event()
        self.panel = Panel(server, self.runs, self, scanning=view.scanning, grade=view.grade_scale)
        self._readout_at = float("-inf")  # wall time of the last readout
        self._scene_shows = self._readout_shows = None  # the replay times they show
        self._draw(time.perf_counter())
        self._thread = threading.Thread(target=self._run, name="replay-player", daemon=True)
        self._thread.start()

    @property
    def start(self) -> float:
        return self._head.start

    @property
    def end(self) -> float:
        return self._head.end

    @property
    def time(self) -> float:
        return self._head.time

    @property
    def playing(self) -> bool:
        return self._head.playing

    @property
    def speed(self) -> float:
        return self._head.speed

    @property
    def shown(self) -> list[bool]:
        return self._shown.runs

    @property
    def pile_shown(self) -> str:
        return self._shown.pile

    @property
    def fan_shown(self) -> bool:
        return self._shown.fan

    @property
    def pile_colour(self) -> str:
        return self._shown.pile_colour

    # -- commands: safe from any thread, applied by the player's thread between frames ----------

    def toggle(self) -> None:
        """Play, or pause; Play at the end starts over."""
        self._actions.put(self._toggle)

    def seek(self, t: float) -> None:
        """Jump to time t (s), clamped to the runs."""
        self._actions.put(lambda: self._seek(t))

    def set_speed(self, speed: float) -> None:
        """Play at `speed` times real time."""
        self._actions.put(lambda: self._set_speed(speed))

    def show_run(self, k: int, shown: bool) -> None:
        """Show or hide run k: its machine, its trail, its readout row and its chart lines."""
        self._actions.put(lambda: self._show_run(k, shown))

    def paint(self, solid: int | None) -> None:
        """Run `solid` in its MJCF colours and the rest translucent; None: each in its own colour."""
        self._actions.put(lambda: self.view.paint(solid))

    def show_pile(self, kind: str) -> None:
        """Show the true pile ("true") or the one the run knew from its scans ("scanned")."""
        if kind not in PILE_SHOWN:
            raise ValueError(f"pile shown: {kind!r}, not one of {', '.join(PILE_SHOWN)}")
        self._actions.put(lambda: self._show_pile(kind))

    def show_fan(self, shown: bool) -> None:
        """Show or hide the scan fan and the hits of the last second."""
        self._actions.put(lambda: self._show_fan(shown))

    def colour_pile(self, kind: str) -> None:
        """Colour a pile of grade by ore ("ore") or by the grade of its top layer ("grade")."""
        if kind not in PILE_COLOURS:
            raise ValueError(f"pile colour: {kind!r}, not one of {', '.join(PILE_COLOURS)}")
        self._actions.put(lambda: self._colour_pile(kind))

    def _show_pile(self, kind: str) -> None:
        shown = self._shown
        if kind == shown.pile:
            return
        shown.pile = kind
        with self.server.atomic():  # the pile shown now arrives as it stands at the current time
            self.view.show_pile(kind)
            self.view.show(self.time)
            self.panel.show_scanner(kind, shown.fan)

    def _colour_pile(self, kind: str) -> None:
        if kind == self._shown.pile_colour or self.view.grade_scale is None:
            return
        self._shown.pile_colour = kind
        with self.server.atomic():  # every tile in its new colours at once
            self.view.colour_pile(kind)
            self.panel.show_pile_colour(kind)

    def _show_fan(self, shown: bool) -> None:
        if shown == self._shown.fan:
            return
        self._shown.fan = shown
        with self.server.atomic():
            self.view.show_fan(shown)
            self.view.show(self.time)
            self.panel.show_scanner(self._shown.pile, shown)

    def _toggle(self) -> None:
        head = self._head
        if not head.playing and head.time >= head.end:
            head.time = head.start
        self._set_playing(not head.playing)

    def _set_playing(self, playing: bool) -> None:
        self._head.playing = playing
        self.panel.show_playing(playing)

    def _set_speed(self, speed: float) -> None:
        self._head.speed = min(max(float(speed), SPEEDS[0]), SPEEDS[1])
        self.panel.speed_slider.value = self._head.speed

    def _seek(self, t: float) -> None:
        self._head.seek(t)

    def _show_run(self, k: int, shown: bool) -> None:
        runs = self._shown.runs
        if runs[k] == shown:
            return
        runs[k] = shown
        with self.server.atomic():
            self.view.set_visible(k, shown)
            self.panel.show_charts(runs)
        self._scene_shows = self._readout_shows = None  # a run shown again is posed, and read out, now

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
            if self._head.playing:
                self._head.advance(now - last)
                if not self._head.playing:
                    self.panel.show_playing(False)
            last = now
            self._draw(now)

    def _draw(self, now: float) -> None:
        """Send what changed: the scene and slider every frame, the readout less often."""
        t = self.time
        if t != self._scene_shows:
            with self.server.atomic():
                self.view.show(t)
                self.panel.time_slider.value = t
            self._scene_shows = t
        if t != self._readout_shows and (not self.playing or now - self._readout_at >= READOUT_PERIOD):
            self.panel.show_readout(t, self.shown, self.end - self.start)
            self._readout_at, self._readout_shows = now, t

    def stop(self) -> None:
        self._stopped.set()
        self._thread.join(timeout=PLAYER_STOP_WAIT)  # a daemon: a frame stuck in viser must not hold the exit
