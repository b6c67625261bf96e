"""The shadow beside a served machine: `python -m bwr_twin.serve` plays the heavy machine with a
plant fault at a time this script does not print until the end, a PLC (a per-axis PID at 10 Hz,
in lockstep) drives it along scenes/heavy_shadow.toml's path, and the live shadow, a second OPC
UA client, watches it and prints its events as they happen, and shows them in the browser: the
machine as measured, its twin's ghost, the residuals and the alarms (bwr_twin.shadow.view).

    python examples/shadow_demo.py [--seed N] [--view PORT]          # or: make shadow

The shadow learns its thresholds from the first LEARN s, which are fault-free; the fault (a
friction rise, a mass change or a derate, drawn from the seed) starts later.
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

from bwr_twin.shadow.detect import learn
from bwr_twin.shadow.live import LiveShadow, Source, read_once
from bwr_twin.shadow.measured import encoder_counts
from bwr_twin.shadow.tags import read_tags
from bwr_twin.shadow.twin import ShadowTwin
from bwr_twin.shadow.view import ShadowView

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "scenes" / "heavy_shadow.toml"
MJCF = ROOT / "mjcf" / "bwr_heavy.xml"
TAGS = ROOT / "examples" / "shadow_tags.toml"
STEP, PERIOD = 10, 0.01  # control periods a PLC cycle, and their length in s
SECONDS, LEARN = 300.0, 90.0  # s: the path, and its fault-free start the thresholds are learned on
FAULTS = ('kind = "friction_rise"\naxis = "slew"\npercent = 40.0', 'kind = "mass_change"\nmass = 10000.0',
          'kind = "drive_derate"\naxis = "travel"\npercent = 20.0')


async def watch(url: str, twin: ShadowTwin, view: ShadowView) -> None:
    shadow = LiveShadow(twin, None, lambda event: print(json.dumps(event), flush=True))
    source = Source(url, read_tags(TAGS, twin.model_name))
    await source.connect()
    async with Client(url, timeout=60, watchdog_intervall=60) as connection:
        plc = await HeavyPlc.attach(connection, STEP, PERIOD)
        for cycle in range(round(SECONDS / (STEP * PERIOD))):
            await plc.cycle()
            await read_once(source, shadow, print, [view])
            if shadow.thresholds is None and shadow.time >= LEARN:
                shadow.thresholds = learn([shadow.blocks()], encoder_counts(shadow.measured()), 0.01)
                print(f"thresholds learned on the first {LEARN:g} s; watching", flush=True)
            if cycle % 300 == 0:
                print(f"t = {shadow.time:.0f} s", flush=True)
    await source.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=None, help="draws the fault and its time (default: at random)")
    parser.add_argument("--view", type=int, default=8080, help="the view's port (default 8080; 0: a free one)")
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    fault, start = FAULTS[rng.integers(len(FAULTS))], float(round(rng.uniform(LEARN + 20, SECONDS - 60)))
    with tempfile.TemporaryDirectory() as folder, socket.socket() as probe:
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
            twin = ShadowTwin(MJCF)
            view = ShadowView(twin.machine, port=args.view)
            print(f"the shadow's view: {view.url}", flush=True)
            asyncio.run(watch(url, twin, view))
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


if __name__ == "__main__":
    main()
