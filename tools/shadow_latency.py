"""How soon the live shadow publishes a block's residuals after the sample that completed it
arrives, against the machine's control period; and how soon the health and the alarms follow,
once the detectors have run.

`python -m bwr_twin.serve` plays the heavy machine (scenes/heavy_shadow.toml, lockstep), a PLC
client at 10 Hz drives it as examples/shadow_demo.py does, and the live shadow, a second client
subscribed to the tags, takes the samples its subscription brought after every PLC cycle and
publishes on its own OPC UA server (bwr_twin.shadow.publish). The latency is the wall-clock time
from the samples' arrival to the residuals written into its address space (and to the health
and alarms written); the
thresholds are learned on the first LEARN s, so the detectors run from then on, over every
block of the session so far.

    python tools/shadow_latency.py [--seconds 300]

Prints a table of the latencies' percentiles in ms and as a share of the control period.
"""

import argparse
import asyncio
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from asyncua import Client

from bwr_twin.shadow.detect import learn
from bwr_twin.shadow.live import LiveShadow, Source, read_once
from bwr_twin.shadow.publish import ShadowServer, residual_ranges
from bwr_twin.shadow.tags import read_tags
from bwr_twin.shadow.twin import ShadowTwin

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
from heavy_plc import HeavyPlc  # the PLC the demo and the tests drive serve with

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "heavy_shadow.toml"
MJCF = ROOT / "mjcf" / "bwr_heavy.xml"
TAGS = ROOT / "examples" / "shadow_tags.toml"
STEP, PERIOD = 10, 0.01  # control periods a PLC cycle, and the control period in s (heavy_shadow.toml)
LEARN = 60.0  # s of the session the thresholds are learned on


class Stopwatch:
    """An output after the shadow's server: when it hears of a block's verdict, the server has
    published it."""

    def __init__(self):
        self.arrived, self.verdicts = None, []

    async def residuals(self, blocks, measured_q, arrived=None) -> None:
        self.arrived = arrived

    async def verdict(self, health, alarms) -> None:
        self.verdicts.append(time.perf_counter() - self.arrived)

    async def stop(self) -> None:
        pass


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


async def session(url: str, seconds: float) -> tuple[list[float], list[float], int]:
    twin = ShadowTwin(MJCF)
    shadow = LiveShadow(twin, None, lambda event: None)
    source = Source(url, read_tags(TAGS, twin.model_name))
    await source.connect()
    published = ShadowServer(f"opc.tcp://127.0.0.1:{free_port()}", {})
    stopwatch = Stopwatch()
    async with Client(url, timeout=60, watchdog_intervall=60) as connection:
        plc = await HeavyPlc.attach(connection, STEP, PERIOD)
        for _ in range(round(seconds / (STEP * PERIOD))):
            await plc.cycle()
            if shadow.thresholds is None and shadow.time >= LEARN:
                shadow.thresholds = thresholds = learn([shadow.blocks()], shadow.counts, 0.01)
                published.ranges = residual_ranges(twin.limits, twin.machine.rated_speed, thresholds)
                await published.start()
            outputs = [published, stopwatch] if shadow.thresholds is not None else []
            await read_once(source, shadow, print, outputs)
    await source.close()
    await published.stop()
    return published.latencies, stopwatch.verdicts, len(shadow.blocks().start)


def row(name: str, values: list[float]) -> str:
    ms = 1e3 * np.asarray(values)
    cells = [np.median(ms), np.percentile(ms, 90), np.percentile(ms, 99), ms.max()]
    return (f"| {name} | {len(ms)} | " + " | ".join(f"{c:.1f}" for c in cells)
            + f" | {ms.max() / (1e3 * PERIOD):.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=300.0, help="the session's length in simulated s")
    args = parser.parse_args()
    url = f"opc.tcp://127.0.0.1:{free_port()}"
    server = subprocess.Popen([sys.executable, "-m", "bwr_twin.serve", str(SCENE), "--endpoint", url],
                              stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        for line in server.stdout:
            if line.startswith("Ctrl-C stops"):
                break
        residuals, verdicts, blocks = asyncio.run(session(url, args.seconds))
    finally:
        server.terminate()
        server.wait(timeout=30)
    print(f"{blocks} blocks of 1 s over {args.seconds:g} s; published from {LEARN:g} s on; "
          f"control period {PERIOD * 1e3:g} ms")
    print("| published | blocks | median (ms) | 90 % (ms) | 99 % (ms) | max (ms) | max / control period |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    print(row("residuals", residuals))
    print(row("health and alarms", verdicts))


if __name__ == "__main__":
    main()
