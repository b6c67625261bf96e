"""Tune any scene keys with CMA-ES (one key: a bounded scalar search), on local workers or a Dask
cluster, resumably.

    python -m bwr_twin.tune tuning/paper_gains --out out/tune
    python -m bwr_twin.tune TUNE.toml --out DIR [--workers N | --scheduler tcp://HOST:PORT] [--force]

TUNE is a tuning file (bwr_twin.config.tuning), or the name of a shipped one (scenes/).
Before anything runs, the whole budget is estimated (evaluations x training seeds, and the
held-out runs, at the base scene's cost) and refused beyond the bounds of bwr_twin.sim.budget
unless --force. The start point (the base scene) is evaluated first: it sets each metric's normaliser. Then
every generation's candidates run on the same training seeds as lockstep batches. After each
generation DIR/tuner_state.pkl and DIR/history.csv are saved; the same command continues a
tuning that was interrupted or killed from its last completed generation, and ends where an
uninterrupted one would have (a wall-time budget aside). At the end DIR holds best_scene.toml,
history.csv, convergence.png and held_out.csv/.md: start against tuned on the held-out seeds.
Exit status: 0 done, 2 bad input (nothing run), 130 interrupted (run the same command to resume).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, leave
from bwr_twin.model.machine import AXES
from bwr_twin.sim.budget import FORCE_HELP


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.tune", description=__doc__.split("\n\n")[0])
    parser.add_argument("tuning", help="tuning TOML file, or a shipped one's name, e.g. tuning/paper_gains")
    parser.add_argument("--out", required=True, type=Path, help="output directory; re-running resumes it")
    engine = parser.add_mutually_exclusive_group()
    engine.add_argument("--workers", type=int, help="local worker processes (default: one per core)")
    engine.add_argument("--scheduler", help="run on a Dask cluster, e.g. tcp://10.0.0.5:8786")
    parser.add_argument("--force", action="store_true", help=FORCE_HELP)
    args = parser.parse_args(argv)
    if args.workers is not None and args.workers < 1:
        parser.error("--workers must be at least 1")
    signal.signal(signal.SIGTERM, _interrupt)

    from bwr_twin.config.tuning import load_tuning
    from bwr_twin.ownership import check_output, mark, marker
    from bwr_twin.shipped import find_scene
    from bwr_twin.sim.budget import check_estimate
    from bwr_twin.tune.cost import budget_estimate

    created = not args.out.exists()
    try:
        tuning = load_tuning(find_scene(args.tuning))
        check_output(args.out, "tuning", inputs={tuning.path, *tuning.base.input_files})
        workers = 1 if args.scheduler else args.workers or os.cpu_count() or 1
        check_estimate(budget_estimate(tuning, workers, force=args.force), where=f"{tuning.path}: 'budget.evaluations' ({tuning.evaluations}) x "
                       f"{len(tuning.training_seeds)} training seeds",
                       out_dir=args.out, force=args.force)
        found = marker(args.out) if args.out.exists() else None
        if found is not None and found.get("tuning") != tuning.digest:
            raise BwrError(f"{args.out}: holds a tuning by another tuning file ({found.get('file')}) or an "
                           f"earlier version of {tuning.path.name}; choose another --out")
        args.out.mkdir(parents=True, exist_ok=True)
        if found is None:
            mark(args.out, "tuning", file=tuning.path.name, tuning=tuning.digest)
        return _tune(tuning, args.out, workers=args.workers, scheduler=args.scheduler)
    except BwrError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: the completed generations are kept; run the same command to resume",
              file=sys.stderr)
        return 130
    finally:
        if created and args.out.is_dir() and {p.name for p in args.out.iterdir()} <= {".bwr_twin"}:
            for path in args.out.iterdir():  # a tuning that never started leaves nothing behind
                path.unlink()
            args.out.rmdir()


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt  # `kill` stops a tuning as cleanly as Ctrl-C


def _tune(tuning, out: Path, *, workers: int | None, scheduler: str | None) -> int:
    from tqdm import tqdm

    from bwr_twin.batch.cli import remove_debris
    from bwr_twin.batch.engines import DaskCluster, LocalPool
    from bwr_twin.ownership import check_resumed
    from bwr_twin.tune.objective import axis_means, score
    from bwr_twin.tune.outputs import write_convergence, write_history
    from bwr_twin.tune.state import TunerState

    started = time.perf_counter()
    remove_debris(out)  # what a killed tuning's workers left
    state = TunerState.load(out)  # a damaged state is named as such first
    check_resumed(out)  # then anything else not as the twin wrote it
    engine = DaskCluster(scheduler) if scheduler else LocalPool(workers or os.cpu_count() or 1, out)
    with engine:
        if state is None:  # the start point alone sets the normalisers
            metrics = _evaluate(engine, tuning, [tuning.start], tuning.training_seeds)[0]
            if any(m is None for m in metrics):
                raise BwrError(f"{tuning.path}: the base scene's runs fail on the training seeds; nothing to tune")
            state = TunerState(_strategy(tuning), axis_means(tuning, metrics))
            start = score(tuning, metrics, state.normalisers)
            state.history.append(_row(tuning, 0, 0, tuning.start, start))
            if start.feasible:
                state.best = {"values": list(tuning.start), "objective": start.value, "generation": 0,
                              "candidate": 0}
            state.evaluations = 1
            state.save(out)
        population = state.strategy.popsize
        with tqdm(total=tuning.evaluations, initial=state.evaluations, unit="eval", file=sys.stderr,
                  disable=not sys.stderr.isatty()) as bar:
            while not state.finished:
                state.finished = _stop_reason(tuning, state, population, time.perf_counter() - started)
                if state.finished:
                    break
                unit = state.strategy.ask()
                values = [[p.from_unit(u) for p, u in zip(tuning.parameters, x)] for x in unit]
                results = _evaluate(engine, tuning, values, tuning.training_seeds)
                scores = [score(tuning, metrics, state.normalisers) for metrics in results]
                state.strategy.tell(unit, [s.value for s in scores])
                state.generation += 1
                for c, (v, s) in enumerate(zip(values, scores), start=1):
                    state.history.append(_row(tuning, state.generation, c, v, s))
                    if s.feasible and (state.best is None or s.value < state.best["objective"]):
                        state.best = {"values": v, "objective": s.value, "generation": state.generation,
                                      "candidate": c}
                state.evaluations += len(values)
                state.elapsed += time.perf_counter() - started
                started = time.perf_counter()
                state.save(out)
                write_history(out, state.history)
                bar.update(len(values))
                best = "none feasible yet" if state.best is None else f"{state.best['objective']:.4g}"
                bar.set_postfix_str(f"generation {state.generation}, best {best}")
            state.save(out)
        write_history(out, state.history)
        write_convergence(out, tuning, state.history)
        table = _finish(engine, tuning, state, out)
    print(table, end="")
    print(f"{tuning.path.name}: {state.evaluations} evaluations in {state.generation} generations "
          f"({state.finished}); best objective {state.best['objective']:.4g} (start "
          f"{state.history[0]['objective']:.4g}); results in {out}/")
    return 0


def _strategy(tuning):
    """CMA-ES over the parameters mapped to [0, 1]; for one parameter, which CMA-ES cannot search
    (it needs two dimensions), a bounded scalar search in the same ask-and-tell shape."""
    x0 = [p.to_unit(v) for p, v in zip(tuning.parameters, tuning.start)]
    if len(x0) == 1:
        from bwr_twin.tune.scalar import DEFAULT_POPULATION, ScalarSearch

        return ScalarSearch(x0[0], tuning.population or DEFAULT_POPULATION)
    import cma

    options = {"bounds": [0.0, 1.0], "seed": tuning.seed, "verbose": -9, "verb_log": 0, "verb_disp": 0}
    if tuning.population:
        options["popsize"] = tuning.population
    return cma.CMAEvolutionStrategy(x0, tuning.sigma0, options)


def _stop_reason(tuning, state, population: int, running: float) -> str:
    from bwr_twin.tune.scalar import search_name

    if state.evaluations + population > tuning.evaluations:
        return f"budget of {tuning.evaluations} evaluations"
    if tuning.wall_time is not None and state.elapsed + running >= tuning.wall_time:
        return f"wall-time budget of {tuning.wall_time:g} s"
    stop = state.strategy.stop()
    return f"{search_name(len(tuning.parameters))} converged ({', '.join(stop)})" if stop else ""


def _evaluate(engine, tuning, candidates: Sequence[Sequence[float]], seeds: Sequence[int]) -> list[list[dict | None]]:
    """Each candidate's metrics.json on each seed (None for a failed run), as lockstep batches."""
    from bwr_twin.batch.cli import plan_locksteps
    from bwr_twin.config.sweep import PlannedRun

    runs = [PlannedRun(f"{c}:{seed}", {}, {}, tuning.scene(values, seed))
            for c, values in enumerate(candidates) for seed in seeds]
    metrics: dict[str, dict | None] = {}
    for _, outcomes in engine.outcomes(plan_locksteps(runs, workers=engine.workers, chunk=None),
                                       plots=False, files=False):
        for outcome in outcomes:
            if outcome.status == "not run":
                raise BwrError(f"a worker was lost: {outcome.error}")
            metrics[outcome.run_id] = outcome.metrics
    return [[metrics[f"{c}:{seed}"] for seed in seeds] for c in range(len(candidates))]


