"""Web replay of a reclaim in the browser, and its offline HTML export.

    python -m bwr_twin.replay [SCENE | RUN_DIR] [--host 127.0.0.1] [--port 8080] [--export FILE.html]

`Plan` and `Recording` hold what is shown, `SceneView` draws it from the MJCF's own visual
geoms, `ReplayServer` serves it with a timeline, and `export_html` writes a recording that plays
offline. docs/replay.md describes the screen.
"""

from bwr_twin.replay.app import ReplayServer
from bwr_twin.replay.export import export_html
from bwr_twin.replay.recording import Plan, Recording

__all__ = ["Plan", "Recording", "ReplayServer", "export_html"]
