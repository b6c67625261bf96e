"""What surrounds the machine: the stockpile, the ground's extent and the initial camera.

All of it is derived from the via points and the machine's drawn extent, never from fixed
machine dimensions, so another MJCF or another path gets a fitting pile and view.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bwr_twin.pile.surface import Surface

ANGLE_OF_REPOSE = np.radians(37.0)  # iron ore fines; sets the slope of the pile's flanks
RECLAIM_REACH_FRACTION = 0.5  # via points at least this share of the largest lateral reach dig the pile
CREST_HEIGHT_FRACTION = 0.9  # of the lowest digging CP: the wheel cuts in, the CP path stays in sight
CAMERA_DIRECTION = np.array([-0.55, -0.7, 0.45])  # scene centre to camera, for a pile on the +Y side
CAMERA_FOV = np.radians(45.0)  # vertical field of view
FRAME_MARGIN = 0.06  # share of the picture's half-width and half-height kept clear around the scene
FIT_STEPS = 40  # bisections of the camera's distance: a relative precision far below a pixel
CAPTION_HEIGHT = 0.8  # of the picture's half-height above its centre: where a text overlay goes
ASPECT = 1.6  # width / height of a typical browser window
PAINTED_SAMPLES = 20_000  # height samples of a painted pile drawn as a height map


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


def painted_heights(pile: Pile, samples: int = PAINTED_SAMPLES) -> Surface:
    """The pile as heights on a grid of about `samples` points over its base: its crest height
    within the crest, falling at the flanks' slope with the distance from the crest (the larger
    of the two along X and Y, which makes the hipped ends) to the ground."""
    base, crest = pile.vertices[:4], pile.vertices[4:]
    (x0, y0), (x1, y1) = base[:, :2].min(axis=0), base[:, :2].max(axis=0)
    height, spread = float(crest[0, 2]), float(crest[0, 0] - base[0, 0])
    spacing = float(np.sqrt((x1 - x0) * (y1 - y0) / samples))
    x = np.arange(x0, x1 + spacing / 2, spacing)
    y = np.arange(y0, y1 + spacing / 2, spacing)
    (cx0, cy0), (cx1, cy1) = crest[:, :2].min(axis=0), crest[:, :2].max(axis=0)
    beyond_x = np.maximum.reduce([cx0 - x, np.zeros_like(x), x - cx1])
    beyond_y = np.maximum.reduce([cy0 - y, np.zeros_like(y), y - cy1])
    z = height * (1.0 - np.maximum(beyond_x[None, :], beyond_y[:, None]) / spread)
    return Surface(x, y, np.clip(z, 0.0, None))


@dataclass(frozen=True)
class View:
    """Where the initial camera stands and what it looks at, in world coordinates (m)."""

    position: np.ndarray
    look_at: np.ndarray
    caption: np.ndarray  # a point near the top centre of the initial picture, for a text overlay
    ground_centre: np.ndarray  # (2,) XY
    ground_size: float  # m, side of the square ground


def frame_view(
    points: np.ndarray, pile_side: float, panel_share: float = 0.0, fov: float = CAMERA_FOV,
    aspect: float = ASPECT,
) -> View:
    """A camera on the rail's side of the scene (away from the pile, `pile_side` = sign of its
    Y offset), high enough to look over the machine, as close as it can stand with all `points`
    (machine, pile, path) in its picture, whose vertical field of view is `fov` (rad) and whose
    width is `aspect` times its height; and a ground that reaches well past them.

    `panel_share` is the part of the window's width a panel covers on the right: the points are
    fitted into the rest. The fit is exact for the perspective, so a machine near the camera
    does not spill out of the picture while a long pile far from it fits.
    """
    low, high = points.min(axis=0), points.max(axis=0)
    centre = (low + high) / 2
    direction = CAMERA_DIRECTION * (1.0, pile_side, 1.0)
    direction = direction / np.linalg.norm(direction)
    right = np.cross(-direction, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    screen_up = np.cross(right, -direction)
    # The picture's edges as slopes from the view axis: left, right (short of the panel), bottom, top.
    tan_v = np.tan(fov / 2) * (1.0 - FRAME_MARGIN)
    tan_h = tan_v * aspect
    edges = (-tan_h, tan_h * (1.0 - 2.0 * panel_share), -tan_v, tan_v)
    relative = points - centre
    across, up, towards = relative @ right, relative @ screen_up, relative @ direction

    def shifts(distance: float) -> tuple[float, float, float, float] | None:
        """The range of sideways and upward shifts of a camera at `distance` from the centre's
        plane that keep every point in the picture, or None if there is none."""
        depth = distance - towards
        if depth.min() <= 0:
            return None
        left, right_, bottom, top = edges
        x = (float(np.max(across - right_ * depth)), float(np.min(across - left * depth)))
        y = (float(np.max(up - top * depth)), float(np.min(up - bottom * depth)))
        return (*x, *y) if x[0] <= x[1] and y[0] <= y[1] else None

    near, far = float(towards.max()), float(towards.max()) + 2.0 * float(np.linalg.norm(high - low)) / tan_v + 1.0
    while shifts(far) is None:  # a narrow picture beside a wide panel: farther still
        near, far = far, 2.0 * far
    for _ in range(FIT_STEPS):  # bisect for the nearest distance at which the points fit
        middle = (near + far) / 2
        near, far = (near, middle) if shifts(middle) is not None else (middle, far)
    x0, x1, y0, y1 = shifts(far)
    look_at = centre + (x0 + x1) / 2 * right + (y0 + y1) / 2 * screen_up
    picture_centre = -panel_share * tan_h * far  # the middle of the part the panel leaves
    caption = look_at + picture_centre * right + CAPTION_HEIGHT * tan_v * far * screen_up
    ground = max(high[0] - low[0], high[1] - low[1]) * 3
    return View(look_at + far * direction, look_at, caption, centre[:2], ground)
