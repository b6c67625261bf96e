"""The strip of error charts along the bottom of a replay video: each axis's position error
(desired - actual; travel in m, slew and luff in degrees, as the readout gives them) of every run
over the whole run, in the run's colour, with a cursor at the picture's time.

Matplotlib draws the strip once; a frame copies it and paints the cursor's pixel columns, which
costs a copy of the strip's pixels instead of a redraw.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.replay.recording import Recording
from bwr_twin.replay.style import hex_colour, run_colour

DPI = 100
FONT_POINTS = 8.0  # at a strip STRIP_LINES high; scaled with the strip
STRIP_LINES = 216  # a 720-line video's strip
CURSOR_COLOUR = (85, 85, 85)  # the browser charts' "now" line
CURSOR_WIDTH = 2 / STRIP_LINES  # of the strip's height


class ChartStrip:
    """The charts as a (height, width, 3) uint8 picture; `draw` puts it, with the cursor at a
    time, into a picture's bottom rows."""

    def __init__(self, recordings: Sequence[Recording], names: Sequence[str], width: int, height: int):
        self.height = height
        scale = height / STRIP_LINES
        figure = Figure(figsize=(width / DPI, height / DPI), dpi=DPI, facecolor="white")
        canvas = FigureCanvasAgg(figure)
        axes = figure.subplots(1, len(AXES), sharex=True)
        start, end = float(recordings[0].plan.time[0]), float(recordings[0].plan.time[-1])
        for j, ax in enumerate(axes):
            for k, (recording, name) in enumerate(zip(recordings, names)):
                ax.plot(recording.plan.time, to_display(j, recording.q_error[:, j]), label=name,
                        color=hex_colour(run_colour(k)), linewidth=1.2 * scale)
            ax.set_title(f"{AXES[j]} error [{UNITS[j]}]", fontsize=FONT_POINTS * scale, pad=2 * scale)
            ax.set_xlim(start, end)
            ax.tick_params(labelsize=0.9 * FONT_POINTS * scale, length=2 * scale, pad=1.5 * scale)
            ax.grid(True, linewidth=0.5 * scale, alpha=0.5)
            ax.set_xlabel("t [s]", fontsize=0.9 * FONT_POINTS * scale, labelpad=1 * scale)
        if len(recordings) > 1:
            axes[0].legend(fontsize=0.8 * FONT_POINTS * scale, loc="upper left", frameon=False)
        figure.subplots_adjust(left=0.05, right=0.99, bottom=0.2, top=0.87, wspace=0.22)
        canvas.draw()
        self.image = np.asarray(canvas.buffer_rgba())[..., :3].copy()
        # Each chart's pixel column of a time, and its rows (matplotlib counts from the bottom).
        self._columns, self._rows = [], []
        for ax in axes:
            (x0, _), (x1, _) = ax.transData.transform([(start, 0.0), (end, 0.0)])
            self._columns.append((x0, (x1 - x0) / (end - start) if end > start else 0.0, start))
            box = ax.get_window_extent()
            self._rows.append(slice(round(height - box.y1), round(height - box.y0)))
        self._cursor_width = max(1, round(CURSOR_WIDTH * height))

    def draw(self, out: np.ndarray, t: float) -> None:
        """The strip into `out` (height, width, 3), with the cursor at time t (s)."""
        out[:] = self.image
        for (x0, per_second, start), rows in zip(self._columns, self._rows):
            x = round(x0 + per_second * (t - start))
            out[rows, max(0, x - self._cursor_width // 2): x + (self._cursor_width + 1) // 2] = CURSOR_COLOUR