def _row(tuning, generation: int, candidate: int, values: Sequence[float], result) -> dict:
    row = {"generation": generation, "candidate": candidate}
    row.update({p.key: float(v) for p, v in zip(tuning.parameters, values)})
    row.update({"objective": result.value, "feasible": result.feasible, "infeasible_because": result.why})
    for metric, means in result.means.items():
        row.update({f"{metric}.{axis}": value for axis, value in zip(AXES, means)})
    return row


def _finish(engine, tuning, state, out: Path) -> str:
    """best_scene.toml and the held-out comparison of the start and the best."""
    from bwr_twin.tune.outputs import held_out_rows, write_best_scene, write_held_out

    best = state.best
    if best is None:
        raise BwrError(f"{tuning.path}: no candidate met the constraints in {state.evaluations} evaluations "
                       "(see history.csv, column infeasible_because); loosen [constraints] or the bounds")
    write_best_scene(out, tuning, best["values"], best["objective"], state.evaluations, state.finished)
    start, tuned = _evaluate(engine, tuning, [tuning.start, best["values"]], tuning.held_out_seeds)
    if any(m is None for m in start + tuned):
        raise BwrError(f"{tuning.path}: a held-out run diverged; see history.csv and best_scene.toml")
    return write_held_out(out, held_out_rows(start, tuned), tuning.held_out_seeds)


if __name__ == "__main__":
    leave(main())
