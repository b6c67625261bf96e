"""Speed of the OPC UA server as a PLC sees it, measured in one run.

    python tools/bench_opcua.py [SCENE] [--periods 2000] [--seconds 10]

Starts `python -m bwr_twin.serve SCENE` twice on free loopback ports, and prints:

(a) lockstep mode: control periods per second of the software-in-the-loop cycle a PLC runs
    (read the encoders and reference, write three setpoints, Step(1)), of Step(1) alone, and of
    Step(1000) against the same run stepped in-process with no server;
(b) real-time mode at 100 Hz (the scene's 10 ms period, speed 1), for `--seconds` of a PLC
    writing every period: the jitter of the server's control period (the spacing of SimTime's
    source timestamps against 10 ms: standard deviation and largest deviation, ms), overruns,
    watchdog trips, and the round trip from a setpoint write to the first read of DriveApplied
    that reflects it (median and 95th percentile, ms, a probe every 20 periods);
(c) real-time mode at a speed the machine cannot follow (`--overload-speed`, no watchdog), for
    `--overload-seconds`: simulated seconds per wall-clock second, overruns, and the slowest and
    median answer to a client reading SimTime meanwhile (ms): the server must keep answering.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from asyncua import Client, ua

from bwr_twin.config.scene import load_scene
from bwr_twin.serve.address_space import NAMESPACE_URI
from bwr_twin.shipped import DEFAULT_SCENE, find_scene
from bwr_twin.sim.lockstep import Lockstep

ROOT = Path(__file__).resolve().parents[1]
AXES = ("Travel", "Slew", "Luff")
HOLD = (0.0, 0.0, 490500.0)  # N, N m, N m: the paper machine's luff holding torque at the path's start
PROBE_EVERY = 20  # control periods between two round-trip probes


class Server:
    """`python -m bwr_twin.serve` on a free loopback port, until `stop()`."""

    def __init__(self, scene: str, *options: str):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.url = f"opc.tcp://127.0.0.1:{probe.getsockname()[1]}"
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        self.process = subprocess.Popen([sys.executable, "-m", "bwr_twin.serve", scene, "--endpoint", self.url,
                                         *options], stdout=subprocess.PIPE, text=True, env=env)
        for line in self.process.stdout:
            if line.startswith("Ctrl-C stops"):
                break
        else:
            raise SystemExit(f"the server did not start (status {self.process.wait()})")

    def stop(self) -> None:
        self.process.send_signal(signal.SIGTERM)
        self.process.communicate(timeout=30)


async def nodes(client: Client):
    ns = await client.get_namespace_index(NAMESPACE_URI)
    reclaimer = await client.nodes.objects.get_child(f"{ns}:Reclaimer")

    async def axis(name):
        return [await reclaimer.get_child([f"{ns}:{a}", f"{ns}:{name}"]) for a in AXES]

    async def machine(name):
        return await reclaimer.get_child(f"{ns}:{name}")

    return ns, reclaimer, axis, machine


def doubles(values) -> list[ua.Variant]:
    return [ua.Variant(float(v), ua.VariantType.Double) for v in values]


async def lockstep(url: str, periods: int) -> dict[str, float]:
    """Control periods per second of the SIL cycle, of Step(1) alone and of Step(1000)."""
    async with Client(url) as client:
        ns, reclaimer, axis, _ = await nodes(client)
        readings = (await axis("EncoderPosition") + await axis("EncoderVelocity") + await axis("ReferencePosition")
                    + await axis("ReferenceVelocity"))
        setpoints = await axis("DriveSetpoint")
        step, one = await reclaimer.get_child(f"{ns}:Step"), ua.Variant(1, ua.VariantType.UInt32)  # resolved once
        await reclaimer.call_method(f"{ns}:Reset")
        started = time.perf_counter()
        for _ in range(periods):
            await client.read_values(readings)
            await client.write_values(setpoints, doubles(HOLD))
            await reclaimer.call_method(step, one)
        cycle = periods / (time.perf_counter() - started)
        started = time.perf_counter()
        for _ in range(periods):
            await reclaimer.call_method(step, one)
        single = periods / (time.perf_counter() - started)
        calls = 10
        started = time.perf_counter()
        for _ in range(calls):
            await reclaimer.call_method(step, ua.Variant(1000, ua.VariantType.UInt32))
        bulk = calls * 1000 / (time.perf_counter() - started)
    return {"cycle": cycle, "step1": single, "step1000": bulk}


def in_process(scene_path: str, periods: int) -> float:
    """Control periods per second of the same run stepped with no server (measure + advance)."""
    loop = Lockstep([load_scene(scene_path)], nthread=1)
    command = np.array([HOLD])
    started = time.perf_counter()
    for _ in range(periods):
        loop.measure()
        loop.advance(command)
    return periods / (time.perf_counter() - started)


class Stamps:
    """asyncua subscription handler: the source timestamp of every SimTime update."""

    def __init__(self):
        self.times: list[float] = []

    def datachange_notification(self, node, value, data) -> None:
        self.times.append(data.monitored_item.Value.SourceTimestamp.timestamp())


async def realtime(url: str, seconds: float) -> dict[str, object]:
    """A PLC writing every 10 ms for `seconds`, with round-trip probes; the server's tick times."""
    async with Client(url) as client:
        ns, reclaimer, axis, machine = await nodes(client)
        setpoints, applied = await axis("DriveSetpoint"), await axis("DriveApplied")
        period = await (await machine("ControlPeriod")).read_value()
        stamps = Stamps()
        subscription = await client.create_subscription(period * 1e3, stamps)
        await subscription.subscribe_data_change(await machine("SimTime"), queuesize=10_000, sampling_interval=0)
        await client.write_values(setpoints, doubles(HOLD))
        await reclaimer.call_method(f"{ns}:Start")
        latencies, force = [], list(HOLD)
        started = time.perf_counter()
        for tick in range(round(seconds / period)):
            if tick % PROBE_EVERY == PROBE_EVERY - 1:
                force[0] = 10.0 + tick * 1e-3  # N on the travel: a value not seen before
                sent = time.perf_counter()
                await client.write_values(setpoints, doubles(force))
                while abs(await applied[0].read_value() - force[0]) > 1e-9 * abs(force[0]):
                    pass
                latencies.append(time.perf_counter() - sent)
            else:
                await client.write_values(setpoints, doubles(force))
            await asyncio.sleep(max(started + (tick + 1) * period - time.perf_counter(), 0.0))
        overruns = await (await machine("Overruns")).read_value()
        tripped = await (await machine("WatchdogTripped")).read_value()
        await reclaimer.call_method(f"{ns}:Stop")
        await asyncio.sleep(5 * period)  # the last notifications
        await subscription.delete()
    spacing = np.diff(stamps.times[1:])  # the first update is the subscription's initial value
    deviation = (spacing - period) * 1e3
    return {"period": period, "ticks": len(spacing), "std": deviation.std(), "max": np.abs(deviation).max(),
            "overruns": overruns, "tripped": tripped, "latency": np.array(latencies) * 1e3}


