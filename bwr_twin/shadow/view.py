"""The shadow's live view in the browser (viser): the machine as measured, solid in its MJCF
colours; the twin's prediction, the same machine seen through (a ghost), at the pose the twin
predicted for the end of the newest block; per axis a chart of its force and position residuals
over the last CHART_BLOCKS blocks; the health of each axis and the alarms.

The ghost parts from the solid machine by the position residual: on a healthy machine they
overlap to within millimetres, as they should. Meshes are sent once (bwr_twin.drawing.meshes);
a block then costs one pose per moving body of each machine and the charts' data.
"""

from __future__ import annotations

import contextlib
import io
import math

import numpy as np
import viser

from bwr_twin.drawing.meshes import Meshes
from bwr_twin.model.machine import Machine
from bwr_twin.shadow.detect import AXES, CLASSES, SOURCES, Alarm
from bwr_twin.shadow.twin import Blocks

CHART_BLOCKS = 300  # blocks (s) of residuals the charts show
TWIN_COLOUR = (90, 110, 255)  # the ghost: blue, as the replay's second machine
TWIN_OPACITY = 0.35  # seen through, as the replay's translucent machines: the solid one stays in front
FORCE_COLOUR, POSITION_COLOUR = "#eb5f14", "#5a6eff"
CAMERA_DIRECTION = np.array([-0.55, -0.7, 0.45])  # from the machine's centre to the camera: from the rail's side
CAMERA_DISTANCE = 0.9  # of the machine's extent (its bounding box's diagonal), from its centre
UNITS = (("N", "m"), ("N·m", "deg"), ("N·m", "deg"))  # force and position residual per axis, as charted
POSITION_SCALE = (1.0, math.degrees(1.0), math.degrees(1.0))  # m; rad to deg


class ShadowView:
    """The view on a viser server at http://`host`:`port` (0: a free port) until `stop()`.

    It takes what the shadow publishes: `residuals(blocks, measured_q)` with each new block and
    `verdict(health, alarms)` after its detectors ran, as the OPC UA server does."""

    def __init__(self, machine: Machine, *, host: str = "127.0.0.1", port: int = 8080):
        with contextlib.redirect_stdout(io.StringIO()):  # viser prints a banner; the shadow prints the URL
            self.server = viser.ViserServer(host=host, port=port, label="BWR shadow", verbose=False)
        self.host = host
        scene = self.server.scene
        self.measured = Meshes(scene, machine, "/measured", False, (0, 0, 0), ("model", 1.0))
        self.twin = Meshes(scene, machine, "/twin", True, TWIN_COLOUR, ("translucent", TWIN_OPACITY))
        home = np.zeros(3)
        for meshes in (self.measured, self.twin):
            meshes.place(home)
        vertices = self.measured.vertices(home)
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        centre, extent = (low + high) / 2, float(np.linalg.norm(high - low))
        direction = CAMERA_DIRECTION / np.linalg.norm(CAMERA_DIRECTION)
        self.server.initial_camera.position = tuple(centre + CAMERA_DISTANCE * extent * direction)
        self.server.initial_camera.look_at = tuple(centre)
        self.server.initial_camera.up = (0.0, 0.0, 1.0)
        scene.add_grid("/ground", width=extent, height=extent, position=(centre[0], centre[1], low[2]))
        gui = self.server.gui
        gui.configure_theme(control_width="large", show_share_button=False)
        with gui.add_folder("Alarms"):
            self.alarms = gui.add_markdown("No alarm. The machine moves as its twin predicts.")
        with gui.add_folder("Health"):
            self.health = gui.add_markdown(_health_table(dict.fromkeys(SOURCES, 100.0)))
        self._time = np.zeros(0)
        self._force = np.zeros((0, 3))
        self._position = np.zeros((0, 3))
        self.charts = []
        with gui.add_folder("Residuals"):
            for j, axis in enumerate(AXES):
                force, position = UNITS[j]
                self.charts.append(gui.add_uplot(
                    (np.zeros(1), np.zeros(1), np.zeros(1)),
                    ({"label": "t [s]"},
                     {"label": f"force [{force}]", "stroke": FORCE_COLOUR, "scale": "force", "width": 1.5},
                     {"label": f"position [{position}]", "stroke": POSITION_COLOUR, "scale": "position",
                      "width": 1.5}),
                    title=f"{axis.capitalize()}: the measured machine less its twin",
                    scales={"x": {"time": False}, "force": {"auto": True}, "position": {"auto": True}},
                    axes=({"label": "t [s]"}, {"scale": "force", "label": force},
                          {"scale": "position", "label": position, "side": 1, "grid": {"show": False}}),
                    aspect=2.0))

    @property
    def url(self) -> str:
        host = "127.0.0.1" if self.host in ("0.0.0.0", "::", "") else self.host
        return f"http://{host}:{self.server.get_port()}"

    async def residuals(self, blocks: Blocks, measured_q: np.ndarray, arrived: float | None = None) -> None:
        """Pose the measured machine at `measured_q` (the encoders at the newest block's end) and
        the ghost where the twin predicted it; add the blocks' residuals to the charts."""
        if not len(blocks.start):
            return
        self._time = np.concatenate([self._time, blocks.end])[-CHART_BLOCKS:]
        self._force = np.concatenate([self._force, blocks.force])[-CHART_BLOCKS:]
        self._position = np.concatenate([self._position, blocks.position])[-CHART_BLOCKS:]
        with self.server.atomic():
            self.measured.place(measured_q)
            self.twin.place(measured_q - blocks.position[-1])  # the residual is measured less predicted
            for j, chart in enumerate(self.charts):
                chart.data = (self._time, self._force[:, j], self._position[:, j] * POSITION_SCALE[j])

    async def verdict(self, health: dict[str, float], alarms: list[Alarm]) -> None:
        """Show each source's health and every alarm so far."""
        self.health.content = _health_table(health)
        if alarms:
            self.alarms.content = "\n".join(f"- **{a.axis} {a.kind}** {a.estimate()}{a.undecided()} "
                                            f"(raised at {a.time_s:.1f} s): {CLASSES[a.kind]}" for a in alarms)

    async def stop(self) -> None:
        with contextlib.redirect_stdout(io.StringIO()):
            self.server.stop()


def _health_table(health: dict[str, float]) -> str:
    rows = "\n".join(f"| {source} | {value:.0f} % |" for source, value in health.items())
    return "| | health |\n| --- | --- |\n" + rows
