"""2D profile scanners on the machine, read from its MJCF, and where they stand for given joints.

A scanner is a `<site>` whose name starts with `scanner` (`scanner_boom`), with `<custom>`
numerics keyed by the site's name (docs/sensing.md, the model contract in docs/contracts.md):

    {site}_fan      start and end angle of the fan, rad
    {site}_step     angular step between rays, rad (it divides the fan into whole steps)
    {site}_rate     scans per second, Hz
    {site}_range    the farthest a ray measures, m
    {site}_noise    range noise: a constant (m) and a share of the range (sigma = a + b x range)
    {site}_dropout  the probability that a ray returns nothing

The rays lie in the site's x-z plane. A ray's angle is measured from the site's -z axis towards
its +x axis: 0 looks along -z, +pi/2 along +x, -pi/2 along -x; its direction in the site frame
is (sin a, 0, -cos a). A site on the boom whose frame is the boom's (x out along the boom, z up
across it) thus fans its rays in the boom's vertical plane, 0 looking down (at luff 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numba
import numpy as np

from bwr_twin.errors import ModelError

SITE_PREFIX = "scanner"
# At most this many rays a scan: a whole circle at 0.1 deg, finer than any 2D profile scanner's
# step (the SICK LMS5xx's finest is 0.1667 deg over 190 deg, 1,141 rays); more is a typo in a step.
MAX_RAYS = 3600
_WHOLE_STEPS = 1e-6  # how near a whole number the fan's steps must come (rounding of radians)


@dataclass(frozen=True, eq=False)
class Mount:
    """Where a site sits on the machine: its pose at q = 0 and the joints that move it.

    `position` (3,) world m and `rotation` (3, 3) (columns: the site's axes in world) at q = 0;
    the first `joints` of travel, slew, luff move it (the chain is serial), each about its
    `anchor` (3, 3) world m along its `axis` (3, 3), both at q = 0.
    """

    position: np.ndarray
    rotation: np.ndarray
    joints: int
    anchor: np.ndarray
    axis: np.ndarray

    def poses(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The site's world positions (runs, 3) and rotations (runs, 3, 3) for joints q (runs, 3)."""
        q = np.ascontiguousarray(q, dtype=float).reshape(-1, 3)
        position, rotation = np.empty((len(q), 3)), np.empty((len(q), 3, 3))
        site_poses(q, self.position, self.rotation, self.joints, self.anchor, self.axis, position, rotation)
        return position, rotation


@dataclass(frozen=True, eq=False)
class Scanner:
    """A 2D profile scanner: its site, fan, rate, range, noise and dropouts (the module's docstring)."""

    name: str  # the site's name
    site: int  # the site's id in the machine's model
    fan: tuple[float, float]  # rad, start and end
    step: float  # rad between rays
    rate: float  # Hz, scans a second
    max_range: float  # m
    noise: tuple[float, float]  # m, and a share of the range: the noise's standard deviation
    dropout: float  # probability a ray returns nothing
    mount: Mount

    @property
    def rays(self) -> int:
        return round((self.fan[1] - self.fan[0]) / self.step) + 1

    @property
    def angles(self) -> np.ndarray:
        """(rays,) rad, from the fan's start to its end."""
        return self.fan[0] + np.arange(self.rays) * self.step

    @property
    def period(self) -> float:
        """s between scans."""
        return 1.0 / self.rate

    @property
    def directions(self) -> np.ndarray:
        """(rays, 3) unit directions of the rays in the site's frame."""
        angles = self.angles
        return np.column_stack([np.sin(angles), np.zeros(len(angles)), -np.cos(angles)])


def read_scanners(model: mujoco.MjModel, path: Path) -> tuple[Scanner, ...]:
    """The scanners of a compiled machine, in site order; () if it has none. Raises ModelError
    naming the file, the site and the key of a numeric that is missing or out of its range."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, s) or "" for s in range(model.nsite)]
    sites = [s for s, name in enumerate(names) if name.startswith(SITE_PREFIX)]
    if not sites:
        return ()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # q = 0
    return tuple(_scanner(model, data, path, names[s], s) for s in sites)


def _scanner(model: mujoco.MjModel, data: mujoco.MjData, path: Path, name: str, site: int) -> Scanner:
    def numeric(suffix: str, count: int, meaning: str) -> np.ndarray:
        key = f"{name}_{suffix}"
        n = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_NUMERIC, key)
        if n < 0:
            raise ModelError(f"{path}: scanner site '{name}' needs custom numeric '{key}' ({meaning})")
        values = model.numeric_data[model.numeric_adr[n]: model.numeric_adr[n] + model.numeric_size[n]]
        if len(values) != count or not np.all(np.isfinite(values)):
            raise ModelError(f"{path}: custom numeric '{key}' of scanner site '{name}' must hold {count} finite "
                             f"value{'s' if count > 1 else ''} ({meaning}), got {values.tolist()}")
        return values.astype(float)

    def refuse(suffix: str, rule: str, value) -> ModelError:
        return ModelError(f"{path}: custom numeric '{name}_{suffix}' of scanner site '{name}' {rule}, got {value}")

    start, end = numeric("fan", 2, "start and end angle, rad")
    if not -math.pi <= start < end <= math.pi:
        raise refuse("fan", "must hold start < end within [-pi, pi] rad", [start, end])
    (step,) = numeric("step", 1, "rad between rays")
    steps = (end - start) / step if step > 0 else np.nan
    if not step > 0 or abs(steps - round(steps)) > _WHOLE_STEPS * max(steps, 1.0):
        raise refuse("step", f"must be > 0 and divide the fan's {end - start:.6g} rad into whole steps", step)
    if round(steps) + 1 > MAX_RAYS:
        raise refuse("step", f"gives {round(steps) + 1} rays a scan, more than {MAX_RAYS}", step)
    (rate,) = numeric("rate", 1, "scans a second, Hz")
    if not rate > 0:
        raise refuse("rate", "must be > 0 Hz", rate)
    (max_range,) = numeric("range", 1, "the farthest a ray measures, m")
    if not max_range > 0:
        raise refuse("range", "must be > 0 m", max_range)
    constant, share = numeric("noise", 2, "m, and a share of the range")
    if not (constant >= 0 and share >= 0):
        raise refuse("noise", "must hold two values >= 0", [constant, share])
    (dropout,) = numeric("dropout", 1, "the probability a ray returns nothing")
    if not 0 <= dropout < 1:
        raise refuse("dropout", "must lie in [0, 1)", dropout)
    return Scanner(name, site, (float(start), float(end)), float(step), float(rate), float(max_range),
                   (float(constant), float(share)), float(dropout), _mount(model, data, site))


def _mount(model: mujoco.MjModel, data: mujoco.MjData, site: int) -> Mount:
    """The site's pose at q = 0 and the joints (the model contract's serial chain) that move it."""
    ancestors, body = set(), int(model.site_bodyid[site])
    while body > 0:
        ancestors.add(body)
        body = int(model.body_parentid[body])
    joints = sum(int(model.jnt_bodyid[j]) in ancestors for j in range(model.njnt))
    return Mount(position=data.site_xpos[site].copy(), rotation=data.site_xmat[site].reshape(3, 3).copy(),
                 joints=joints, anchor=data.xanchor[:3].copy(), axis=data.xaxis[:3].copy())


@numba.njit(cache=True)
def site_poses(q, position0, rotation0, joints, anchor, axis, position, rotation):  # pragma: no cover - compiled
    """A site's world positions (runs, 3) and rotations (runs, 3, 3) for each run's joints q (runs, 3)."""
    for run in range(q.shape[0]):
        site_pose(q[run], position0, rotation0, joints, anchor, axis, position[run], rotation[run])


@numba.njit(cache=True)
def site_pose(q, position0, rotation0, joints, anchor, axis, position, rotation):  # pragma: no cover - compiled
    """A site's world pose for joints q (3,): its pose at q = 0 moved by the luff about its pivot,
    then the slew about its axis, then the travel along the rail (the serial chain's joints in
    world at q = 0, innermost first), for the first `joints` of them; into position (3,) and
    rotation (3, 3)."""
    position[:] = position0
    rotation[:] = rotation0
    turn = np.empty((3, 3))
    for j in range(joints - 1, -1, -1):
        k = axis[j]
        if j == 0:  # travel: a slide along its axis
            for a in range(3):
                position[a] += q[0] * k[a]
            continue
        c, s = math.cos(q[j]), math.sin(q[j])
        for a in range(3):  # Rodrigues: I cos + sin [k]x + (1 - cos) k k'
            for b in range(3):
                turn[a, b] = (1.0 - c) * k[a] * k[b] + (c if a == b else 0.0)
        turn[0, 1] -= s * k[2]
        turn[0, 2] += s * k[1]
        turn[1, 0] += s * k[2]
        turn[1, 2] -= s * k[0]
        turn[2, 0] -= s * k[1]
        turn[2, 1] += s * k[0]
        arm = position - anchor[j]
        for a in range(3):
            position[a] = anchor[j, a] + turn[a, 0] * arm[0] + turn[a, 1] * arm[1] + turn[a, 2] * arm[2]
        for col in range(3):
            r0, r1, r2 = rotation[0, col], rotation[1, col], rotation[2, col]
            for a in range(3):
                rotation[a, col] = turn[a, 0] * r0 + turn[a, 1] * r1 + turn[a, 2] * r2
