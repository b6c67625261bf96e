"""What the replay shows: a `Plan` (known before simulating) and a `Recording` (after).

A plan is the machine, the desired path sampled at the record period and the via points in
world coordinates; it comes from a scene in milliseconds, so the page can show the machine while
the simulation runs. A recording adds the actual joint values and CP positions, read from a run
directory (`bwr_twin.run`) or taken from an in-memory `RunResult`. A scene's run is cached as a
run directory keyed by everything that decides its outcome.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from bwr_twin.config.scene import Scene
from bwr_twin.errors import BwrError
from bwr_twin.model.machine import Machine
from bwr_twin.pile.surface import Surface, build_surface
from bwr_twin.planning.follower import Stage
from bwr_twin.replay.scans import Scans
from bwr_twin.results.run_files import (
    GradeSeries,
    RunScene,
    TimeSeries,
    read_scene,
    read_timeseries,
    timeseries_of,
)
from bwr_twin.shipped import PACKAGE
from bwr_twin.stockpile.history import PileHistory
from bwr_twin.stockpile.layers import top_grade

if TYPE_CHECKING:
    from bwr_twin.sim.record import RunResult

# The sub-packages whose code decides a run (the replay's own code does not).
_SIMULATION_CODE = tuple(PACKAGE / name for name in ("config", "model", "planning", "control", "sim", "stockpile",
                                                      "sensing", "results"))


@dataclass(frozen=True)
class Plan:
    """The machine and its desired path. Arrays are per sample (n,) or (n, 3), per axis in the
    order travel, slew, luff, in SI units (m, rad, s); positions in world coordinates."""

    machine: Machine
    title: str
    time: np.ndarray
    q_desired: np.ndarray
    qd_desired: np.ndarray
    cp_desired: np.ndarray
    via_times: np.ndarray  # (k,) s
    via_points: np.ndarray  # (k, 3) m
    pile: Surface | None = None  # the stockpile at the start, if the scene has one
    via_stages: tuple[Stage, ...] = ()  # a bench plan's, typed (bwr_twin.planning.follower); () on a path
    neighbour: Machine | None = None  # a second machine on the rail, if the scene has one
    neighbour_q_desired: np.ndarray | None = None  # (n, 3) its schedule
    activity: str = "reclaim"  # what the machine does, for labels: "reclaim" or "stacking"

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def names(self) -> list[str]:
        """Each via point's name; "" for one the replay marks but does not name."""
        return [s.name for s in self.via_stages] or [f"P{i + 1}" for i in range(len(self.via_times))]

    def stage(self, t: float) -> str | None:
        """A bench plan's stage at time t, "bench 1, pass 3", from the stages begun before it;
        None on a path."""
        if not self.via_stages:
            return None
        bench, step = "", ""
        for stage, start in zip(self.via_stages, self.via_times):
            if start > t:
                break
            if stage.kind == "bench":
                bench, step = stage.name, "moving onto it"
            elif stage.kind == "pass":
                step = stage.name
            elif stage.kind == "end":
                step = "done"
            elif step.startswith("pass"):  # a move after a pass
                step = "travel step"
        return ", ".join(part for part in (bench, step) if part) or None

    @property
    def landmarks(self) -> list[tuple[str, float]]:
        """(name, time) of the via points to jump to: every one of a path, each bench of a plan."""
        if not self.via_stages:
            return list(zip(self.names, self.via_times.tolist()))
        return [(s.name, float(t)) for s, t in zip(self.via_stages, self.via_times) if s.kind == "bench"]

    @classmethod
    def from_scene(cls, scene: Scene) -> Plan:
        """Plan the scene's path (inverse kinematics and cubics only, no simulation), its bench
        reclaim as the plan's speed law alone would run it, or its stacking pattern."""
        from bwr_twin.planning.trajectory import Trajectory

        machine = Machine(scene.machine.mjcf)
        period = scene.simulation.record_period
        if scene.reclaim is not None:
            from bwr_twin.planning.bench import plan_scene
            from bwr_twin.planning.follower import nominal

            control = scene.simulation.control_period
            time, q_desired, qd_desired, trajectory, stages = nominal(
                plan_scene(scene), control, machine.fk, every=max(round(period / control), 1),
                stop_time=scene.reclaim.stop.time)
        elif scene.stacking is not None:
            from bwr_twin.planning.stacking import plan_stacking

            pattern = plan_stacking(scene, machine, period)
            time, (q_desired, qd_desired, _) = pattern.time, pattern.rows
            trajectory, stages = pattern.waypoints, list(pattern.stages)
        else:
            stages = []
            try:
                trajectory = Trajectory.plan(scene.trajectory, machine)
            except BwrError as exc:
                raise type(exc)(f"{scene.path}: {exc}") from None
            time = trajectory.times[0] + np.arange(round(trajectory.duration / period) + 1) * period
            q_desired, qd_desired, _ = trajectory.sample(time)
        pile = build_surface(scene.stockpile, scene.path) if scene.stockpile is not None else None
        neighbour = neighbour_q = None
        if scene.neighbour is not None:
            from bwr_twin.sim.neighbour import neighbour_schedule

            neighbour = Machine(scene.neighbour.mjcf)
            neighbour_q = neighbour_schedule(scene, neighbour).sample(time)[0]
        return cls(
            machine=machine,
            title=scene.path.name,
            time=time,
            q_desired=q_desired,
            qd_desired=qd_desired,
            cp_desired=machine.fk(q_desired),
            via_times=trajectory.times,
            via_points=trajectory.points,
            pile=pile,
            via_stages=tuple(stages),
            neighbour=neighbour,
            neighbour_q_desired=neighbour_q,
            activity="stacking" if scene.stacking is not None else "reclaim",
        )


