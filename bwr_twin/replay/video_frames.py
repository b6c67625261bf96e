"""The pictures of a replay video, drawn offscreen by MuJoCo's own OpenGL renderer: a header
with the time and each run's tracking errors, written by MuJoCo's text overlay; the scene
(bwr_twin.replay.video_scene) below it; and, if asked, the chart strip
(bwr_twin.replay.video_charts) along the bottom.

The OpenGL context is MuJoCo's for the MUJOCO_GL environment variable: `egl` when it is not
set (set so here, before MuJoCo's context module is imported: headless, no display; without a
GPU, Mesa's software rasteriser llvmpipe, from Debian's libegl1 and libegl-mesa0), `osmesa`
(libosmesa6) or `glfw` (a display). Multisampling is off: on llvmpipe, resolving a multisampled
picture costs more than drawing it (50 ms at 1280x720), for edges a little smoother.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence

import mujoco
import numpy as np

from bwr_twin.errors import BwrError
from bwr_twin.replay import readout
from bwr_twin.replay.recording import Recording
from bwr_twin.replay.style import run_colour
from bwr_twin.replay.video_scene import ReplayScene

STRIP_SHARE = 0.3  # of the picture's height, the chart strip's
FONT_LINES = 480 / 100  # MuJoCo's font scale 100 suits 480 picture lines; it comes in steps of 50
TEXT_MARGIN = 0.012  # of the picture's height, around the header's text
HEADER_COLOUR = (0.16, 0.17, 0.19, 1.0)  # rgba: the text stays legible, and covers no part of the scene
TEXT_COLOUR = (1.0, 1.0, 1.0)


def gl_context(width: int, height: int):
    """MuJoCo's OpenGL context for MUJOCO_GL (egl if unset), current on this thread. BwrError,
    one line, if this machine has none."""
    backend = os.environ.setdefault("MUJOCO_GL", "egl").strip().lower()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # glfw only warns that it found no display
            if backend == "egl":
                from mujoco.egl import GLContext
            elif backend == "osmesa":
                from mujoco.osmesa import GLContext
            else:
                import glfw

                if not glfw.init():  # before a context half made, whose clean-up would fail noisily
                    raise RuntimeError("glfw cannot start")
                from mujoco.glfw import GLContext
            context = GLContext(width, height)
            context.make_current()
    except Exception as exc:  # noqa: BLE001 - each backend fails its own way: ImportError, RuntimeError, GLFWError
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise BwrError(f"MUJOCO_GL={backend}: no OpenGL context for rendering offscreen ({reason[:200]}); "
                       "egl needs Debian's libegl1 and libegl-mesa0, osmesa libosmesa6") from None
    return context


class FrameRenderer:
    """Pictures (height, width, 3) of uint8 RGB, top row first, of `recordings` at any time.

    `names` label the runs in the burnt-in readout when there are several; `charts` adds the
    strip of error charts with a cursor at the picture's time."""

    def __init__(self, recordings: Sequence[Recording], names: Sequence[str], size: tuple[int, int], *,
                 charts: bool = False):
        width, height = size
        self.recordings, self.names = list(recordings), list(names)
        self.size = size
        self.strip = None
        if charts:
            from bwr_twin.replay.video_charts import ChartStrip

            strip_height = 2 * round(STRIP_SHARE * height / 2)
            self.strip = ChartStrip(self.recordings, self.names, width, strip_height)
        self.strip_height = self.strip.height if self.strip else 0
        self.scene = ReplayScene(self.recordings, width, height)
        self._gl = gl_context(width, height)
        scale = int(np.clip(50 * round(height / FONT_LINES / 50), 50, 300))
        self._context = mujoco.MjrContext(self.scene.model, scale)
        mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
        self._margin = round(TEXT_MARGIN * height)
        header = (1 + len(self.recordings)) * self._context.charHeight + 2 * self._margin
        # OpenGL counts rows from the bottom: the strip, the scene, the header.
        self._header = mujoco.MjrRect(0, height - header, width, header)
        self._view = mujoco.MjrRect(0, self.strip_height, width, height - header - self.strip_height)
        self._whole = mujoco.MjrRect(0, 0, width, height)
        self._pixels = np.empty((height, width, 3), dtype=np.uint8)

    def frame(self, t: float) -> np.ndarray:
        """The picture at time t (s) of the runs."""
        scene = self.scene
        scene.update(t)
        if scene.pile_changed:
            mujoco.mjr_uploadHField(scene.model, self._context, scene.pile_hfield)
            mujoco.mjr_uploadTexture(scene.model, self._context, scene.pile_texture)
        mujoco.mjr_render(self._view, scene.scene, self._context)
        self._burn_in(t)
        mujoco.mjr_readPixels(self._pixels, None, self._whole, self._context)
        picture = np.ascontiguousarray(self._pixels[::-1])  # OpenGL's first row is the bottom one
        if self.strip is not None:
            self.strip.draw(picture[picture.shape[0] - self.strip_height:], t)
        return picture

    def readout_lines(self, t: float) -> list[tuple[str, tuple[float, float, float]]]:
        """(text, rgb) lines: the time of the run, then each run's position errors per axis with
        their units, formatted as the browser's readout formats them."""
        first = self.recordings[0]
        instant = first.at(t)
        head = f"{first.plan.title}   t = {instant.time:.1f} s of {first.plan.duration:g} s"
        if instant.reclaim_rate is not None:
            head += f"   reclaim rate {instant.reclaim_rate:,.0f} t/h"
        if instant.stage is not None:
            head += f"   plan: {instant.stage}"
        lines = [(head, TEXT_COLOUR)]
        several = len(self.recordings) > 1
        for k, (recording, name) in enumerate(zip(self.recordings, self.names)):
            errors = "   ".join(f"{axis} {error}" for axis, _, _, error in readout.rows(recording.at(t)))
            label = f"{name}{' (solid)' if k == 0 else ''}: " if several else ""
            colour = tuple(c / 255 for c in run_colour(k)) if several else TEXT_COLOUR
            lines.append((f"{label}error (desired - actual)   {errors}", colour))
        return lines

    def _burn_in(self, t: float) -> None:
        """The readout lines in the header, one a line."""
        header, line_height = self._header, self._context.charHeight
        mujoco.mjr_rectangle(header, *HEADER_COLOUR)  # also makes the header the viewport mjr_text places in
        for i, (text, colour) in enumerate(self.readout_lines(t)):
            bottom = header.height - self._margin - (i + 1) * line_height
            mujoco.mjr_text(mujoco.mjtFont.mjFONT_NORMAL, text, self._context, self._margin / header.width,
                            bottom / header.height, *colour)

    def close(self) -> None:
        """Free the OpenGL resources."""
        if self._gl is not None:
            self._context.free()
            self._gl.free()
            self._gl = None
