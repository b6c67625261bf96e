// node-opcua on the twin's secured endpoint (Basic256Sha256, SignAndEncrypt): an anonymous
// session and a user's, each reading what it may do (a setpoint's UserAccessLevel, Step's
// UserExecutable) and calling Step; the user's password goes in the UserName token as the
// endpoint's token policy asks. Writes what it saw to OUT.json; stops itself within a minute.
// usage: BWR_PASSWORD=... node login.js opc.tcp://127.0.0.1:PORT NAMESPACE_URI USER PKI_FOLDER OUT.json
"use strict";
const fs = require("fs");
const {
    OPCUAClient, MessageSecurityMode, SecurityPolicy, AttributeIds, DataType, OPCUACertificateManager,
    UserTokenType,
} = require("node-opcua");

const GIVE_UP_MS = 60000;
const stopper = setTimeout(() => {
    process.stderr.write(`error: gave up after ${GIVE_UP_MS} ms\n`);
    process.exit(2);
}, GIVE_UP_MS);

async function session(client, identity, namespaceUri) {
    const opened = await client.createSession(identity);
    try {
        const ns = (await opened.readNamespaceArray()).indexOf(namespaceUri);
        const [level, executable] = await opened.read([
            { nodeId: `ns=${ns};s=Reclaimer.Travel.DriveSetpoint`, attributeId: AttributeIds.UserAccessLevel },
            { nodeId: `ns=${ns};s=Reclaimer.Step`, attributeId: AttributeIds.UserExecutable },
        ]);
        let step;
        try {
            step = (await opened.call({
                objectId: `ns=${ns};s=Reclaimer`, methodId: `ns=${ns};s=Reclaimer.Step`,
                inputArguments: [{ dataType: DataType.UInt32, value: 1 }],
            })).statusCode.name;
        } catch (refused) { // a whole request refused: node-opcua throws with the service's code
            step = refused.message.match(/Bad\w+/) ? refused.message.match(/Bad\w+/)[0] : refused.message;
        }
        return { userAccessLevel: level.value.value, userExecutable: executable.value.value, step };
    } finally {
        await opened.close();
    }
}

async function main() {
    const [url, namespaceUri, userName, pki, out] = process.argv.slice(2);
    const client = OPCUAClient.create({
        applicationName: "node-opcua check of bwr_twin",
        securityMode: MessageSecurityMode.SignAndEncrypt,
        securityPolicy: SecurityPolicy.Basic256Sha256,
        endpointMustExist: false,
        connectionStrategy: { maxRetry: 3, initialDelay: 200, maxDelay: 2000 },
        clientCertificateManager: new OPCUACertificateManager({ rootFolder: pki, automaticallyAcceptUnknownCertificate: true }),
    });
    await client.connect(url);
    try {
        const endpoints = await client.getEndpoints();
        const tokens = endpoints.flatMap((e) => e.userIdentityTokens
            .filter((t) => t.tokenType === UserTokenType.UserName)
            .map((t) => ({ endpoint: e.securityPolicyUri, token: t.securityPolicyUri })));
        const anonymous = await session(client, { type: UserTokenType.Anonymous }, namespaceUri);
        const user = await session(client, { type: UserTokenType.UserName, userName, password: process.env.BWR_PASSWORD },
            namespaceUri);
        fs.writeFileSync(out, JSON.stringify({ tokens, anonymous, user }));
    } finally {
        await client.disconnect();
    }
}

main().then(() => clearTimeout(stopper)).catch((error) => {
    process.stderr.write(`error: ${error && error.stack || error}\n`);
    process.exit(1);
});
