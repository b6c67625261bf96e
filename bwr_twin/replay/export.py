"""A self-contained HTML recording of a replay that plays offline, from a double-click.

The scene is built exactly as for the live replay, then viser's scene serializer records one
frame per `1 / frame_rate` s of playback at `speed` times real time. GUI elements are not part of
such a recording, so the readout is a scene label here. Only poses, the trail's tip and the label
change per frame, which keeps the paper's 700 s reclaim at 10x and 25 fps under 2 MB.
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import viser

from bwr_twin.errors import BwrError
from bwr_twin.replay import readout
from bwr_twin.replay.recording import Recording
from bwr_twin.replay.view import SceneView
from bwr_twin.results.ownership import HTML_TAG, check_output
from bwr_twin.results.rundir import write_atomically

EXPORT_SPEED = 10.0  # x real time
EXPORT_FRAME_RATE = 25.0  # frames per second of playback: smooth at 10x


def export_html(
    recording: Recording,
    path: str | Path,
    *,
    speed: float = EXPORT_SPEED,
    frame_rate: float = EXPORT_FRAME_RATE,
    ghost: tuple[Recording, str] | None = None,
) -> int:
    """Write the recording's replay to `path` (atomically); returns the file size in bytes."""
    path = Path(path)
    check_output(path, "export", option="--export")
    if not path.parent.is_dir():
        raise BwrError(f"{path}: the folder {path.parent} does not exist")
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        html = _record(server, recording, speed, frame_rate, ghost)
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    html = html.replace("<head>", f"<head>{HTML_TAG}", 1)  # how a later export knows it may replace this
    write_atomically(path, lambda partial: partial.write_text(html, encoding="utf-8"))
    return path.stat().st_size


def _record(server: viser.ViserServer, recording: Recording, speed: float, frame_rate: float,
            ghost: tuple[Recording, str] | None) -> str:
    view = SceneView(server, recording.plan)
    view.attach(recording)
    if ghost is not None:
        view.add_ghost(*ghost)
    duration = recording.plan.duration
    caption = server.scene.add_label(
        "/readout", "", position=view.caption_position, anchor="top-center", font_screen_scale=1.1
    )
    serializer = server.get_scene_serializer()
    start = float(recording.plan.time[0])
    frames = np.append(np.arange(start, start + duration, speed / frame_rate), start + duration)
    for i, t in enumerate(frames):
        with server.atomic():
            view.show(float(t))
            caption.text = readout.as_text(recording.at(float(t)), duration)
        if i + 1 < len(frames):
            serializer.insert_sleep(1.0 / frame_rate)
    return serializer.as_html()
