"""The shadow beside a served machine: `python -m bwr_twin.serve` plays the heavy machine with a
plant fault at a time this script does not print until the end, a PLC (a per-axis PID at 10 Hz,
in lockstep) drives it along scenes/heavy_shadow.toml's path, and the live shadow, a second OPC
UA client, watches it and prints its events as they happen, and shows them in the browser: the
machine as measured, its twin's ghost, the residuals and the alarms (bwr_twin.shadow.view).

    python examples/shadow_demo.py [--seed N] [--view PORT] [--thresholds FILE]   # or: make shadow

The fault (a friction rise, a mass change or a derate) and its start are drawn from the seed.
The shadow's thresholds are learned as on a real machine, from fault-free logs of its usual
work at the rate the shadow will see it: an hour of it, twelve runs of the same scene with
other seeds under the PLC's PID at its 10 Hz, simulated before the demo starts (about 15 s);
or read from --thresholds.
"""

import argparse
import asyncio
import json
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from asyncua import Client
from heavy_plc import HeavyPlc

from bwr_twin.config.scene import load_scene
from bwr_twin.errors import exit_status
from bwr_twin.progress import simulated_seconds
from bwr_twin.results.rundir import write_run
from bwr_twin.shadow.cli import DEFAULT_PER_HOUR
from bwr_twin.shadow.detect import Thresholds
from bwr_twin.shadow.live import LiveShadow, Source, read_once
from bwr_twin.shadow.tags import read_tags
from bwr_twin.shadow.twin import ShadowTwin
from bwr_twin.shadow.view import ShadowView
from bwr_twin.shadow.watch import learn_from
from bwr_twin.sim.lockstep import simulate

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "heavy_shadow.toml"
MJCF = ROOT / "mjcf" / "bwr_heavy.xml"
TAGS = ROOT / "examples" / "shadow_tags.toml"
STEP, PERIOD = 10, 0.01  # control periods a PLC cycle, and their length in s
SECONDS = 300.0  # s: the path
LEARN_ON = range(1000, 1012)  # the seeds of the fault-free logs the thresholds are learned on: an hour
FAULTS = ('kind = "friction_rise"\naxis = "slew"\npercent = 40.0', 'kind = "mass_change"\nmass = 10000.0',
          'kind = "drive_derate"\naxis = "travel"\npercent = 20.0')


def learned(twin: ShadowTwin, folder: Path) -> Thresholds:
    """Thresholds from an hour of fault-free logs of the scene, sampled as the shadow sees the
    served machine: the PLC's cycle is their control and record period."""
    logs, cycle = [], STEP * PERIOD
    with simulated_seconds("fault-free logs to learn from") as progress:
        for i, seed in enumerate(LEARN_ON):
            scene, log = folder / f"fault-free-{seed}.toml", folder / f"fault-free-{seed}"
            scene.write_text(f'extends = "{SCENE}"\n[simulation]\nseed = {seed}\ncontrol_period = {cycle}\n'
                             f"record_period = {cycle}\n")
            write_run(simulate(load_scene(scene), nthread=1), log, plots=False)
            logs.append(log)
            progress((i + 1) * SECONDS, len(LEARN_ON) * SECONDS)
    thresholds = learn_from(twin, logs, DEFAULT_PER_HOUR)
    print(f"thresholds learned on {len(logs) * SECONDS / 3600:g} h of fault-free logs; watching", flush=True)
    return thresholds


async def watch(url: str, twin: ShadowTwin, thresholds: Thresholds, view: ShadowView) -> None:
    shadow = LiveShadow(twin, thresholds, lambda event: print(json.dumps(event), flush=True))
    source = Source(url, read_tags(TAGS, twin.model_name))
    await source.connect()
    async with Client(url, timeout=60, watchdog_intervall=60) as connection:
        plc = await HeavyPlc.attach(connection, STEP, PERIOD)
        for cycle in range(round(SECONDS / (STEP * PERIOD))):
            await plc.cycle()
            await read_once(source, shadow, print, [view])
            if cycle % 300 == 0:
                print(f"t = {shadow.time:.0f} s", flush=True)
    await source.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=None, help="draws the fault and its time (default: at random)")
    parser.add_argument("--view", type=int, default=8080, help="the view's port (default 8080; 0: a free one)")
    parser.add_argument("--thresholds", type=Path, help="thresholds.json a shadow wrote (default: learned from an "
                        "hour of fault-free logs)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    fault, start = FAULTS[rng.integers(len(FAULTS))], float(round(rng.uniform(60.0, SECONDS - 60)))
    twin = ShadowTwin(MJCF)
    with tempfile.TemporaryDirectory() as folder, socket.socket() as probe:
        thresholds = Thresholds.read(args.thresholds) if args.thresholds else learned(twin, Path(folder))
        probe.bind(("127.0.0.1", 0))
        url = f"opc.tcp://127.0.0.1:{probe.getsockname()[1]}"
        probe.close()
        scene = Path(folder) / "machine.toml"
        scene.write_text(f'extends = "{SCENE}"\n[[faults]]\n{fault}\nstart = {start}\n')
        server = subprocess.Popen([sys.executable, "-m", "bwr_twin.serve", str(scene), "--endpoint", url],
                                  stdout=subprocess.PIPE, text=True)
        try:
            for line in server.stdout:
                if line.startswith("Ctrl-C stops"):
                    break
            view = ShadowView(twin.machine, port=args.view)
            print(f"the shadow's view: {view.url}", flush=True)
            asyncio.run(watch(url, twin, thresholds, view))
        finally:
            server.terminate()
            server.wait(timeout=30)
    print(f"the machine's fault was: {' '.join(fault.split())}, from {start:g} s")
    print(f"the view stays at {view.url} until Ctrl-C", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        asyncio.run(view.stop())
    return 0


if __name__ == "__main__":
    sys.exit(exit_status(main, interrupted="interrupted"))
