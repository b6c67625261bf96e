// A node-opcua client against the twin's server, as an HMI or a PLC of another stack would be:
// browses Objects/Reclaimer, reads a unit and a range over the wire, subscribes to SimTime and
// the travel's reference, writes the setpoints, calls Step (well and badly), and waits for the
// subscription to see SimTime move. Writes what it saw to OUT.json; stops itself within a minute.
// usage: node client.js opc.tcp://127.0.0.1:PORT NAMESPACE_URI PKI_FOLDER OUT.json
// PKI_FOLDER: where the client keeps its own certificate (made once, about 4 s) and its trust lists.
"use strict";
const fs = require("fs");
const {
    OPCUAClient, MessageSecurityMode, SecurityPolicy, AttributeIds, DataType, TimestampsToReturn,
    ClientMonitoredItem, OPCUACertificateManager,
} = require("node-opcua");

const GIVE_UP_MS = 60000; // a busy machine included; the test's own timeout is longer
const STEPS = [1, 10, 100];

const stopper = setTimeout(() => {
    process.stderr.write(`error: gave up after ${GIVE_UP_MS} ms\n`);
    process.exit(2);
}, GIVE_UP_MS);

async function main() {
    const [url, namespaceUri, pki, out] = process.argv.slice(2);
    const client = OPCUAClient.create({
        applicationName: "node-opcua check of bwr_twin",
        securityMode: MessageSecurityMode.None,
        securityPolicy: SecurityPolicy.None,
        endpointMustExist: false,
        connectionStrategy: { maxRetry: 3, initialDelay: 200, maxDelay: 2000 },
        clientCertificateManager: new OPCUACertificateManager({ rootFolder: pki, automaticallyAcceptUnknownCertificate: true }),
    });
    await client.connect(url);
    const session = await client.createSession();
    try {
        const ns = (await session.readNamespaceArray()).indexOf(namespaceUri);
        const id = (path) => `ns=${ns};s=${path}`;
        const objects = await session.browse("ObjectsFolder");
        const reclaimer = objects.references.find((r) => r.browseName.name === "Reclaimer");
        const children = (await session.browse(reclaimer.nodeId)).references.map((r) => r.browseName.name);
        const travel = (await session.browse(id("Reclaimer.Travel"))).references.map((r) => r.browseName.name);
        const [units, range] = await session.read([
            { nodeId: id("Reclaimer.Travel.EncoderPosition.EngineeringUnits"), attributeId: AttributeIds.Value },
            { nodeId: id("Reclaimer.Travel.EncoderPosition.EURange"), attributeId: AttributeIds.Value },
        ]);

        const reset = await session.call({ objectId: reclaimer.nodeId, methodId: id("Reclaimer.Reset"), inputArguments: [] });
        const subscription = await session.createSubscription2({
            requestedPublishingInterval: 20, requestedMaxKeepAliveCount: 20, requestedLifetimeCount: 600,
            publishingEnabled: true, priority: 1,
        });
        const notified = { SimTime: [], ReferencePosition: [], DriveCommanded: [] };
        const stamped = { SimTime: [], DriveCommanded: [] };  // each notification's source timestamp, ms since 1970
        for (const [name, path] of [["SimTime", "Reclaimer.SimTime"], ["ReferencePosition", "Reclaimer.Travel.ReferencePosition"],
                                    ["DriveCommanded", "Reclaimer.Luff.DriveCommanded"]]) {
            const item = ClientMonitoredItem.create(subscription, { nodeId: id(path), attributeId: AttributeIds.Value },
                { samplingInterval: 0, discardOldest: true, queueSize: 100 }, TimestampsToReturn.Both);
            item.on("changed", (value) => {
                notified[name].push(value.value.value);
                if (name in stamped) stamped[name].push(value.sourceTimestamp ? value.sourceTimestamp.getTime() : null);
            });
        }
        const writes = await session.write([0, 1, 2].map((axis) => ({
            nodeId: id(`Reclaimer.${["Travel", "Slew", "Luff"][axis]}.DriveSetpoint`), attributeId: AttributeIds.Value,
            value: { value: { dataType: DataType.Double, value: axis === 2 ? 490500.0 : 0.0 } },
        })));
        const steps = [];
        for (const n of STEPS) {
            const result = await session.call({
                objectId: reclaimer.nodeId, methodId: id("Reclaimer.Step"),
                inputArguments: [{ dataType: DataType.UInt32, value: n }],
            });
            steps.push({ status: result.statusCode.name, simTime: result.outputArguments.map((v) => v.value) });
        }
        const bare = await session.call({ objectId: reclaimer.nodeId, methodId: id("Reclaimer.Step"), inputArguments: [] });
        const end = steps[steps.length - 1].simTime[0];
        const deadline = Date.now() + 20000;
        while (!notified.SimTime.some((t) => Math.abs(t - end) < 1e-9) && Date.now() < deadline) {
            await new Promise((resolve) => setTimeout(resolve, 50));
        }
        await subscription.terminate();
        fs.writeFileSync(out, JSON.stringify({
            namespaceIndex: ns, reclaimerChildren: children, travelChildren: travel,
            units: units.value.value, unitsStatus: units.statusCode.name, range: range.value.value,
            reset: reset.statusCode.name, writes: writes.map((s) => s.name), steps,
            stepWithoutArgument: bare.statusCode.name, notified, stamped,
        }));
    } finally {
        await session.close();
        await client.disconnect();
    }
}

main().then(() => clearTimeout(stopper)).catch((error) => {
    process.stderr.write(`error: ${error && error.stack || error}\n`);
    process.exit(1);
});
