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
import numpy as np

from bwr_twin.errors import ModelError
from bwr_twin.model.mount import Mount, mount_of

SITE_PREFIX = "scanner"
# At most this many rays a scan: a whole circle at 0.1 deg, finer than any 2D profile scanner's
# step (the SICK LMS5xx's finest is 0.1667 deg over 190 deg, 1,141 rays); more is a typo in a step.
MAX_RAYS = 3600
_WHOLE_STEPS = 1e-6  # how near a whole number the fan's steps must come (rounding of radians)


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
                   (float(constant), float(share)), float(dropout), mount_of(model, data, int(model.site_bodyid[site]), data.site_xpos[site],
                                                                     data.site_xmat[site]))
