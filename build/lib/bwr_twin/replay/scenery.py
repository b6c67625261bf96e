"""What surrounds the machine: the stockpile, the ground's extent and the initial camera.

All of it is derived from the via points and the machine's drawn extent, never from fixed
machine dimensions, so another MJCF or another path gets a fitting pile and view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ANGLE_OF_REPOSE = np.radians(37.0)  # iron ore fines; sets the slope of the pile's flanks
RECLAIM_REACH_FRACTION = 0.5  # via points at least this share of the largest lateral reach dig the pile
CREST_HEIGHT_FRACTION = 0.9  # of the lowest digging CP: the wheel cuts in, the CP path stays in sight
CAMERA_DIRECTION = np.array([-0.55, -0.7, 0.45])  # scene centre to camera, for a pile on the +Y side
CAMERA_FOV = np.radians(45.0)  # vertical field of view
FRAME_FILL = 0.8  # share of the bounding sphere's diameter that must fit the picture's height
ASPECT = 1.6  # width / height of a typical browser window


@dataclass(frozen=True)
class Pile:
    """A stockpile: a hipped prism whose flat crest spans the reclaimed via points."""

    vertices: np.ndarray  # (8, 3) m: base corners, then crest corners
    faces: np.ndarray  # (10, 3): crest and four flanks
    side: float  # +1 or -1: the side of the rail it lies on (sign of Y)


def stockpile(via_points: np.ndarray, rail_y: float) -> Pile | None:
    """The pile the bucket wheel reclaims, or None when the path never leaves the rail's line.

    The crest spans the via points that reach out at least RECLAIM_REACH_FRACTION of the path's
    largest lateral reach (the ones in the pile, not the home position over the rail), a little
    below the lowest of them, so the wheel cuts into it; the flanks fall at the angle of repose
    to the ground.
    """
    lateral = via_points[:, 1] - rail_y
    reach = np.max(np.abs(lateral))
    if reach < 1e-6:
        return None
    side = np.sign(lateral[np.argmax(np.abs(lateral))])
    digging = via_points[side * lateral >= RECLAIM_REACH_FRACTION * reach]
    height = CREST_HEIGHT_FRACTION * float(digging[:, 2].min())
    if height <= 0:
        return None
    spread = height / np.tan(ANGLE_OF_REPOSE)
    x0, x1 = digging[:, 0].min(), digging[:, 0].max()
    y0, y1 = digging[:, 1].min(), digging[:, 1].max()
    base = [
        (x0 - spread, y0 - spread),
        (x1 + spread, y0 - spread),
        (x1 + spread, y1 + spread),
        (x0 - spread, y1 + spread),
    ]
    crest = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
    vertices = np.array([(x, y, 0.0) for x, y in base] + [(x, y, height) for x, y in crest])
    faces = [[4, 5, 6], [4, 6, 7]]  # crest
    for i in range(4):  # flanks, one quad per side of the base
        j = (i + 1) % 4
        faces += [[i, j, j + 4], [i, j + 4, i + 4]]
    return Pile(vertices, np.array(faces), float(side))


@dataclass(frozen=True)
class View:
    """Where the initial camera stands and what it looks at, in world coordinates (m)."""

    position: np.ndarray
    look_at: np.ndarray
    caption: np.ndarray  # a point near the top centre of the initial picture, for a text overlay
    ground_centre: np.ndarray  # (2,) XY
    ground_size: float  # m, side of the square ground


def frame_view(points: np.ndarray, pile_side: float, panel_share: float = 0.0) -> View:
    """A camera on the rail's side of the scene (away from the pile, `pile_side` = sign of its
    Y offset), high enough to look over the machine, that fits all `points` (machine, pile,
    path) into its field of view, and a ground that reaches well past them.

    `panel_share` is the part of the window's width a panel covers on the right; the scene is
    then centred in the rest.
    """
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    radius = float(np.linalg.norm(high - low) / 2)
    direction = CAMERA_DIRECTION * (1.0, pile_side, 1.0)
    direction = direction / np.linalg.norm(direction)
    distance = FRAME_FILL * radius / np.sin(CAMERA_FOV / 2)
    right = np.cross(-direction, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    screen_up = np.cross(right, -direction)
    half_height = distance * np.tan(CAMERA_FOV / 2)
    look_at = centre + panel_share * ASPECT * half_height * right
    caption = centre + 0.8 * half_height * screen_up
    ground = max(high[0] - low[0], high[1] - low[1]) * 3
    return View(look_at + distance * direction, look_at, caption, centre[:2], ground)
