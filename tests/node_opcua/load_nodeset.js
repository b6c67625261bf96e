// Loads a NodeSet2 file into node-opcua's address space (on top of its standard nodeset) and
// writes to OUT.json, as one JSON object (stdout carries node-opcua's own warnings), what node-opcua made of the twin's namespace: every analog item's
// EngineeringUnits and EURange, and every method's InputArguments and OutputArguments.
// usage: node load_nodeset.js FILE.xml NAMESPACE_URI OUT.json
"use strict";
const fs = require("fs");
const { AddressSpace, generateAddressSpace, nodesets, NodeClass, coerceNodeId } = require("node-opcua");

const ANALOG_TYPES = new Set(["AnalogItemType", "AnalogUnitType"]);

function propertyValue(node, name) {
    const property = node.getPropertyByName(name);
    if (!property) return undefined;
    const value = property.readValue().value.value;
    return value === null || value === undefined ? null : JSON.parse(JSON.stringify(value));
}

async function main() {
    const [file, namespaceUri, out] = process.argv.slice(2);
    const addressSpace = AddressSpace.create();
    try {
        await generateAddressSpace(addressSpace, [nodesets.standard, file]);
        const namespace = addressSpace.getNamespace(namespaceUri);
        const analog = {};
        const methods = {};
        for (const node of namespace.nodeIterator()) {
            const key = node.nodeId.toString().replace(/^ns=\d+;/, "");
            if (node.nodeClass === NodeClass.Variable && node.typeDefinitionObj &&
                ANALOG_TYPES.has(node.typeDefinitionObj.browseName.name)) {
                analog[key] = {
                    type: node.typeDefinitionObj.browseName.name,
                    engineeringUnits: propertyValue(node, "EngineeringUnits"),
                    euRange: propertyValue(node, "EURange"),
                };
            } else if (node.nodeClass === NodeClass.Method) {
                methods[key] = {
                    inputArguments: propertyValue(node, "InputArguments"),
                    outputArguments: propertyValue(node, "OutputArguments"),
                };
            }
        }
        fs.writeFileSync(out, JSON.stringify({ namespaceIndex: namespace.index, analog, methods }));
    } finally {
        addressSpace.dispose();
    }
}

main().catch((error) => {
    process.stderr.write(`error: ${error && error.stack || error}\n`);
    process.exit(1);
});
