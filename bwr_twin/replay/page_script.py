"""The page's part of the charts: a cursor line at the current time on every chart, and a click on
a chart that seeks the timeline to the time clicked; in the live page and in the HTML export.

viser sends the charts' data and options, but no chart event reaches the server and a chart has no
marker that moves without sending its data again. So a small script runs in the page: on every
animation frame it reads the time slider's value and moves a line over each uPlot chart (found
through viser's `__viserTestpoints.uplots` registry), and a click types the clicked time into the
slider's number box, which viser sends to the server like a user's entry. The player, the time's
one owner, then seeks as for any other entry. GUI HTML cannot hold a <script>, so the script rides
in an image's error handler, once per page.

The export's charts are images beside the recorded scene (bwr_twin.replay.export_charts): its
script reads the playback bar's time instead, and a click types the matching playback time into
the bar's number box. Above them, it writes several runs' readout from the errors the page holds.
"""

from __future__ import annotations

import base64

CURSOR_CLASS = "bwr-time-cursor"  # the cursor line's element, one per chart (tests look for it)
CURSOR_COLOUR = "#555555"

_LIVE = r"""
(() => {
  if (window.bwrTimelineCharts) return;  // the element holding this may mount again
  window.bwrTimelineCharts = true;
  const sliderId = "%(slider)s", step = %(step)r;
  const charts = () => Object.values(window.__viserTestpoints?.uplots ?? {}).map((entry) => entry.chart);
  const pressed = new WeakMap();  // chart -> where a press began: a drag zooms, a click seeks
  function cursorOf(chart) {
    let line = chart.over.querySelector(".%(cursor)s");
    if (!line) {
      line = document.createElement("div");
      line.className = "%(cursor)s";
      line.style.cssText = "position:absolute;top:0;bottom:0;width:0;border-left:1.5px solid %(colour)s;" +
        "pointer-events:none;z-index:5";
      chart.over.appendChild(line);
      chart.over.style.cursor = "pointer";
      chart.over.addEventListener("mousedown", (event) => pressed.set(chart, event.clientX));
      chart.over.addEventListener("click", (event) => {
        if (Math.abs(event.clientX - (pressed.get(chart) ?? event.clientX)) > 3) return;
        seek(chart.posToVal(event.offsetX, "x"));
      });
    }
    return line;
  }
  function slider() {
    return document.getElementById(sliderId);
  }
  function seek(t) {
    const box = slider()?.parentElement?.querySelector("input:not([type=hidden])");
    if (!box || !Number.isFinite(t)) return;
    const thumb = slider().querySelector('[role="slider"]');
    const low = Number(thumb.getAttribute("aria-valuemin")), high = Number(thumb.getAttribute("aria-valuemax"));
    const setValue = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, "value").set;
    const clamped = Math.min(Math.max(t, low), high);
    setValue.call(box, (Math.round(clamped / step) * step).toFixed(Math.max(0, -Math.floor(Math.log10(step)))));
    box.dispatchEvent(new Event("input", { bubbles: true }));
  }
  function frame() {
    const thumb = slider()?.querySelector('[role="slider"]');
    if (thumb) {
      const t = Number(thumb.getAttribute("aria-valuenow"));
      for (const chart of charts()) {
        const line = cursorOf(chart);
        const x = chart.valToPos(t, "x");
        const inside = Number.isFinite(x) && x >= 0 && x <= chart.over.clientWidth;
        line.style.display = inside ? "block" : "none";
        if (inside) line.style.left = x + "px";
        line.dataset.time = String(t);
      }
    }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
"""


