"""A self-contained HTML recording of a replay, of one run or several, that plays offline from a
double-click.

The scene is built exactly as for the live replay, then viser's scene serializer records one
frame per `1 / frame_rate` s of playback at `speed` times real time. GUI elements are not part of
such a recording, so one run's readout is a scene label here; the charts are SVG images in a
column beside the scene, with a cursor that follows the playback and seeks it when clicked, below
several runs' readout (bwr_twin.replay.export_charts). Only poses, the trails' tips and the label
change per frame, which keeps the paper's 700 s reclaim at 10x and 25 fps under 2 MB, and four
runs of it under 5 MB. A run's laser scans are drawn as `scan_view.EXPORT` decimates them, both
piles recorded, and the column starts with the controls that choose the pile shown.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import viser

from bwr_twin.errors import BwrError
from bwr_twin.ownership import HTML_TAG, check_output, write_atomically
from bwr_twin.replay import readout
from bwr_twin.replay.charts import charts
from bwr_twin.replay.export_charts import COLUMN_SHARE, charts_column, readout_data
from bwr_twin.replay.recording import Recording
from bwr_twin.replay.runs import Run
from bwr_twin.replay.scan_view import EXPORT, scanned_note
from bwr_twin.replay.scenery import ASPECT
from bwr_twin.replay.view import SceneView

EXPORT_SPEED = 10.0  # x real time
EXPORT_FRAME_RATE = 25.0  # frames per second of playback: smooth at 10x


def export_html(
    recording: Recording,
    path: str | Path,
    *,
    speed: float = EXPORT_SPEED,
    frame_rate: float = EXPORT_FRAME_RATE,
    name: str | None = None,
    others: Sequence[Run] = (),
    side_by_side: bool = False,
) -> int:
    """Write the replay of `recording` (named `name`) and `others` to `path` (atomically);
    returns the file size in bytes."""
    path = Path(path)
    check_output(path, "export", option="--export")
    if not path.parent.is_dir():
        raise BwrError(f"{path}: the folder {path.parent} does not exist")
    runs = [Run(recording, name or Path(recording.plan.title).stem), *others]
    with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        html = _record(server, runs, speed, frame_rate, side_by_side)
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    html = html.replace("<head>", f"<head>{HTML_TAG}", 1)  # how a later export knows it may replace this
    write_atomically(path, lambda partial: partial.write_text(html, encoding="utf-8"), record=True, option="--export")
    return path.stat().st_size


def _record(server: viser.ViserServer, runs: list[Run], speed: float, frame_rate: float,
            side_by_side: bool) -> str:
    """The recorded scene, with the charts' column added to the page."""
    recordings = [run.recording for run in runs]
    view = SceneView(server, [r.plan for r in recordings], names=[run.label for run in runs],
                     side_by_side=side_by_side, aspect=ASPECT * (1.0 - COLUMN_SHARE), scans=EXPORT)
    for k, recording in enumerate(recordings):
        view.attach(recording, k)
    start = min(float(r.plan.time[0]) for r in recordings)
    duration = max(float(r.plan.time[-1]) for r in recordings) - start
    # One run's readout is a scene label, as before there were charts; several runs' is the column's.
    caption = None if len(runs) > 1 else server.scene.add_label(
        "/readout", "", position=view.caption_position, anchor="top-center", font_screen_scale=1.1
    )
    serializer = server.get_scene_serializer()
    frames = np.append(np.arange(start, start + duration, speed / frame_rate), start + duration)
    for i, t in enumerate(frames):
        with server.atomic():
            view.show(float(t))
            if caption is not None:
                caption.text = readout.as_text(recordings[0].at(float(t)), duration)
        if i + 1 < len(frames):
            serializer.insert_sleep(1.0 / frame_rate)
    column = charts_column(charts(recordings, [run.name for run in runs]), [True] * len(runs), start=start,
                           speed=speed, readout=readout_data(runs, duration) if len(runs) > 1 else None,
                           scanner=scanned_note(recordings[0].scans, EXPORT.known_period) if view.scanning else None)
    page = serializer.as_html()
    end = page.rindex("</body>")
    return page[:end] + column + page[end:]
