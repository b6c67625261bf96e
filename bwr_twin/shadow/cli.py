"""The shadow: the twin beside the machine, over a recorded log at full speed or live over OPC UA.

    python -m bwr_twin.shadow --log RUN_DIR --model MJCF --baseline FAULT_FREE_RUN_DIR [...] --out DIR
    python -m bwr_twin.shadow --log RUN_DIR --model MJCF --thresholds thresholds.json --out DIR
    python -m bwr_twin.shadow --source opc.tcp://HOST:PORT --tags tags.toml --model MJCF --thresholds FILE
    ... --serve opc.tcp://127.0.0.1:4841     # and serve the residuals, health and alarms over OPC UA
    ... --view 8080                           # and show them in the browser, http://127.0.0.1:8080

RUN_DIR is a run directory (or its timeseries.csv) of the machine being watched: its encoders'
positions, its drives' speed feedback and their forces (docs/shadow.md). The thresholds are
learned from a fault-free log of the same machine (--baseline), for --false-alarms-per-hour
(default 0.01), or read from a thresholds.json an earlier shadow wrote. DIR holds events.jsonl
(the alarms: class, axis, size, onset; and the gaps), residuals.csv (per block of 1 s the force,
position, speed and drift residuals per axis) and thresholds.json. DIR appears only when
complete. Live (--source), the shadow subscribes to the tags a tag map names (docs/shadow.md),
or reads them every --poll s, and prints its events as JSON lines as they happen (the source
lost and back, gaps, alarms), until Ctrl-C or --duration s. With --serve URL the shadow is an OPC UA server too
(bwr_twin.shadow.publish, docs/shadow.md), and with --view PORT a page in the browser
(bwr_twin.shadow.view): live, each block's residuals, the health and the alarms as they come;
over a log, what the shadow made of it, served until Ctrl-C or --duration s. Bad input exits
with status 2 and one line.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import math
import time
from pathlib import Path

from bwr_twin.arguments import CommandParser
from bwr_twin.errors import BwrError, exit_status, leave

DEFAULT_PER_HOUR = 0.01  # false alarms an hour the thresholds are set for: one in 100 h of watching


def main(argv: list[str] | None = None) -> int:
    parser = CommandParser(prog="python -m bwr_twin.shadow", description=__doc__.split("\n\n")[0])
    watched = parser.add_mutually_exclusive_group(required=True)
    watched.add_argument("--log", type=Path, help="run directory (or timeseries.csv) to watch")
    watched.add_argument("--source", help="the machine's OPC UA server, opc.tcp://HOST:PORT, to watch live")
    parser.add_argument("--tags", type=Path, help="live: the tag map (tags.toml)")
    parser.add_argument("--poll", type=float, help="live: read every tag every POLL s instead of subscribing "
                        "(for a PLC whose server stamps one cycle's values apart)")
    parser.add_argument("--duration", type=float, help="live, or a log with --serve: stop after this many s "
                        "(default: until Ctrl-C)")
    parser.add_argument("--serve", metavar="URL", help="serve the residuals, health and alarms over OPC UA at "
                        "opc.tcp://HOST:PORT")
    parser.add_argument("--view", metavar="PORT", type=int, help="show the machine, its twin's ghost, the residuals "
                        "and the alarms at http://127.0.0.1:PORT (0: a free port)")
    parser.add_argument("--model", required=True, type=Path, help="the machine's MJCF the twin runs")
    learned = parser.add_mutually_exclusive_group(required=True)
    learned.add_argument("--baseline", type=Path, nargs="+", help="fault-free run directories (or timeseries.csv) "
                         "of the machine, the more of its usual work the better: learn the "
                         "thresholds from them")
    learned.add_argument("--thresholds", type=Path, help="thresholds.json an earlier shadow wrote")
    parser.add_argument("--false-alarms-per-hour", type=float, default=DEFAULT_PER_HOUR,
                        help=f"the false-alarm rate the thresholds are set for (1/h, default {DEFAULT_PER_HOUR})")
    parser.add_argument("--out", type=Path, help="output directory (must not exist); a log's shadow needs it")
    parser.add_argument("--overwrite", action="store_true", help="replace DIR, a shadow's output, once the new "
                        "one is complete")
    args = parser.parse_args(argv)
    return exit_status(lambda: _run(args))


def _run(args: argparse.Namespace) -> int:
    if args.source is not None:
        return _live(args)
    if args.out is None:
        raise BwrError("--out is needed to watch a --log: the folder its events and residuals go to")
    if args.tags is not None:
        raise BwrError("--tags is for a live --source, not a --log")
    if args.duration is not None and args.serve is None and args.view is None:
        raise BwrError("--duration is for a live --source, or a --log with --serve or --view")
    _check_serving(args)
    from bwr_twin.ownership import check_output
    from bwr_twin.results.rundir import staged_directory
    from bwr_twin.shadow.detect import Thresholds
    from bwr_twin.shadow.twin import ShadowTwin
    from bwr_twin.shadow.watch import learn_from, watch, write_outputs

    inputs = [p for p in (args.log, args.model, *(args.baseline or ()), args.thresholds) if p is not None]
    check_output(args.out, "shadow", overwrite=args.overwrite, inputs=inputs)
    if not args.model.is_file():
        raise BwrError(f"{args.model}: MJCF file not found")
    for path in (args.log, *(args.baseline or ())):
        if path is not None and not (path / "timeseries.csv" if path.is_dir() else path).is_file():
            raise BwrError(f"{path}: no log there: give a run directory or its timeseries.csv")
    known = Thresholds.read(args.thresholds) if args.thresholds is not None else None  # refused before the twin is built
    twin = ShadowTwin(args.model)
    thresholds = known if known is not None else learn_from(twin, args.baseline, args.false_alarms_per_hour)
    started = time.perf_counter()
    watched = watch(twin, args.log, thresholds)
    took = time.perf_counter() - started
    with staged_directory(args.out, overwrite=args.overwrite, kind="shadow") as staging:
        write_outputs(staging, watched, thresholds)
    span = float(watched.measured.time[-1] - watched.measured.time[0])
    print(f"{args.log}: {span:g} s of log watched in {took:.1f} s ({span / max(took, 1e-9):.0f}x real time), "
          f"{len(watched.blocks.start)} blocks, {len(watched.gaps)} gaps, {len(watched.alarms)} alarms")
    for start, end in watched.gaps:
        print(f"gap: no samples from {start:.2f} s to {end:.2f} s (nothing concluded over it)")
    for alarm in watched.alarms:
        print(f"alarm: {alarm.describe()}")
    print(f"events in {args.out}/events.jsonl")
    if args.serve is not None or args.view is not None:
        asyncio.run(_show_log(args, twin, thresholds, watched))
    return 0


def _check_serving(args: argparse.Namespace) -> None:
    if args.serve is not None and not args.serve.startswith("opc.tcp://"):
        raise BwrError(f"--serve must be an opc.tcp://HOST:PORT address, got {args.serve!r}")
    if args.duration is not None and not args.duration > 0:
        raise BwrError("--duration must be > 0 s")
    if args.view is not None and not 0 <= args.view <= 65535:
        raise BwrError(f"--view must be a TCP port, 0 to 65535, got {args.view}")


@contextlib.asynccontextmanager
async def _outputs(args: argparse.Namespace, twin, thresholds):
    """The OPC UA server (--serve) and the view (--view) the shadow publishes to, started; each
    said where it is; stopped on leaving."""
    from bwr_twin.shadow.publish import ShadowServer, residual_ranges
    from bwr_twin.shadow.view import ShadowView

    outputs = []
    try:
        if args.serve is not None:
            server = ShadowServer(args.serve, residual_ranges(twin.limits, twin.machine.rated_speed, thresholds))
            await server.start()
            outputs.append(server)
            print(f"serving the shadow at {args.serve}", flush=True)
        if args.view is not None:
            view = ShadowView(twin.machine, port=args.view)
            outputs.append(view)
            print(f"view: {view.url}", flush=True)
        yield outputs
    finally:
        for output in outputs:
            await output.stop()


async def _show_log(args: argparse.Namespace, twin, thresholds, watched) -> None:
    """Publish what the shadow made of a log (every block's residuals, the pose at its end, the
    health, the alarms) until --duration s have passed or Ctrl-C."""
    async with _outputs(args, twin, thresholds) as outputs:
        end = watched.measured.time.searchsorted(watched.blocks.end[-1]) if len(watched.blocks.start) else -1
        for output in outputs:
            await output.residuals(watched.blocks, watched.measured.q[end])
            await output.verdict(watched.health, watched.alarms)
        print("shown" + (f" for {args.duration:g} s" if args.duration else ": Ctrl-C stops"), flush=True)
        await asyncio.sleep(args.duration if args.duration is not None else math.inf)


def _live(args: argparse.Namespace) -> int:
    import json

    from bwr_twin.shadow.detect import Thresholds
    from bwr_twin.shadow.live import LiveShadow, Source, run_live
    from bwr_twin.shadow.tags import read_tags
    from bwr_twin.shadow.twin import ShadowTwin
    from bwr_twin.shadow.watch import learn_from

    if args.out is not None:
        raise BwrError("--out is for a --log; live, the events are printed as JSON lines")
    if args.tags is None:
        raise BwrError("--source needs --tags: the tag map naming the machine's variables (docs/shadow.md)")
    if not args.source.startswith("opc.tcp://"):
        raise BwrError(f"--source must be an opc.tcp://HOST:PORT address, got {args.source!r}")
    if args.poll is not None and not args.poll > 0:
        raise BwrError(f"--poll must be > 0 s, got {args.poll:g}")
    _check_serving(args)
    if not args.model.is_file():
        raise BwrError(f"{args.model}: MJCF file not found")
    twin = ShadowTwin(args.model)
    tags = read_tags(args.tags, twin.model_name)
    thresholds = (Thresholds.read(args.thresholds) if args.thresholds is not None
                  else learn_from(twin, args.baseline, args.false_alarms_per_hour))

    def say(event: dict) -> None:
        print(json.dumps(event), flush=True)

    shadow = LiveShadow(twin, thresholds, say, tags.wind.air if tags.wind is not None else None)

    async def live() -> None:
        async with _outputs(args, twin, thresholds) as outputs:
            await run_live(Source(args.source, tags, args.poll), shadow, say, duration=args.duration,
                           outputs=outputs)

    asyncio.run(live())
    return 0


if __name__ == "__main__":
    leave(main())