async def overload(url: str, seconds: float) -> dict[str, float]:
    """Reads of SimTime while the clock runs behind: their latencies, and how far time got."""
    async with Client(url) as client:
        ns, reclaimer, axis, machine = await nodes(client)
        sim_time, overruns = await machine("SimTime"), await machine("Overruns")
        period = await (await machine("ControlPeriod")).read_value()
        await client.write_values(await axis("DriveSetpoint"), doubles(HOLD))
        await reclaimer.call_method(f"{ns}:Start")
        latencies, started = [], time.perf_counter()
        while time.perf_counter() - started < seconds:
            sent = time.perf_counter()
            await sim_time.read_value()
            latencies.append(time.perf_counter() - sent)
        wall = time.perf_counter() - started
        await reclaimer.call_method(f"{ns}:Stop")
        late, reached = await overruns.read_value(), await sim_time.read_value()
    return {"rate": reached / wall, "overruns": late, "periods": round(reached / period),
            "worst": max(latencies) * 1e3, "median": np.median(latencies) * 1e3}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scene", nargs="?", default=str(DEFAULT_SCENE))
    parser.add_argument("--periods", type=int, default=2000, help="lockstep: periods of each loop")
    parser.add_argument("--seconds", type=float, default=10.0, help="real time: wall-clock seconds of the PLC")
    parser.add_argument("--overload-speed", type=float, default=200.0)
    parser.add_argument("--overload-seconds", type=float, default=5.0)
    args = parser.parse_args()
    scene = str(find_scene(args.scene))

    server = Server(scene)
    try:
        rates = asyncio.run(lockstep(server.url, args.periods))
    finally:
        server.stop()
    alone = in_process(scene, 10_000)
    print(f"scene: {Path(scene).name}; lockstep mode over OPC UA on loopback, {args.periods} periods a loop")
    print(f"  SIL cycle (read 12 values, write 3 setpoints, Step(1)): {rates['cycle']:,.0f} periods/s, "
          f"{1e3 / rates['cycle']:.2f} ms a period")
    print(f"  Step(1) alone: {rates['step1']:,.0f} periods/s, {1e3 / rates['step1']:.2f} ms a call")
    print(f"  Step(1000): {rates['step1000']:,.0f} periods/s; in-process, no server: {alone:,.0f} periods/s "
          f"({1e6 / alone:.0f} us a period)")

    server = Server(scene, "--realtime")
    try:
        figures = asyncio.run(realtime(server.url, args.seconds))
    finally:
        server.stop()
    latency = figures["latency"]
    print(f"real-time mode, {1 / figures['period']:g} Hz, speed 1, {args.seconds:g} s of a PLC writing "
          "every period")
    print(f"  control period jitter over {figures['ticks']} periods: std {figures['std']:.3f} ms, "
          f"largest deviation {figures['max']:.2f} ms; overruns {figures['overruns']}, "
          f"watchdog tripped: {figures['tripped']}")
    print(f"  setpoint write -> DriveApplied read back ({len(latency)} probes): "
          f"median {np.median(latency):.2f} ms, p95 {np.percentile(latency, 95):.2f} ms")

    server = Server(scene, "--realtime", "--speed", f"{args.overload_speed:g}", "--watchdog-periods", "0")
    try:
        behind = asyncio.run(overload(server.url, args.overload_seconds))
    finally:
        server.stop()
    print(f"real-time mode at speed {args.overload_speed:g}, {args.overload_seconds:g} s: "
          f"{behind['rate']:.1f} simulated s per s, {behind['overruns']} overruns in {behind['periods']} periods; "
          f"a read of SimTime meanwhile: median {behind['median']:.2f} ms, slowest {behind['worst']:.1f} ms")


if __name__ == "__main__":
    main()