@dataclass(frozen=True)
class Instant:
    """The state at one time, interpolated between records. SI units, world coordinates."""

    time: float  # s
    q_desired: np.ndarray  # (3,) m, rad, rad
    q_actual: np.ndarray
    cp_desired: np.ndarray  # (3,) m
    cp_actual: np.ndarray
    reclaim_rate: float | None = None  # t/h, with a stockpile
    stage: str | None = None  # where a bench plan stands: "pass 3"; None on a path
    neighbour_q: np.ndarray | None = None  # (3,) a second machine's joints, if the scene has one

    @property
    def q_error(self) -> np.ndarray:
        """Desired minus actual (the sign of the metrics, docs/contracts.md)."""
        return self.q_desired - self.q_actual


@dataclass(frozen=True)
class Recording:
    """A finished run: its plan plus what the machine actually did."""

    plan: Plan
    q_actual: np.ndarray  # (n, 3) m, rad, rad
    qd_actual: np.ndarray  # (n, 3) m/s, rad/s, rad/s
    cp_actual: np.ndarray  # (n, 3) m
    reclaim_rate: np.ndarray | None = None  # (n,) t/h, with a stockpile
    pile: PileHistory | None = None  # the pile as it was dug, with a stockpile
    controller: str = ""  # the controller's type, as its scene names it: "fuzzy_model", "pid", ...
    scans: Scans | None = None  # the run's laser scans, if its machine scanned the pile
    neighbour_q: np.ndarray | None = None  # (n, 3) a second machine's joints, if the scene has one
    grade: GradeSeries | None = None  # the grade stacked or reclaimed, for a run of a pile with grade

    @property
    def q_error(self) -> np.ndarray:
        """Desired minus actual, (n, 3) in m, rad, rad (the sign of the metrics, docs/contracts.md)."""
        return self.plan.q_desired - self.q_actual

    @property
    def qd_error(self) -> np.ndarray:
        """Desired minus actual velocity, (n, 3) in m/s, rad/s, rad/s."""
        return self.plan.qd_desired - self.qd_actual

    def at(self, t: float) -> Instant:
        """The state at time t (s), linear between records, held at the ends."""
        time = self.plan.time
        k = int(np.clip(np.searchsorted(time, t, side="right") - 1, 0, len(time) - 2))
        s = float(np.clip((t - time[k]) / (time[k + 1] - time[k]), 0.0, 1.0))

        def blend(series: np.ndarray) -> np.ndarray:
            return (1.0 - s) * series[k] + s * series[k + 1]

        return Instant(
            time=float(np.clip(t, time[0], time[-1])),
            q_desired=blend(self.plan.q_desired),
            q_actual=blend(self.q_actual),
            cp_desired=blend(self.plan.cp_desired),
            cp_actual=blend(self.cp_actual),
            reclaim_rate=float(self.reclaim_rate[k + round(s)]) if self.reclaim_rate is not None else None,
            stage=self.plan.stage(t),
            neighbour_q=None if self.neighbour_q is None else blend(self.neighbour_q),
        )

    @classmethod
    def from_run_dir(cls, run_dir: str | Path) -> Recording:
        """Read a run directory written by `python -m bwr_twin.run` (or `results.write_run`)."""
        from bwr_twin.results.rundir import METRICS_FILE, PILE_FILE, SCENE_FILE, TIMESERIES_FILE

        run_dir = Path(run_dir)
        missing = [f for f in (TIMESERIES_FILE, SCENE_FILE) if not (run_dir / f).is_file()]
        if missing:
            raise BwrError(f"{run_dir}: not a run directory of bwr_twin.run (no {', '.join(missing)})")
        scene = read_scene(run_dir / SCENE_FILE)
        machine = Machine(scene.mjcf)
        neighbour = Machine(scene.neighbour_mjcf) if scene.neighbour_mjcf is not None else None
        series = read_timeseries(run_dir / TIMESERIES_FILE, envelope=machine.envelope,
                                 neighbour_envelope=neighbour.envelope if neighbour is not None else None)
        if len(series.time) < 2:
            raise BwrError(f"{run_dir / TIMESERIES_FILE}: {len(series.time)} rows of samples; a replay needs at least 2")
        pile_file = run_dir / PILE_FILE
        pile = PileHistory.read(pile_file, float(series.time[-1])) if pile_file.is_file() else None
        scans = Scans.read(run_dir, *((pile.x, pile.y) if pile is not None else ()))
        run = {}
        try:
            if scene.via_times is None:  # a bench reclaim's waypoints are the run's own
                run = json.loads((run_dir / METRICS_FILE).read_text())["run"]
            return cls._from_series(series, scene, machine, pile=pile, run=run, scans=scans, neighbour=neighbour)
        except (ValueError, OSError) as exc:
            raise BwrError(f"{run_dir}: unreadable run directory: {exc}") from None
        except KeyError as exc:
            raise BwrError(f"{run_dir / METRICS_FILE}: incomplete: no {exc} in its run block") from None
        except (TypeError, AttributeError, IndexError):  # JSON of another shape than a run block's
            raise BwrError(f"{run_dir / METRICS_FILE}: its run block is not the one bwr_twin.run writes (the "
                           "plan's waypoint_times, waypoints and waypoint_stages)") from None

    @classmethod
    def from_result(cls, result: RunResult) -> Recording:
        """A `RunResult` as its run directory would hold it."""
        from bwr_twin.results.rundir import timeseries_columns

        reclaim, stacking, pile = result.reclaim, result.stacking, None
        if reclaim is not None:
            pile = reclaim.history or PileHistory.start_and_end(
                reclaim.x, reclaim.y, reclaim.z_start, reclaim.z_end, float(result.time[-1]))
        elif stacking is not None:  # the pile it stacked, grown from the bare yard
            pile = stacking.history or PileHistory.start_and_end(
                stacking.x, stacking.y, np.zeros_like(stacking.z), stacking.z, float(result.time[-1]),
                top_grade(stacking.layer_grade, stacking.count), stacking.grade_name, stacking.band)
        what = str(result.scene.path)
        neighbour = Machine(result.scene.neighbour.mjcf) if result.scene.neighbour is not None else None
        return cls._from_series(timeseries_of(*timeseries_columns(result), what),
                                RunScene.of(result.scene.to_dict(), what), result.machine, pile=pile,
                                run=result.metrics["run"], scans=Scans.of(getattr(result, "scan", None)),
                                neighbour=neighbour)

    @classmethod
    def _from_series(
        cls, series: TimeSeries, scene: RunScene, machine: Machine, *, pile: PileHistory | None = None,
        run: dict, scans: Scans | None = None, neighbour: Machine | None = None,
    ) -> Recording:
        """`run`: metrics.json's run block (a bench reclaim's waypoints); `scans`: the run's, posed
        here on its machine at its joint values; `neighbour`: the second machine on the rail."""
        stages: tuple[Stage, ...] = ()
        if scene.via_times is None:  # a bench reclaim: where the run began each segment of its plan, and which
            via_times = np.array(run["waypoint_times"], dtype=float)
            via_points = np.array(run["waypoints"], dtype=float).reshape(-1, 3)
            stages = tuple(Stage(**stage) for stage in run["waypoint_stages"])
        else:
            via_times, via_points = scene.via_times, scene.via_points
        signals = series.signals
        plan = Plan(
            machine=machine,
            title=scene.title,
            time=series.time,
            q_desired=signals["q_desired"],
            qd_desired=signals["qd_desired"],
            cp_desired=series.cp_desired,
            via_times=via_times,
            via_points=via_points,
            pile=Surface(pile.x, pile.y, pile.z_start) if pile is not None else None,
            via_stages=stages,
            activity=scene.activity,
        )
        q_actual = signals["q"]
        if neighbour is not None:
            plan = dataclasses.replace(plan, neighbour=neighbour, neighbour_q_desired=series.neighbour["q_desired"])
        if scans is not None:
            scans.attach(machine, plan.time, q_actual)
        return cls(plan, q_actual, signals["qd"], series.cp_actual,
                   reclaim_rate=series.reclaim["rate"] if series.reclaim is not None else None, pile=pile,
                   controller=scene.controller, scans=scans,
                   neighbour_q=series.neighbour["q"] if neighbour is not None else None,
                   grade=series.grade)


