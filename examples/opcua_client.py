"""A minimal PLC for the twin's OPC UA server: a per-axis PD with the luff's holding torque,
run in lockstep (read the encoders, write the drive setpoints, Step(1)).

    python -m bwr_twin.serve pid_paper &              # lockstep mode on opc.tcp://127.0.0.1:4840
    python examples/opcua_client.py [--url opc.tcp://127.0.0.1:4840] [--periods 500]

Prints the largest encoder error per axis over the periods it ran.
"""

import argparse
import asyncio

from asyncua import Client, ua

NAMESPACE = "urn:bwr_twin:reclaimer"
AXES = ("Travel", "Slew", "Luff")
KP = (28000.0, 7262500.0, 5000000.0)  # N/m, N m/rad, N m/rad: pid_paper's gains, 2 rad/s
KD = (28000.0, 7262500.0, 5000000.0)  # N s/m, N m s/rad, N m s/rad
HOLD = (0.0, 0.0, 490500.0)  # N, N m, N m: the luff's static gravity torque


async def run(url: str, periods: int) -> list[float]:
    client = Client(url, timeout=60, watchdog_intervall=60)  # s: patient on a busy machine (docs/opcua.md)
    client.session_timeout = 600_000  # ms: what the server grants; asking for more only draws a warning
    async with client:
        ns = await client.get_namespace_index(NAMESPACE)
        reclaimer = await client.nodes.objects.get_child(f"{ns}:Reclaimer")

        async def nodes(name):
            return [await reclaimer.get_child([f"{ns}:{axis}", f"{ns}:{name}"]) for axis in AXES]

        measured = await nodes("EncoderPosition") + await nodes("EncoderVelocity")
        reference = await nodes("ReferencePosition") + await nodes("ReferenceVelocity")
        setpoints = await nodes("DriveSetpoint")
        step = await reclaimer.get_child(f"{ns}:Step")  # found once: a name would be looked up every call
        await reclaimer.call_method(f"{ns}:Reset")
        worst = [0.0, 0.0, 0.0]
        for _ in range(periods):
            q, qd, q_ref, qd_ref = (lambda v: (v[0:3], v[3:6], v[6:9], v[9:12]))(
                await client.read_values(measured + reference))
            forces = [HOLD[i] + KP[i] * (q_ref[i] - q[i]) + KD[i] * (qd_ref[i] - qd[i]) for i in range(3)]
            worst = [max(w, abs(r - m)) for w, r, m in zip(worst, q_ref, q)]
            await client.write_values(setpoints, [ua.Variant(f, ua.VariantType.Double) for f in forces])
            await reclaimer.call_method(step, ua.Variant(1, ua.VariantType.UInt32))
        return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--url", default="opc.tcp://127.0.0.1:4840")
    parser.add_argument("--periods", type=int, default=500)
    args = parser.parse_args()
    worst = asyncio.run(run(args.url, args.periods))
    print(f"largest encoder error over {args.periods} periods: travel {worst[0] * 1e3:.2f} mm, "
          f"slew {worst[1]:.5f} rad, luff {worst[2]:.5f} rad")


if __name__ == "__main__":
    main()
