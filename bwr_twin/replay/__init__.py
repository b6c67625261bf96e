"""Web replay of a reclaim in the browser, of one run or several, and its offline HTML export.

    python -m bwr_twin.replay [SCENE | RUN_DIR ...] [--runs NAME,...] [--side-by-side] [--export FILE.html]

`Plan` and `Recording` hold what is shown, `Run` names a recording among several, `SceneView`
draws them from the MJCF's own visual geoms, `ReplayServer` serves them with a timeline, and
`export_html` writes a recording that plays offline. docs/replay.md describes the screen.
"""

from bwr_twin.replay.app import ReplayServer
from bwr_twin.replay.export import export_html
from bwr_twin.replay.recording import Plan, Recording
from bwr_twin.replay.runs import Run, choose_runs, load_runs

__all__ = ["Plan", "Recording", "ReplayServer", "Run", "choose_runs", "export_html", "load_runs"]