def path_difference(ghost: Plan, plan: Plan) -> str:
    """What differs between the via points of two plans, or "" if they follow the same path."""
    if len(ghost.via_times) != len(plan.via_times):
        return f"{len(ghost.via_times)} via points over {ghost.duration:g} s against {len(plan.via_times)} over " \
               f"{plan.duration:g} s"
    names = plan.names
    for i, (t_ghost, t_plan) in enumerate(zip(ghost.via_times, plan.via_times)):
        if t_ghost != t_plan:
            return f"via point {names[i] or i + 1} at t = {t_ghost:g} s against {t_plan:g} s"
        p_ghost, p_plan = ghost.via_points[i], plan.via_points[i]
        if not np.allclose(p_ghost, p_plan, atol=1e-9):
            return (f"via point {names[i] or i + 1} (t = {t_plan:g} s) at ({', '.join(f'{v:.6g}' for v in p_ghost)}) m "
                    f"against ({', '.join(f'{v:.6g}' for v in p_plan)}) m, in world coordinates")
    return ""


def decimate(time: np.ndarray, step: float) -> np.ndarray:
    """Indices of samples about `step` seconds apart, always including the last."""
    every = max(1, round(step / float(np.median(np.diff(time))))) if len(time) > 1 else 1
    indices = np.arange(0, len(time), every)
    return indices if indices[-1] == len(time) - 1 else np.append(indices, len(time) - 1)


def cache_key(scene: Scene) -> str:
    """A digest of everything that decides a run: the resolved scene, both compiled models
    (includes and meshes too), the controller's files (a rule base, an engineer's Python file),
    a surveyed pile's file and the package's simulation code."""
    digest = hashlib.sha256()
    settings = scene.to_dict()
    settings.pop("path")  # where the scene file lives does not change the run
    digest.update(json.dumps(settings, sort_keys=True).encode())
    for mjcf in (scene.machine.mjcf, scene.controller_mjcf):
        model = mujoco.MjModel.from_xml_path(str(mjcf))
        compiled = np.zeros(mujoco.mj_sizeModel(model), dtype=np.uint8)
        mujoco.mj_saveModel(model, None, compiled)
        digest.update(compiled.tobytes())
    survey = (scene.stockpile.surface_file,) if scene.stockpile and scene.stockpile.surface_file else ()
    for file in (*scene.controller.files, *survey):
        digest.update(file.read_bytes())
    for source in sorted(path for folder in _SIMULATION_CODE for path in folder.rglob("*.py")):
        digest.update(source.read_bytes())
    return digest.hexdigest()[:16]
