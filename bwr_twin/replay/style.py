"""How the replay draws: colours, line widths and opacity, shared by the live page, the HTML
export and the charts, so that a run has one colour everywhere."""

from __future__ import annotations

from bwr_twin.drawing.geometry import rgb  # noqa: F401  (the replay's modules take it from here)

DESIRED_COLOUR = (60, 120, 230)
ACTUAL_COLOUR = (235, 95, 20)  # the first run's trail
GHOST_COLOUR = (90, 110, 255)  # the second run's
TARGET_COLOUR = (220, 30, 30)
VIA_COLOUR = (30, 30, 30)
ORE_COLOUR = (112, 66, 44)
GROUND_COLOUR = (205, 196, 178)
# A laser scanner's: its fan green like a laser line, the rays that returned nothing paler, its hits
# yellow over the ore, and the pile known from them a cool grey-blue, unlike any ore.
FAN_COLOUR = (20, 200, 80)
MISS_COLOUR = (150, 220, 170)
HIT_COLOUR = (255, 225, 30)
KNOWN_COLOUR = (95, 130, 170)
# Each run's colour, in order: trail, chart lines, and its machine when painted in it. Far from
# the desired path's blue, the target's red and the ore's brown.
RUN_COLOURS = (ACTUAL_COLOUR, GHOST_COLOUR, (40, 160, 70), (170, 60, 200), (20, 170, 190), (120, 120, 120),
               (150, 150, 30), (210, 60, 130))
GHOST_OPACITY = 0.35  # a translucent machine: seen through, the solid one stays in front
PATH_STEP = 1.0  # s between drawn points of a path or trail
LINE_WIDTH = 2.5  # px, a desired path; a trail is twice as wide
MARKER_SCALE = 0.01  # marker radius as a share of the path's extent
LABEL_MERGE = 4.0  # via points closer than this many marker radii share one label


def run_colour(k: int) -> tuple[int, int, int]:
    """Run k's colour (0-255)."""
    return RUN_COLOURS[k % len(RUN_COLOURS)]


def hex_colour(colour: tuple[int, int, int]) -> str:
    return "#" + "".join(f"{c:02x}" for c in colour)
