"""A reclaimer loaded from any MJCF file that meets the model contract (docs/contracts.md).

Everything the kinematics needs (where the slew axis stands, where the luff pivot sits, how far
out the bucket wheel centre CP is) is read from the compiled model at q = 0, and the operating
envelope from the file's `<custom>` data, so swapping the file is enough to swap the machine.

Forward and inverse kinematics are the closed forms of the paper's Eq. (2) and (3), written for
that geometry: a slew axis at (sx, sy), a luff pivot `pivot_reach` out from it at height
`pivot_height`, and a CP `boom_length` from the pivot at elevation `boom_angle0 + luff`.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numba
import numpy as np

from bwr_twin.errors import EnvelopeError, ModelError, UnreachableError
from bwr_twin.model.dynamics import ChainDynamics
from bwr_twin.model.instruments import BeltScaleSpec, WheelMotorSpec, read_instruments
from bwr_twin.model.scanner import Scanner, read_scanners
from bwr_twin.model.shapes import read_collision_shapes
from bwr_twin.model.spec import Drawing, Edits, Heights, Payload, compile_model
from bwr_twin.textfile import version

AXES = ("travel", "slew", "luff")
UNITS = ("m", "deg", "deg")  # display units; the code works in SI (m, rad)
# The CP's site: a reclaimer's bucket wheel centre, or a stacker's discharge point at its boom tip.
CP_SITES = ("bucket_wheel_center", "discharge_point")
ENVELOPE_KEY = "envelope_{axis}"
WHEEL_KEYS = ("wheel_diameter", "wheel_width", "wheel_buckets", "bucket_volume", "wheel_discharges_per_minute")
WHEEL_POWER_KEY = "wheel_power"  # optional: without it, the cutting force has no ceiling
# Optional, each with its default in Wheel: the cut's flanks, the highest bench, the turn's clearance.
WHEEL_SIDE_SLOPE_KEY = "wheel_side_slope"
WHEEL_BENCH_SHARE_KEY = "wheel_bench_share"
WHEEL_CLEARANCE_KEY = "wheel_clearance"
RAIL_CLEARANCE_KEY = "rail_clearance"
RATED_SPEED_KEY = "rated_speed_{axis}"  # optional: without it, an axis has no rated speed (inf)
# Optional `<custom><text>` entries naming the machine, as OPC 40001-1 identifies one (bwr_twin.serve), and
# the rest of its nameplate, as the Asset Administration Shell's Digital Nameplate holds it (bwr_twin.export aas).
IDENTIFICATION_KEYS = ("manufacturer", "model", "serial_number", "year_of_construction", "manufacturer_country",
                       "manufacturer_city", "manufacturer_street", "manufacturer_zipcode")
# Axis of each joint in world coordinates at q = 0: rail +X, slew +Z, luff -Y (raising the CP).
CONTRACT_AXES = {"travel": (1.0, 0.0, 0.0), "slew": (0.0, 0.0, 1.0), "luff": (0.0, -1.0, 0.0)}
_TOL = 1e-9


def to_display(axis_index: int, value):
    """A joint value, or an array of them, in its display unit (m or degrees)."""
    return value if axis_index == 0 else np.degrees(value)


def describe(axis_index: int, value: float) -> str:
    """A joint value with its unit, for messages: '12.300 m' or '90.000 deg'."""
    return f"{to_display(axis_index, value):.3f} {UNITS[axis_index]}"


def paper_to_world(p: np.ndarray) -> np.ndarray:
    """Paper frame 0 (x lateral, y down, z along the rail) to world (Z up, rail along +X)."""
    p = np.asarray(p, dtype=float)
    return np.stack([p[..., 2], -p[..., 0], -p[..., 1]], axis=-1)


def world_to_paper(p: np.ndarray) -> np.ndarray:
    """World to paper frame 0: x_p = -Y, y_p = -Z, z_p = X."""
    p = np.asarray(p, dtype=float)
    return np.stack([-p[..., 1], -p[..., 2], p[..., 0]], axis=-1)


@dataclass(frozen=True)
class Geometry:
    """Link geometry derived from the compiled model (the paper's L2-L5 equivalents)."""

    slew_axis_xy: tuple[float, float]  # world XY of the slew axis at travel = 0 [m]
    pivot_reach: float  # slew axis to luff pivot, horizontal (paper L4) [m]
    pivot_height: float  # luff pivot above the rail (paper L2 + L3) [m]
    boom_length: float  # luff pivot to CP (paper L5) [m]
    boom_angle0: float  # elevation of pivot-to-CP at luff = 0 [rad]


@dataclass(frozen=True)
class Wheel:
    """The bucket wheel's cutting geometry and capacity, from the MJCF's `<custom>` numerics."""

    diameter: float  # m, the cutting circle
    width: float  # m, the buckets' width
    buckets: int
    bucket_volume: float  # m^3 one bucket holds
    discharges_per_minute: float  # buckets emptied a minute (buckets x rpm)
    power: float = np.inf  # W, the wheel drive's rating: the most it can cut with
    # Without their keys in the file: flanks at 80.5 deg, a few grid cells wide (docs/stockpile.md);
    # benches at most 0.6 x D, the bulk-handling rule (docs/reclaiming.md); half a metre of clearance.
    side_slope: float = 6.0  # m the cut's flanks rise per m beside the buckets' width
    bench_share: float = 0.6  # the highest bench the wheel takes, as a share of its diameter
    clearance: float = 0.5  # m the wheel turns clear of the pile's edge beyond its speed ramp

    @property
    def radius(self) -> float:
        return self.diameter / 2

    @property
    def capacity(self) -> float:
        """The most material the buckets carry away, m^3/s."""
        return self.discharges_per_minute * self.bucket_volume / 60.0

    @property
    def bucket_interval(self) -> float:
        """s between two discharges: each bucket's time in the cut."""
        return 60.0 / self.discharges_per_minute

    @property
    def rim_speed(self) -> float:
        """Speed of the bucket lips, m/s."""
        return np.pi * self.diameter * self.discharges_per_minute / self.buckets / 60.0


@dataclass(frozen=True)
class Limits:
    """How far and how fast the machine may move: what the drives and the file's ratings allow.

    joint_range: (3, 2) mechanical end stops (inf where a joint is unlimited).
    envelope: (3, 2) operating envelope per axis, [low, high] in m and rad.
    drive_limits: (3, 2) generalised force limits of the drives in N and N m (inf if none).
    rated_speed: (3,) the drives' rated speeds in m/s and rad/s (inf where the file gives none).
    """

    joint_range: np.ndarray
    envelope: np.ndarray
    drive_limits: np.ndarray
    rated_speed: np.ndarray


@dataclass(frozen=True)
class Sensors:
    """The instruments the file's sites and `<custom>` numerics describe: the 2D laser scanners
    (bwr_twin.model.scanner; () if none) and the rate instruments (bwr_twin.model.instruments,
    each None if the file has none)."""

    scanners: tuple[Scanner, ...]
    belt_scale: BeltScaleSpec | None
    wheel_motor: WheelMotorSpec | None


class Machine:
    """A compiled reclaimer model with its geometry, envelope and kinematics.

    Attributes:
        path: the MJCF file.
        model: the compiled MjModel; simulation parts make their own MjData from it.
        geometry: link geometry read from the model.
        envelope: (3, 2) operating envelope per axis, [low, high] in m and rad.
        joint_range: (3, 2) mechanical end stops (inf where a joint is unlimited).
        drive_limits: (3, 2) generalised force limits of the drives in N and N m (inf if none).
        wheel: the bucket wheel, or None if the file does not describe one (it cannot dig).
        rail_clearance: half-width (m) of the strip beside the rail axis that the machine's
            carriage takes, where no stockpile may lie (0 if the file does not say).
        rated_speed: (3,) the drives' rated speeds in m/s and rad/s (inf where the file gives none).
        identification: the file's `<custom><text>` entries of IDENTIFICATION_KEYS, key -> text
            (only those it has); `name` the `<mujoco model=...>` name.
        scanners: the 2D laser scanners on the machine, its sites named `scanner...` with their
            `<custom>` numerics (bwr_twin.model.scanner); () if it has none.
        belt_scale, wheel_motor: the rate instruments its `<custom>` numerics describe
            (bwr_twin.model.instruments), each None if it has none.
        collision_shapes: its collision geoms (group 5, `collision_<part>`,
            bwr_twin.model.shapes); () if it has none.
        limits, sensors: the records that hold joint_range, envelope, drive_limits, rated_speed
            (`Limits`) and scanners, belt_scale, wheel_motor (`Sensors`), which read through them.
    """

    @classmethod
    def shared(cls, path: str | Path, payloads: Sequence[Payload] = ()) -> Machine:
        """The machine of `path` with `payloads`, compiled once per version of the file and shared
        by whoever asks for the same: a scene's checks, its plan, its plant without a pile and its
        controller's belief. Read it, never change it."""
        path = Path(path)
        return _shared(path, version(path), tuple(payloads))

    def __init__(self, path: str | Path, *, payloads: Sequence[Payload] = (), stockpile: Heights | None = None,
                 stockpile_drawing: Drawing | None = None):
        """Compile `path`, adding each payload as a point mass on its body (what the plant
        carries and the file does not say, e.g. ore caked on the bucket wheel), and the
        stockpile, if given, as a heightfield in the world, drawn as `stockpile_drawing` says."""
        self.path = Path(path)
        self.payloads = tuple(payloads)
        self.model = compile_model(self.path, Edits(payloads=self.payloads, stockpile=stockpile,
                                                    stockpile_drawing=stockpile_drawing))
        self.joint_ids = self._check_joints()
        self.actuator_ids = self._check_actuators()
        self.cp_site = self._cp_site()
        self.geometry = self._derive_geometry()
        joint_range = np.array(
            [
                self.model.jnt_range[j] if self.model.jnt_limited[j] else (-np.inf, np.inf)
                for j in self.joint_ids
            ]
        )
        envelope = self._read_envelope(joint_range)
        drive_limits = self._drive_limits()
        self.wheel = self._read_wheel()
        rail_clearance = self._numeric(RAIL_CLEARANCE_KEY)
        self.rail_clearance = float(rail_clearance[0]) if rail_clearance is not None else 0.0
        self.limits = Limits(joint_range, envelope, drive_limits, self._read_rated_speed())
        self.identification = {key: text for key in IDENTIFICATION_KEYS if (text := self._text(key)) is not None}
        self.name = self.model.names[:self.model.names.index(b"\0")].decode()
        self.sensors = Sensors(read_scanners(self.model, self.path), *read_instruments(self.model, self.path))
        self.collision_shapes = read_collision_shapes(self.model, self.path, int(self.model.site_bodyid[self.cp_site]))

    @property
    def joint_range(self) -> np.ndarray:
        return self.limits.joint_range

    @property
    def envelope(self) -> np.ndarray:
        return self.limits.envelope

    @property
    def drive_limits(self) -> np.ndarray:
        return self.limits.drive_limits

    @property
    def rated_speed(self) -> np.ndarray:
        return self.limits.rated_speed

    @property
    def scanners(self) -> tuple[Scanner, ...]:
        return self.sensors.scanners

    @property
    def belt_scale(self) -> BeltScaleSpec | None:
        return self.sensors.belt_scale

    @property
    def wheel_motor(self) -> WheelMotorSpec | None:
        return self.sensors.wheel_motor

    def physics_model(self, timestep: float | None = None, *, rigid_body_only: bool = False,
                      neighbour: Path | None = None) -> mujoco.MjModel:
        """A physics-only copy of the model (no visual geoms) at `timestep` s (None: the file's).

        `rigid_body_only` leaves only what M and the bias forces need (`Edits`); `neighbour`, a
        second machine's MJCF, is attached after this one (its names prefixed). Raises
        ModelError if deleting the visual geoms changed a mass or an inertia: the model contract
        keeps masses in `<inertial>`.
        """
        edits = Edits(payloads=self.payloads, timestep=timestep, physics_only=True, rigid_body_only=rigid_body_only,
                      neighbour=neighbour)
        model = compile_model(self.path, edits)
        for field in ("body_mass", "body_inertia", "body_ipos"):
            own = getattr(model, field)[: self.model.nbody]  # a neighbour's bodies come after this machine's
            if not np.array_equal(own, getattr(self.model, field)):
                raise ModelError(
                    f"{self.path}: its visual geoms change '{field}': give every body an <inertial> "
                    "and the visual geoms no mass (model contract)"
                )
        return model

    @functools.cached_property
    def dynamics(self) -> ChainDynamics:
        """M(q) and bias(q, qd) of the machine's rigid bodies in closed form (payloads included),
        identified from MuJoCo and checked against it (bwr_twin.model.dynamics)."""
        dynamics = ChainDynamics.identify(self.physics_model(rigid_body_only=True))
        if dynamics is None:  # the contract's joint checks leave no such chain: a defect, said plainly
            raise ModelError(f"{self.path}: its mass matrix and bias forces do not have the closed form of a "
                             "travel-slew-luff chain (bwr_twin/model/dynamics.py)")
        return dynamics

    # -- contract ---------------------------------------------------------------------------

    def _check_joints(self) -> list[int]:
        m = self.model
        names = [mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(m.njnt)]
        if names != list(AXES) or m.nv != 3:
            raise ModelError(
                f"{self.path}: the model must have exactly the joints {list(AXES)} in that order, "
                f"found {names}"
            )
        expected_types = (mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_HINGE)
        for j, (axis, jtype) in enumerate(zip(AXES, expected_types)):
            if m.jnt_type[j] != jtype:
                raise ModelError(f"{self.path}: joint '{axis}' must be a {jtype.name[6:].lower()} joint")
        # Each joint must sit on a descendant of the previous joint's body (a serial PRR chain).
        for parent, child in ((0, 1), (1, 2)):
            body = m.jnt_bodyid[child]
            while body not in (0, m.jnt_bodyid[parent]):
                body = m.body_parentid[body]
            if body == 0:
                raise ModelError(f"{self.path}: joint '{AXES[child]}' does not move with joint '{AXES[parent]}'")
        return list(range(3))

    def _check_actuators(self) -> list[int]:
        m = self.model
        ids = []
        for j, axis in enumerate(AXES):
            a = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, axis)
            if a < 0:
                raise ModelError(f"{self.path}: no actuator named '{axis}' (one motor per joint, named after it)")
            is_motor = (
                m.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
                and m.actuator_trnid[a, 0] == j
                and m.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_NONE
                and m.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_FIXED
                and m.actuator_biastype[a] == mujoco.mjtBias.mjBIAS_NONE
            )
            if not is_motor:
                raise ModelError(f"{self.path}: actuator '{axis}' must be a motor on joint '{axis}'")
            ids.append(a)
        return ids

    def _derive_geometry(self) -> Geometry:
        m = self.model
        data = mujoco.MjData(m)
        mujoco.mj_kinematics(m, data)
        for j, axis in enumerate(AXES):
            if not np.allclose(data.xaxis[j], CONTRACT_AXES[axis], atol=_TOL):
                raise ModelError(
                    f"{self.path}: joint '{axis}' must turn about world {CONTRACT_AXES[axis]} at q = 0, "
                    f"found {np.round(data.xaxis[j], 6).tolist()}"
                )
        slew_axis = data.xanchor[1]
        pivot = data.xanchor[2]
        cp = data.site_xpos[self.cp_site]
        boom = cp - pivot
        if abs(pivot[1] - slew_axis[1]) > _TOL or abs(boom[1]) > _TOL:
            raise ModelError(
                f"{self.path}: the luff pivot and the CP must lie in the boom's vertical plane through "
                f"the slew axis at q = 0 (lateral offsets {pivot[1] - slew_axis[1]:.3g} m, {boom[1]:.3g} m)"
            )
        return Geometry(
            slew_axis_xy=(float(slew_axis[0]), float(slew_axis[1])),
            pivot_reach=float(pivot[0] - slew_axis[0]),
            pivot_height=float(pivot[2]),
            boom_length=float(np.hypot(boom[0], boom[2])),
            boom_angle0=float(np.arctan2(boom[2], boom[0])),
        )

    def _numeric(self, key: str) -> np.ndarray | None:
        """The values of `<custom><numeric name=key>`, or None if the file has none."""
        m = self.model
        n = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_NUMERIC, key)
        if n < 0:
            return None
        adr, size = m.numeric_adr[n], m.numeric_size[n]
        return m.numeric_data[adr : adr + size].copy()

    def _text(self, key: str) -> str | None:
        """The text of `<custom><text name=key>`, or None if the file has none."""
        m = self.model
        n = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_TEXT, key)
        if n < 0:
            return None
        adr, size = m.text_adr[n], m.text_size[n]
        return m.text_data[adr : adr + size].rstrip(b"\0").decode()

    def _read_envelope(self, joint_range: np.ndarray) -> np.ndarray:
        envelope = joint_range.copy()
        for j, axis in enumerate(AXES):
            key = ENVELOPE_KEY.format(axis=axis)
            values = self._numeric(key)
            if values is None:
                continue
            low, high = (values.tolist() + [np.nan, np.nan])[:2]
            if len(values) != 2 or not low < high:
                raise ModelError(f"{self.path}: custom numeric '{key}' must hold two values, low < high")
            envelope[j] = (low, high)
        return envelope

    def _read_wheel(self) -> Wheel | None:
        values = {key: self._numeric(key) for key in WHEEL_KEYS}
        missing = [key for key, value in values.items() if value is None]
        if len(missing) == len(WHEEL_KEYS):
            return None
        if missing:
            raise ModelError(f"{self.path}: the bucket wheel needs custom numeric '{missing[0]}' (model contract)")
        for key, value in values.items():
            if len(value) != 1 or not value[0] > 0:
                raise ModelError(f"{self.path}: custom numeric '{key}' must hold one value > 0")
        (diameter, width, buckets, volume, discharges) = (float(values[key][0]) for key in WHEEL_KEYS)
        if buckets != round(buckets):
            raise ModelError(f"{self.path}: custom numeric 'wheel_buckets' must be a whole number, got {buckets}")
        optional = {}
        for name, key in (("power", WHEEL_POWER_KEY), ("side_slope", WHEEL_SIDE_SLOPE_KEY),
                          ("bench_share", WHEEL_BENCH_SHARE_KEY), ("clearance", WHEEL_CLEARANCE_KEY)):
            value = self._numeric(key)
            if value is None:
                continue
            if len(value) != 1 or not value[0] > 0:
                raise ModelError(f"{self.path}: custom numeric '{key}' must hold one value > 0")
            optional[name] = float(value[0])
        return Wheel(diameter, width, int(buckets), volume, discharges, **optional)

    def _read_rated_speed(self) -> np.ndarray:
        speeds = np.full(3, np.inf)
        for j, axis in enumerate(AXES):
            key = RATED_SPEED_KEY.format(axis=axis)
            value = self._numeric(key)
            if value is None:
                continue
            if len(value) != 1 or not value[0] > 0:
                raise ModelError(f"{self.path}: custom numeric '{key}' must hold one value > 0")
            speeds[j] = value[0]
        return speeds

    def _cp_site(self) -> int:
        """The id of the one CP site the file has (CP_SITES)."""
        found = [site for name in CP_SITES if (site := mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, name)) >= 0]
        if len(found) != 1:
            raise ModelError(f"{self.path}: {'no site' if not found else 'two sites'} named '{CP_SITES[0]}' (a "
                             f"reclaimer's bucket wheel centre) or '{CP_SITES[1]}' (a stacker's boom tip): it needs "
                             "exactly one, at the CP")
        return found[0]

    def _drive_limits(self) -> np.ndarray:
        m = self.model
        limits = np.full((3, 2), np.inf)
        limits[:, 0] = -np.inf
        for j, a in enumerate(self.actuator_ids):
            gear = m.actuator_gear[a, 0]
            if m.actuator_ctrllimited[a]:
                limits[j] = np.sort(m.actuator_ctrlrange[a] * gear)
            if m.actuator_forcelimited[a]:
                limits[j, 0] = max(limits[j, 0], m.actuator_forcerange[a, 0])
                limits[j, 1] = min(limits[j, 1], m.actuator_forcerange[a, 1])
        return limits

    # -- kinematics ---------------------------------------------------------------------------

    def fk(self, q: np.ndarray) -> np.ndarray:
        """World position of the CP for joint values q of shape (..., 3) -> (..., 3), in m."""
        g = self.geometry
        q = np.asarray(q, dtype=float)
        out = np.empty(q.shape)
        _fk(q.reshape(-1, 3), g.slew_axis_xy[0], g.slew_axis_xy[1], g.pivot_reach, g.pivot_height, g.boom_length,
            g.boom_angle0, out.reshape(-1, 3))
        return out

    def ik(self, p: np.ndarray, *, label: str = "target", check_envelope: bool = True) -> np.ndarray:
        """Joint values (travel, slew, luff) that put the CP at world point p (m).

        The branch is the paper's: boom pointing away from the slew axis (|luff elevation| and
        |slew| at most 90 degrees). Raises UnreachableError when no configuration reaches p and,
        unless told otherwise, EnvelopeError when the answer leaves the operating envelope.
        """
        g = self.geometry
        x, y, z = (float(v) for v in p)
        where = f"{label} at world ({x:.3f}, {y:.3f}, {z:.3f}) m"
        height = (z - g.pivot_height) / g.boom_length
        if abs(height) > 1.0 + _TOL:
            raise UnreachableError(
                f"{where}: height Z = {z:.3f} m is beyond the boom's reach, "
                f"luff pivot at {g.pivot_height:.3f} m +- boom {g.boom_length:.3f} m"
            )
        elevation = np.arcsin(np.clip(height, -1.0, 1.0))
        reach = g.pivot_reach + g.boom_length * np.cos(elevation)
        lateral = (y - g.slew_axis_xy[1]) / reach
        if abs(lateral) > 1.0 + _TOL:
            raise UnreachableError(
                f"{where}: lateral offset {y - g.slew_axis_xy[1]:.3f} m from the rail axis exceeds "
                f"the horizontal reach {reach:.3f} m at that height"
            )
        slew = np.arcsin(np.clip(lateral, -1.0, 1.0))
        travel = x - g.slew_axis_xy[0] - reach * np.cos(slew)
        q = np.array([travel, slew, elevation - g.boom_angle0])
        if check_envelope:
            self.check_envelope(q, label=where)
        return q

    def check_envelope(self, q: np.ndarray, *, label: str = "configuration") -> None:
        """Raise EnvelopeError naming the axis, the limit and the value if q leaves the envelope."""
        for j, axis in enumerate(AXES):
            low, high = self.envelope[j]
            if not low - _TOL <= q[j] <= high + _TOL:
                raise EnvelopeError(
                    f"{label}: {axis} = {describe(j, q[j])} is outside the operating envelope "
                    f"[{describe(j, low)}, {describe(j, high)}] of {self.path.name}"
                )

    def __repr__(self) -> str:
        return f"Machine({str(self.path)!r})"


@functools.lru_cache(maxsize=8)
def _shared(path: Path, stamp: tuple, payloads: tuple) -> Machine:
    """Machine.shared's compile, once per file version (`stamp`) and payloads."""
    return Machine(path, payloads=payloads)


@numba.njit(cache=True)
def _fk(q, slew_x, slew_y, pivot_reach, pivot_height, boom_length, boom_angle0, out):  # pragma: no cover - compiled
    """The paper's Eq. (2) for the model's geometry, row by row: q (n, 3) -> CP (n, 3)."""
    for r in range(q.shape[0]):
        elevation = boom_angle0 + q[r, 2]
        reach = pivot_reach + boom_length * math.cos(elevation)
        out[r, 0] = q[r, 0] + slew_x + reach * math.cos(q[r, 1])
        out[r, 1] = slew_y + reach * math.sin(q[r, 1])
        out[r, 2] = pivot_height + boom_length * math.sin(elevation)