_EXPORT = r"""
(() => {
  // The playback bar's slider (the page's only one) gives the recording's time p; the runs' is start + p * speed.
  const start = %(start)r, speed = %(speed)r;
  const figures = [...document.querySelectorAll(".bwr-chart")];
  const playback = () => document.querySelector('[role="slider"]');
  for (const figure of figures) {
    const plot = document.createElement("div");
    plot.className = "bwr-plot";
    const line = document.createElement("div");
    line.className = "%(cursor)s";
    line.style.cssText = "position:absolute;top:0;bottom:0;width:0;border-left:1.5px solid %(colour)s";
    plot.appendChild(line);
    figure.appendChild(plot);
    figure.addEventListener("click", (event) => {
      const box = plot.getBoundingClientRect();
      const share = Math.min(Math.max((event.clientX - box.left) / box.width, 0), 1);
      const t0 = Number(figure.dataset.t0), t1 = Number(figure.dataset.t1);
      seek(t0 + share * (t1 - t0));
    });
  }
  function seek(t) {
    const box = playback()?.closest(".mantine-Paper-root")?.querySelector("input.mantine-NumberInput-input");
    if (!box) return;
    const setValue = Object.getOwnPropertyDescriptor(HTMLInputElement.prototype, "value").set;
    setValue.call(box, String(Math.max(0, (t - start) / speed)));
    box.dispatchEvent(new Event("input", { bubbles: true }));
  }
  // Several runs' readout: each run's errors at the playback's time, linear between records.
  const data = JSON.parse(document.getElementById("bwr-readout-data")?.textContent ?? "null");
  const table = document.getElementById("bwr-readout");
  function interpolate(times, values, t) {
    let low = 0, high = times.length - 1;
    if (t <= times[0]) return values[0];
    if (t >= times[high]) return values[high];
    while (high - low > 1) {
      const middle = (low + high) >> 1;
      if (times[middle] <= t) low = middle; else high = middle;
    }
    const share = (t - times[low]) / (times[high] - times[low]);
    return values[low] + share * (values[high] - values[low]);
  }
  let readAt = null;
  function showReadout(t) {
    if (!data || !table || t === readAt) return;
    readAt = t;
    const signed = (value) => (value >= 0 ? "+" : "") + value.toFixed(4);
    const head = `<tr><th>run</th>${data.axes.map((a, j) => `<th>${a} [${data.units[j]}]</th>`).join("")}` +
      (data.rates ? "<th>rate [t/h]</th>" : "") + "</tr>";
    const rows = data.runs.map((run) => {
      const cells = run.error.map((values) => `<td>${signed(interpolate(run.time, values, t))}</td>`).join("");
      const rate = data.rates ? `<td>${run.rate ? Math.round(interpolate(run.time, run.rate, t)).toLocaleString("en") : ""}</td>` : "";
      return `<tr><td><span style="color:${run.colour}">&#9632;</span> ${run.name}</td>${cells}${rate}</tr>`;
    }).join("");
    table.innerHTML = `<p><b>t = ${t.toFixed(1)} s</b> of ${data.duration} s; error = desired - actual</p>` +
      `<table>${head}${rows}</table>`;
  }
  function frame() {
    const thumb = playback();
    if (thumb) {
      const t = start + Number(thumb.getAttribute("aria-valuenow")) * speed;
      showReadout(t);
      for (const figure of figures) {
        const t0 = Number(figure.dataset.t0), t1 = Number(figure.dataset.t1);
        const line = figure.querySelector(".%(cursor)s");
        line.style.left = (100 * Math.min(Math.max((t - t0) / (t1 - t0), 0), 1)) + "%%";
        line.dataset.time = String(t);
      }
    }
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
"""


# The export's scanner controls: which pile and whether the fan show, at every site whose run scanned.
# A recording's nodes have no GUI to hide them, and viser sets each three.js object's `visible` from
# its own state every frame; so the script gives the nodes /sites/<k>/pile, /scanned and /scan a
# `visible` that says what the controls choose (their children follow: three.js skips the children
# of a hidden object), again whenever the playback makes the node anew.
_EXPORT_SCANNER = r"""
(() => {
  const pile = document.getElementById("%(pile)s"), fan = document.getElementById("%(fan)s");
  const NODE = /^\/sites\/\d+\/(pile|scanned|scan)$/;
  function wanted(kind) {
    if (kind === "scan") return fan.checked;
    return (kind === "pile") === (pile.value === "true");
  }
  function frame() {
    const nodes = window.__viserMutable?.nodeRefFromName ?? {};
    let changed = false;
    for (const [name, node] of Object.entries(nodes)) {
      const match = NODE.exec(name);
      if (!match || !node) continue;
      if (!node.bwrChosen) {
        let own = node.visible;
        Object.defineProperty(node, "visible", {
          configurable: true,
          get() { return this.bwrShown ?? own; },
          set(value) { own = value; },
        });
        node.bwrChosen = true;
      }
      const shown = wanted(match[1]);
      if (node.bwrShown !== shown) {
        node.bwrShown = shown;
        changed = true;
      }
    }
    if (changed) window.__viserMutable?.requestRender?.();
    requestAnimationFrame(frame);
  }
  requestAnimationFrame(frame);
})();
"""
SCANNER_PILE_ID = "bwr-pile-shown"  # the export's <select> of the pile shown (tests look for it)
SCANNER_FAN_ID = "bwr-fan-shown"  # its checkbox of the scan fan and hits


def export_scanner_script() -> str:
    """The export's script for its scanner controls (SCANNER_PILE_ID, SCANNER_FAN_ID)."""
    return _EXPORT_SCANNER % {"pile": SCANNER_PILE_ID, "fan": SCANNER_FAN_ID}


def export_script(start: float, speed: float) -> str:
    """The export's script: the charts' cursors at the playback's time, a click seeks the playback."""
    return _EXPORT % {"start": float(start), "speed": float(speed), "cursor": CURSOR_CLASS, "colour": CURSOR_COLOUR}


def live_script_html(slider_id: str, step: float) -> str:
    """GUI HTML that installs the charts' cursor and click-to-seek for the time slider whose
    element id is `slider_id` and whose step is `step` (s)."""
    script = _LIVE % {"slider": slider_id, "step": float(step), "cursor": CURSOR_CLASS, "colour": CURSOR_COLOUR}
    encoded = base64.b64encode(script.encode()).decode()
    return f'<img src="data:," alt="" style="display:none" onerror="new Function(atob(\'{encoded}\'))()">'
