"""The OPC UA server around the twin: its address space, clock and security, from start to a
clean stop on Ctrl-C or SIGTERM."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import logging
import signal
from dataclasses import dataclass
from pathlib import Path

from asyncua import Server

from bwr_twin.config.scene import Scene
from bwr_twin.model.machine import AXES
from bwr_twin.serve import LOCKSTEP, ServeError
from bwr_twin.serve.address_space import INSTRUMENT_VARIABLES, METHODS, NAMESPACE_URI, AddressSpace
from bwr_twin.serve.alarms import Alarms
from bwr_twin.serve.announce import exposure_lines, is_loopback
from bwr_twin.serve.clock import Clock
from bwr_twin.serve.machinery import Machinery
from bwr_twin.serve.nodeset import write_nodeset
from bwr_twin.serve.results import RunWriter
from bwr_twin.serve.security import secure
from bwr_twin.serve.sensing import Sensing
from bwr_twin.serve.writes import write_each_node
from bwr_twin.sim.plant import mujoco_warnings
from bwr_twin.sim.ranges import eu_ranges
from bwr_twin.sim.twin import Twin

APPLICATION_URI = "urn:bwr_twin:serve"  # a server certificate's subjectAltName URI must be this


@dataclass(frozen=True)
class Options:
    """The command line's choices; `speed` simulated seconds per wall-clock second."""

    url: str
    host: str
    port: int
    mode: str = LOCKSTEP
    speed: float = 1.0
    watchdog_periods: int = 10
    users: Path | None = None
    user_certificates: Path | None = None
    certificate: Path | None = None
    private_key: Path | None = None
    out: Path | None = None
    overwrite: bool = False
    plots: bool = True


async def serve(scene: Scene, options: Options) -> int:
    """Serve the twin until SIGTERM (returns 0) or SIGINT (raises KeyboardInterrupt once stopped)."""
    stopped, interrupted = asyncio.Event(), []  # heard from here on; acted on once the server listens
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGTERM, stopped.set)
    loop.add_signal_handler(signal.SIGINT, lambda: (interrupted.append(True), stopped.set()))
    writer = None
    if options.out is not None:
        writer = RunWriter(options.out, overwrite=options.overwrite, plots=options.plots,
                           inputs=scene.input_files, log=_say)
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)  # the server reports in its own lines
    twin = Twin(scene)
    server = Server()
    await server.init()
    server.set_endpoint(options.url)
    server.set_server_name("bwr_twin reclaimer")
    await server.set_application_uri(APPLICATION_URI)
    policies, access = await secure(server, url=options.url, loopback=is_loopback(options.host),
                                    users_file=options.users, certificate=options.certificate,
                                    private_key=options.private_key, user_certificates=options.user_certificates)
    clock = Clock(twin, mode=options.mode, speed=options.speed, watchdog_periods=options.watchdog_periods,
                  log=_say, on_done=writer)
    space = await build_address_space(server, clock)
    try:
        await server.start()
    except OSError as exc:
        reason = f"port {options.port} is in use" if exc.errno == errno.EADDRINUSE else exc.strerror or str(exc)
        raise ServeError(f"--endpoint {options.url}: cannot listen ({reason})") from None

    for line in exposure_lines(url=options.url, host=options.host, port=options.port, mode=_mode_line(clock),
                               policies=policies, access=access, writable=space.writable(),
                               methods=[f"Reclaimer/{m}" for m in METHODS], namespace=NAMESPACE_URI):
        _say(line)
    try:
        with mujoco_warnings():  # a diverging run is reported by the twin, not printed by MuJoCo
            await stopped.wait()
    finally:
        await clock.close()
        if writer is not None:
            await writer.finish()
        await server.stop()
    _say("server stopped")
    if interrupted:
        raise KeyboardInterrupt
    return 0


async def build_address_space(server: Server, clock: Clock) -> AddressSpace:
    """The twin's nodes on `server`, typed: the contract's variables as analog items with their
    ranges, the instruments, scanners and faults the run has, the Machinery building blocks, the
    alarms; all published by `clock` from now on."""
    twin = clock.twin
    ranges = eu_ranges(twin.loop)
    instruments = [variable.name for variable in INSTRUMENT_VARIABLES if (variable.name, None) in ranges]
    clock.space = space = await AddressSpace.build(server, clock.methods(), ranges, instruments,
                                                   neighbour=twin.loop.neighbour is not None)
    clock.listeners = [await Machinery.build(space, twin.loop.machine), await Alarms.build(space)]
    sensing = await Sensing.build(space, twin)  # the scanners and the faults, if the run has them
    if sensing is not None:
        clock.listeners.append(sensing)
    for index, axis in enumerate(AXES):
        server.set_attribute_value_setter(space.nodes["DriveSetpoint", axis].nodeid, clock.setpoint_setter(index))
    write_each_node(server)  # a setter's refusal is its node's result, not the whole Write's
    await clock.publish(setpoint=True)
    return space


async def export_nodeset(scene: Scene, options: Options, path: Path) -> int:
    """`--nodeset`: write the address space `serve` would serve to `path` as a UA NodeSet2, and
    serve nothing."""
    logging.getLogger("asyncua").setLevel(logging.CRITICAL)
    server = Server()
    await server.init()
    clock = Clock(Twin(scene), mode=options.mode, speed=options.speed, watchdog_periods=options.watchdog_periods,
                  log=_say)
    await build_address_space(server, clock)
    count = await write_nodeset(server, NAMESPACE_URI, path, overwrite=options.overwrite)
    _say(f"nodeset: {count} nodes of {NAMESPACE_URI} written to {path}")
    return 0


def _mode_line(clock: Clock) -> str:
    twin = clock.twin
    most = " at most" if not twin.loop.tracking.shared else ""  # a bench plan ends when it is done
    path = f"{clock.path_periods} control periods{most} of {twin.period * 1e3:g} ms ({twin.loop.duration:g} s path)"
    if clock.mode == LOCKSTEP:
        return f"lockstep: Step(n) advances the twin n control periods; {path}"
    watchdog = (f"watchdog after {clock.watchdog.periods} periods without a DriveSetpoint write"
                if clock.watchdog.periods else "no watchdog")
    return f"realtime at {clock.speed:g}x the wall clock once Start is called; {path}; {watchdog}"


def _say(line: str) -> None:
    with contextlib.suppress(BrokenPipeError):  # a reader that went away does not stop the server
        print(line, flush=True)

