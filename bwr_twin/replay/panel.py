"""The replay's GUI panel: timeline, the chooser of runs, readout and charts.

It only draws what the player tells it and forwards what a user does to the player's commands
(`Player.toggle`, `seek`, ...), which queue it for the player's thread: no state lives here, and
no callback changes the scene.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

import viser

from bwr_twin.replay import readout
from bwr_twin.replay.charts import charts
from bwr_twin.replay.page_script import live_script_html
from bwr_twin.replay.pile import PILE_COLOURS
from bwr_twin.replay.scan_view import LIVE, PILE_SHOWN, scanned_note
from bwr_twin.replay.style import hex_colour, run_colour

if TYPE_CHECKING:
    from bwr_twin.replay.grade_scale import GradeScale
    from bwr_twin.replay.runs import Run


class Player(Protocol):
    """What the panel's controls ask of the player (bwr_twin.replay.player.Player), which
    queues each request for its own thread."""

    start: float
    end: float

    def toggle(self) -> None: ...
    def seek(self, t: float) -> None: ...
    def set_speed(self, speed: float) -> None: ...
    def show_run(self, k: int, shown: bool) -> None: ...
    def paint(self, run: int | None) -> None: ...
    def show_pile(self, kind: str) -> None: ...
    def show_fan(self, shown: bool) -> None: ...
    def colour_pile(self, kind: str) -> None: ...


SPEEDS = (1, 100)  # x real time, the speed slider's range
INITIAL_SPEED = 10
MARK_CHARACTER = 0.03  # of the time slider's width: one character of a mark's label (0.6rem on ~190 px)
MARK_GAP = 0.02  # of the slider's width between two labels
EACH_IN_ITS_COLOUR = "each in its own colour"


def via_point_marks(times, names, labelled: set[str] | None = None,
                    span: float | None = None) -> tuple[float | tuple[float, str], ...]:
    """Time slider marks at the via points, labelled with their names (P1, P2, ...; of a bench
    plan only those in `labelled`, say its benches and its end) unless a label would print over
    the one before; the readout names the others. `span` (s) is the slider's, if not the via points'."""
    marks: list[float | tuple[float, str]] = []
    span = span or float(times[-1] - times[0]) or 1.0
    last_t, last_name = -float("inf"), ""
    for t, name in zip(times, names):
        room = (MARK_CHARACTER * (len(name) + len(last_name)) / 2 + MARK_GAP) * span
        if name and (labelled is None or name in labelled) and t - last_t >= room:
            marks.append((float(t), name))
            last_t, last_name = t, name
        else:
            marks.append(float(t))
    return tuple(marks)


def solid_choices(runs: Sequence[Run]) -> list[str]:
    """The "Machines" dropdown: one run solid and the rest seen through, for each run; or each
    machine solid in its own colour."""
    return [f"{run.name} solid, the rest translucent" for run in runs] + [EACH_IN_ITS_COLOUR]


class Panel:
    """The GUI of `runs` on `server`, wired to `player`'s commands; with `scanning`, the scanner's
    controls (the pile shown, the fan); with a `grade` scale (a pile of grade), the pile's colour
    and the scale's legend."""

    def __init__(self, server: viser.ViserServer, runs: Sequence[Run], player: Player, *, scanning: bool = False,
                 grade: GradeScale | None = None):
        self.server, self.runs = server, list(runs)
        gui = server.gui
        plan = self.runs[0].recording.plan
        step = float(plan.time[1] - plan.time[0])
        with gui.add_folder("Timeline"):
            self.play_button = gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY)
            labelled = {name for name, _ in plan.landmarks} | {"end"} if plan.via_stages else None
            self.time_slider = gui.add_slider("Time [s]", min=player.start, max=player.end, step=step,
                                              initial_value=player.start,
                                              marks=via_point_marks(plan.via_times, plan.names, labelled,
                                                                    span=player.end - player.start))
            self.speed_slider = gui.add_slider("Speed [x]", min=SPEEDS[0], max=SPEEDS[1], step=1,
                                               initial_value=INITIAL_SPEED, marks=(1, 10, 50, 100))
            landmarks = dict(plan.landmarks)
            # A stacking's plan has passes, no benches: nothing to jump to (viser refuses an empty group).
            self.jump = gui.add_button_group("Jump to", list(landmarks)) if landmarks else None
        self.shown_boxes: list[viser.GuiCheckboxHandle] = []
        if len(self.runs) > 1:
            with gui.add_folder("Runs"):
                self.machines = gui.add_dropdown("Machines", solid_choices(self.runs),
                                                 initial_value=solid_choices(self.runs)[0])
                for k, run in enumerate(self.runs):
                    box = gui.add_checkbox(run.label, initial_value=True, hint=f"show or hide {run.label}")
                    self.shown_boxes.append(box)
                    box.on_update(lambda event, k=k: player.show_run(k, bool(event.target.value)))

                @self.machines.on_update
                def _(event: viser.GuiEvent) -> None:
                    choice = solid_choices(self.runs).index(event.target.value)
                    player.paint(choice if choice < len(self.runs) else None)

        self.pile_shown: viser.GuiDropdownHandle | None = None
        self.fan_shown: viser.GuiCheckboxHandle | None = None
        if scanning:
            with gui.add_folder("Scanner"):
                self.pile_shown = gui.add_dropdown("Pile shown", PILE_SHOWN, initial_value=PILE_SHOWN[0],
                                                   hint="the true pile, or the one the automation knew from its scans")
                self.fan_shown = gui.add_checkbox("Scan fan and hits", initial_value=True,
                                                  hint="the latest scan's rays and the last second's hits")
                gui.add_markdown(f"*Scanned*: {scanned_note(self.runs[0].recording.scans, LIVE.known_period)}")

            @self.pile_shown.on_update
            def _(event: viser.GuiEvent) -> None:
                if event.client is not None:  # a user's choice, not the player's own update
                    player.show_pile(str(event.target.value))

            @self.fan_shown.on_update
            def _(event: viser.GuiEvent) -> None:
                if event.client is not None:
                    player.show_fan(bool(event.target.value))

        self.pile_colour: viser.GuiDropdownHandle | None = None
        self.grade_legend: viser.GuiHtmlHandle | None = None
        if grade is not None:
            with gui.add_folder("Pile"):
                self.pile_colour = gui.add_dropdown(
                    "Pile colour", PILE_COLOURS, initial_value=PILE_COLOURS[0],
                    hint="ore: weathered, bright where freshly cut; grade: the grade of the layer exposed at each cell")
                self.grade_legend = gui.add_html(grade.legend_html(), visible=False)

            @self.pile_colour.on_update
            def _(event: viser.GuiEvent) -> None:
                if event.client is not None:  # a user's choice, not the player's own update
                    player.colour_pile(str(event.target.value))

        with gui.add_folder("Readout"):
            self.readout = gui.add_markdown("")
        with gui.add_folder("Charts"):
            self.charts = charts([run.recording for run in self.runs], [run.name for run in self.runs])
            everyone = [True] * len(self.runs)
            self.chart_handles = [
                gui.add_uplot(chart.data(everyone), chart.series(everyone), title=chart.title,
                              scales=chart.ranges(everyone), axes=chart.axes, aspect=1.6)
                for chart in self.charts
            ]
            gui.add_html(live_script_html(self.time_slider._impl.uuid, step))

        @self.play_button.on_click
        def _(_) -> None:
            player.toggle()

        @self.time_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            if event.client is not None:  # a user's drag or entry, not the player's own update
                player.seek(float(self.time_slider.value))

        @self.speed_slider.on_update
        def _(event: viser.GuiEvent) -> None:
            if event.client is not None:
                player.set_speed(float(self.speed_slider.value))

        if self.jump is not None:
            @self.jump.on_click
            def _(event: viser.GuiEvent) -> None:
                player.seek(landmarks[event.target.value])

    # -- drawn on the player's thread only ------------------------------------------------------

    def show_playing(self, playing: bool) -> None:
        self.play_button.label = "Pause" if playing else "Play"
        self.play_button.icon = viser.Icon.PLAYER_PAUSE if playing else viser.Icon.PLAYER_PLAY

    def show_scanner(self, pile: str, fan: bool) -> None:
        """The scanner's controls as the player shows the scene (a choice from Python, or another tab)."""
        if self.pile_shown is not None and self.pile_shown.value != pile:
            self.pile_shown.value = pile
        if self.fan_shown is not None and self.fan_shown.value != fan:
            self.fan_shown.value = fan

    def show_pile_colour(self, kind: str) -> None:
        """The pile's colour as the player shows it, and the grade's legend with the grade."""
        if self.pile_colour is None:
            return
        if self.pile_colour.value != kind:
            self.pile_colour.value = kind
        self.grade_legend.visible = kind == "grade"

    def show_readout(self, t: float, shown: Sequence[bool], duration: float) -> None:
        if len(self.runs) == 1:
            self.readout.content = readout.as_markdown(self.runs[0].recording.at(t), duration)
            return
        ks = [k for k, on in enumerate(shown) if on]
        self.readout.content = readout.runs_markdown(
            t, [self.runs[k].recording.at(t) for k in ks], [self.runs[k].name for k in ks],
            [hex_colour(run_colour(k)) for k in ks], duration)

    def show_charts(self, shown: Sequence[bool]) -> None:
        """Each chart with the lines of the runs shown, its y-range fitted to them."""
        for chart, handle in zip(self.charts, self.chart_handles):
            lines = chart.shown(shown)
            handle.visible = bool(lines)
            if lines:
                handle.series, handle.data, handle.scales = chart.series(shown), chart.data(shown), chart.ranges(shown)
