"""The HTML export's column beside the recorded scene: the live page's charts (bwr_twin.replay.charts)
drawn as SVG images by matplotlib, with a cursor at the playback's time and click-to-seek, and,
for several runs, their readout (bwr_twin.replay.page_script).

A viser scene recording carries no GUI, so these are a companion part of the page rather than
part of the recording. Each image's plot area is fixed in the figure, so that the page's script
maps a time to a place on it, and back, from four numbers. The readout's errors are each run's
records, to six digits: the page interpolates them at the playback's time as the live readout does.
"""

from __future__ import annotations

import base64
import html
import io
import json
from collections.abc import Sequence

import numpy as np

from bwr_twin.model.machine import AXES, UNITS, to_display
from bwr_twin.replay.charts import Chart
from bwr_twin.replay.page_script import SCANNER_FAN_ID, SCANNER_PILE_ID, export_scanner_script, export_script
from bwr_twin.replay.runs import Run
from bwr_twin.replay.scan_view import PILE_SHOWN
from bwr_twin.replay.style import hex_colour, run_colour

CHART_SIZE = (5.0, 2.7)  # in, each chart's figure
PLOT_BOX = (0.13, 0.87, 0.33, 0.88)  # left, right, bottom, top of every plot area, as figure fractions
COLUMN_SHARE = 0.34  # of the page's width: the column right of the scene
LEGEND_COLUMNS = 2
SCANNER_STYLE = """<style>
#bwr-scanner { font-size: 12px; padding: 0.4em 0.6em; border-bottom: 1px solid #eee; }
#bwr-scanner label { margin-right: 1.2em; white-space: nowrap; }
#bwr-scanner p { margin: 0.3em 0 0; color: #555; }
</style>"""
DIGITS = 6  # significant digits of the readout's errors


def chart_svg(chart: Chart, shown: Sequence[bool]) -> str:
    """One chart as an SVG document, its plot area at PLOT_BOX and its time axis exactly the chart's."""
    import matplotlib  # here: the live replay never draws with it, and it takes a second to import
    from matplotlib.figure import Figure  # no pyplot: no global state, no display backend

    fig = Figure(figsize=CHART_SIZE)
    left, right, bottom, top = PLOT_BOX
    fig.subplots_adjust(left=left, right=right, bottom=bottom, top=top)
    ax = fig.add_subplot()
    axes = {chart.axes[1]["scale"]: ax}
    used = {line.series["scale"] for line in chart.shown(shown)}
    for spec in chart.axes[2:]:  # a second scale, on the right, if a line is drawn on it
        if spec["scale"] in used:
            axes[spec["scale"]] = ax.twinx()
    for spec in chart.axes[1:]:
        if spec["scale"] in axes and spec.get("label"):
            axes[spec["scale"]].set_ylabel(spec["label"], fontsize=8)
    for line in chart.shown(shown):
        series = line.series
        axes[series["scale"]].plot(chart.time, line.values, color=series["stroke"], linewidth=1.0,
                                   linestyle=(0, series["dash"]) if "dash" in series else "-", label=series["label"])
    ranges = chart.ranges(shown)
    for scale, target in axes.items():
        target.tick_params(labelsize=7)
        if "range" in ranges.get(scale, {}):
            target.set_ylim(*ranges[scale]["range"])
    ax.set_xlim(float(chart.time[0]), float(chart.time[-1]))
    ax.set_xlabel("t [s]", fontsize=8)
    ax.set_title(chart.title, fontsize=9)
    handles = [h for target in axes.values() for h in target.get_legend_handles_labels()[0]]
    fig.legend(handles=handles, loc="lower center", ncol=LEGEND_COLUMNS, fontsize=6.5, frameon=False)
    with matplotlib.rc_context({"svg.fonttype": "none"}):  # text as text: a small file
        buffer = io.StringIO()
        fig.savefig(buffer, format="svg")
    return buffer.getvalue()


