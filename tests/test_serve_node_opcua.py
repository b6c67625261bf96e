"""The twin's OPC UA as a stack other than asyncua reads it: the NodeSet2 file validated against
the OPC Foundation's UANodeSet.xsd and loaded by node-opcua with every unit, range and method
argument, and a node-opcua client that browses, steps and subscribes against `serve`
(docs/opcua.md). node-opcua comes from npm (tests/node_opcua_stack.py), once per checkout."""

from __future__ import annotations

import subprocess

import pytest
from conftest import ROOT, write_short_scene
from lxml import etree
from node_opcua_stack import install, run_script
from test_serve import Launched, environment, serve_command

from bwr_twin.serve.address_space import AXIS_VARIABLES, MACHINE_VARIABLES, NAMESPACE_URI, UNITS

UA_NODESET = "{http://opcfoundation.org/UA/2011/03/UANodeSet.xsd}"
UA_TYPES = "{http://opcfoundation.org/UA/2008/02/Types.xsd}"
XML_ENCODINGS = {"i=885": "Range", "i=888": "EUInformation", "i=297": "Argument"}  # Part 6: "Default XML"


@pytest.fixture(scope="session")
def node_opcua():
    """node-opcua's node_modules folder, installed once (the install's time printed with -s)."""
    modules, seconds = install()
    print(f"\nnode-opcua: {f'installed in {seconds:.1f} s' if seconds else 'found installed'} ({modules})")
    return modules


@pytest.fixture(scope="module")
def short_scene(tmp_path_factory):
    return write_short_scene(tmp_path_factory.mktemp("node_opcua"))


@pytest.fixture(scope="module")
def nodeset(short_scene, tmp_path_factory):
    path = tmp_path_factory.mktemp("nodeset") / "reclaimer.xml"
    written = subprocess.run(serve_command(short_scene, "--nodeset", str(path)), cwd=ROOT, env=environment(),
                             capture_output=True, text=True, timeout=120, check=False)
    assert written.returncode == 0, written.stderr
    return path


def test_the_nodeset_validates_against_the_schema_and_names_its_models(nodeset, node_opcua):
    schema = etree.XMLSchema(etree.parse(str(node_opcua / "node-opcua-nodesets" / "nodesets" / "UANodeSet.xsd")))
    document = etree.parse(str(nodeset))
    assert schema.validate(document), [str(error) for error in schema.error_log][:5]

    (model,) = document.getroot().iterfind(f"{UA_NODESET}Models/{UA_NODESET}Model")
    (required,) = model.iterfind(f"{UA_NODESET}RequiredModel")
    assert model.get("ModelUri") == NAMESPACE_URI and model.get("Version")
    assert required.get("ModelUri") == "http://opcfoundation.org/UA/" and required.get("Version").startswith("1.05")

    # Every ExtensionObject names its DataType's XML encoding node, not the DataType (i=884, 887, 296).
    type_ids = [(element.findtext(f"{UA_TYPES}TypeId/{UA_TYPES}Identifier"),
                 etree.QName(element.find(f"{UA_TYPES}Body")[0]).localname)
                for element in document.iter(f"{UA_TYPES}ExtensionObject")]
    assert type_ids and all(XML_ENCODINGS.get(type_id) == body for type_id, body in type_ids), set(type_ids)
    assert {body for _, body in type_ids} == set(XML_ENCODINGS.values())


def test_node_opcua_loads_every_unit_range_and_argument_of_the_nodeset(nodeset, node_opcua, tmp_path):
    loaded = run_script(node_opcua, "load_nodeset.js", str(nodeset), NAMESPACE_URI, out=tmp_path / "loaded.json")
    analog = loaded["analog"]
    doubles = [v for v in MACHINE_VARIABLES if v.variant.name == "Double"]
    assert len(analog) == len(doubles) + 3 * len(AXIS_VARIABLES) - 3  # every Double; AtLimit is a Boolean
    missing = {node: item for node, item in analog.items() if item["engineeringUnits"] is None
               or item["euRange"] is None}
    assert not missing, f"{len(missing)} analog items load without units or range: {sorted(missing)}"
    travel = analog["s=Reclaimer.Travel.EncoderPosition"]
    assert travel["type"] == "AnalogUnitType" and travel["engineeringUnits"]["displayName"]["text"] == "m"
    assert travel["engineeringUnits"]["unitId"] == int.from_bytes(UNITS["m"][0].encode(), "big")
    assert travel["euRange"]["low"] < 0 < travel["euRange"]["high"]
    assert analog["s=Reclaimer.SimTime"]["euRange"] == {"low": 0, "high": 20}  # the short path's 20 s

    step = loaded["methods"]["s=Reclaimer.Step"]
    assert [(a["name"], a["dataType"], a["valueRank"]) for a in step["inputArguments"]] == [("n", "ns=0;i=7", -1)]
    assert [(a["name"], a["dataType"]) for a in step["outputArguments"]] == [("SimTime", "ns=0;i=11")]


