"""Figure layout shared by every figure the twin writes: the resolution, and titles that fit."""

from __future__ import annotations

import re

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text

DPI = 110
TITLE_MARGIN = 0.01  # of the figure's width, kept clear at either edge of a title


def fit_titles(fig: Figure) -> None:
    """Break every title line too wide for the figure at its commas and semicolons (else at its
    spaces) into rows of even length, and shrink a title whose single word still does not fit, so
    that no title runs past the figure's edges. An axes' title is fitted to the axes' width before
    the layout (the layout widens single-column axes); matplotlib's own wrapping, at draw time,
    breaks any line the final layout still finds too wide."""
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    renderer = canvas.get_renderer()  # measures text only: nothing is drawn
    width = fig.bbox.width
    rooms = []  # (title, its room in pixels)
    for text in fig.texts:  # the suptitle: centred on its position
        x = text.get_transform().transform(text.get_position())[0]
        rooms.append((text, 2 * min(x, width - x)))
    rooms += [(ax.title, ax.get_position().width * width) for ax in fig.axes]
    for text, room in rooms:
        if text.get_text():
            _fit(text, room - 2 * TITLE_MARGIN * width, renderer)
            text.set_wrap(True)


def _fit(text: Text, room: float, renderer) -> None:
    original = text.get_text()

    def wide(s: str) -> float:
        text.set_text(s)
        return text.get_window_extent(renderer).width

    def rows(tokens: list[str], limit: float) -> list[str]:
        filled = [tokens[0]]
        for token in tokens[1:]:
            if wide(f"{filled[-1]} {token}") <= limit:
                filled[-1] = f"{filled[-1]} {token}"
            else:
                filled.append(token)
        return filled

    lines = []
    for line in original.split("\n"):
        if wide(line) <= room:
            lines.append(line)
            continue
        # Break at ", " and "; " where the pieces fit; a piece that alone is too wide, at its spaces.
        tokens = []
        for piece in re.split(r"(?<=[,;]) ", line):
            tokens += [piece] if wide(piece) <= room else piece.split(" ")
        # As few rows as fit, then the narrowest width that needs no more: rows of even length.
        count = len(rows(tokens, room))
        low, high = min(max(wide(token) for token in tokens), room), room
        for _ in range(8):
            middle = (low + high) / 2
            low, high = (low, middle) if len(rows(tokens, middle)) <= count else (middle, high)
        lines += rows(tokens, high)
    widest = max(wide(line) for line in lines)
    text.set_text("\n".join(lines))
    if widest > room:  # one word wider than the figure
        text.set_fontsize(text.get_fontsize() * room / widest)