def readout_data(runs: Sequence[Run], duration: float) -> dict:
    """What the page's readout needs: per run its name, colour, record times and errors (display
    units), and its reclaim rate if it has one."""
    out = []
    for k, run in enumerate(runs):
        r = run.recording
        errors = [to_display(j, r.q_error[:, j]) for j in range(len(AXES))]
        out.append({"name": run.name, "colour": hex_colour(run_colour(k)), "time": _rounded(r.plan.time),
                    "error": [_rounded(e) for e in errors],
                    "rate": _rounded(r.reclaim_rate) if r.reclaim_rate is not None else None})
    return {"duration": float(f"{duration:g}"), "axes": list(AXES), "units": list(UNITS), "runs": out,
            "rates": any(run["rate"] is not None for run in out)}


def _rounded(values: np.ndarray) -> list[float]:
    return [float(f"{v:.{DIGITS}g}") for v in np.asarray(values, dtype=float)]


def charts_column(charts: Sequence[Chart], shown: Sequence[bool], *, start: float, speed: float,
                  readout: dict | None = None, scanner: str | None = None) -> str:
    """The page's column and its script, to go at the end of the export's <body>: with a run that
    scanned, the scanner's controls and `scanner`, what the scanned pile is; the runs' `readout`
    (`readout_data`; None: the scene carries it) and the charts. The recording's playback time p
    is the runs' time start + p * speed."""
    figures = []
    for chart in charts:
        if not chart.shown(shown):
            continue
        svg = base64.b64encode(chart_svg(chart, shown).encode()).decode()
        t0, t1 = float(chart.time[0]), float(chart.time[-1])
        figures.append(
            f'<figure class="bwr-chart" data-t0="{t0!r}" data-t1="{t1!r}">'
            f'<img alt="{html.escape(chart.title)}" src="data:image/svg+xml;base64,{svg}"></figure>')
    left, right, bottom, top = PLOT_BOX
    width = f"{100 * COLUMN_SHARE:g}vw"
    style = f"""<style>
#root {{ position: fixed !important; left: 0; top: 0; bottom: 0; right: {width}; width: auto !important; }}
#bwr-charts {{ position: fixed; top: 0; right: 0; bottom: 0; width: {width}; overflow-y: auto;
  background: #fff; border-left: 1px solid #ddd; font-family: sans-serif; }}
#bwr-readout {{ font-size: 12px; padding: 0.4em 0.6em; border-bottom: 1px solid #eee; }}
#bwr-readout p {{ margin: 0 0 0.3em; }}
#bwr-readout td, #bwr-readout th {{ padding: 0 0.5em; text-align: right; white-space: nowrap; }}
#bwr-readout td:first-child, #bwr-readout th:first-child {{ text-align: left; }}
#bwr-charts figure {{ position: relative; margin: 0.4em; cursor: pointer; }}
#bwr-charts img {{ width: 100%; display: block; }}
#bwr-charts .bwr-plot {{ position: absolute; left: {left * 100:.3f}%; right: {(1 - right) * 100:.3f}%;
  top: {(1 - top) * 100:.3f}%; bottom: {bottom * 100:.3f}%; pointer-events: none; }}
</style>"""
    data = ""
    if readout is not None:  # "</" cannot end the script early: JSON escapes no slash, so do it here
        data = ('<script type="application/json" id="bwr-readout-data">'
                + json.dumps(readout, separators=(",", ":")).replace("</", "<\\/") + "</script>")
        figures.insert(0, '<div id="bwr-readout"></div>')
    scripts = export_script(start, speed)
    if scanner is not None:
        choices = "".join(f'<option value="{kind}">{kind}</option>' for kind in PILE_SHOWN)
        figures.insert(0, f'<div id="bwr-scanner"><label>Pile shown <select id="{SCANNER_PILE_ID}">{choices}</select>'
                          f'</label><label><input type="checkbox" id="{SCANNER_FAN_ID}" checked> Scan fan and hits'
                          f'</label><p><i>Scanned</i>: {html.escape(scanner)}</p></div>')
        scripts += export_scanner_script()
        style += SCANNER_STYLE
    return f'{style}{data}<div id="bwr-charts">{"".join(figures)}</div><script>{scripts}</script>'