def test_a_node_opcua_client_browses_steps_and_sees_its_subscription_move(short_scene, node_opcua, tmp_path):
    server = Launched(short_scene)
    try:
        seen = run_script(node_opcua, "client.js", server.ready(), NAMESPACE_URI, str(node_opcua.parent / "pki"),
                          out=tmp_path / "client.json")
    finally:
        status = server.stop()
    assert status == 0 and "Traceback" not in server.stderr, server.stderr

    assert {"SimTime", "PeriodsLeft", "Travel", "Slew", "Luff", "Step", "Reset"} <= set(seen["reclaimerChildren"])
    assert "DriveSetpoint" in seen["travelChildren"] and "EncoderPosition" in seen["travelChildren"]
    assert seen["units"]["displayName"]["text"] == "m" and seen["range"]["low"] < 0 < seen["range"]["high"]
    assert seen["reset"] == "Good" and seen["writes"] == ["Good"] * 3
    assert [step["status"] for step in seen["steps"]] == ["Good"] * 3
    assert [step["simTime"][0] for step in seen["steps"]] == pytest.approx([0.01, 0.11, 1.11])  # 1, 10, 100 periods
    assert seen["stepWithoutArgument"] == "BadArgumentsMissing"
    # The subscription saw SimTime reach each Step's end (a publication per Step), and the reference move.
    assert seen["notified"]["SimTime"][-1] == pytest.approx(1.11)
    assert len(set(seen["notified"]["SimTime"])) >= 2 and len(set(seen["notified"]["ReferencePosition"])) >= 2
    # The luff's commanded force comes stamped with the readings of the period it was held over
    # (a client groups a cycle's values by source timestamp): 490.5 kN m from the first Step on.
    commanded, stamps = seen["notified"]["DriveCommanded"], seen["stamped"]["DriveCommanded"]
    assert commanded and commanded[-1] == pytest.approx(490500.0)
    assert None not in stamps and set(stamps) <= set(seen["stamped"]["SimTime"])
    times = dict(zip(seen["stamped"]["SimTime"], seen["notified"]["SimTime"], strict=True))
    assert [times[stamp] > 0 for stamp in stamps] == [value == pytest.approx(490500.0) for value in commanded]


def test_node_opcua_logs_in_with_an_encrypted_password_and_reads_what_each_session_may_do(short_scene, node_opcua,
                                                                                          tmp_path):
    """On the secured endpoint node-opcua finds the UserName token policy naming Basic256Sha256, so
    it encrypts the password (asyncua decrypts it); an anonymous session reads no write access
    and Step not executable, and is refused Step; the user steps."""
    from test_serve import PASSWORD, USER, certificate_pair

    from bwr_twin.serve.security import hash_password

    users = tmp_path / "users.txt"
    users.write_text(f"{USER}:{hash_password(PASSWORD)}\n")
    cert, key = certificate_pair(tmp_path, "server")
    server = Launched(short_scene, "--users", str(users), "--certificate", str(cert), "--private-key", str(key))
    try:
        seen = run_script(node_opcua, "login.js", server.ready(), NAMESPACE_URI, USER, str(node_opcua.parent / "pki"),
                          out=tmp_path / "login.json", environment={"BWR_PASSWORD": PASSWORD})
    finally:
        status = server.stop()
    assert status == 0 and "Traceback" not in server.stderr, server.stderr

    basic256sha256 = "http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256"
    assert seen["tokens"] == [{"endpoint": basic256sha256, "token": basic256sha256}]
    assert seen["anonymous"] == {"userAccessLevel": 1, "userExecutable": False, "step": "BadUserAccessDenied"}
    assert seen["user"] == {"userAccessLevel": 3, "userExecutable": True, "step": "Good"}
