"""OPC UA's services as Parts 4 and 9 say the twin's server must answer them, seen by a real
asyncua client (docs/opcua.md): method calls' status codes, Write node by node, UserAccessLevel
and UserExecutable per session, Start on a tripped clock, the path's last period,
ConditionRefresh, and the UserName token encrypted on the secured endpoint."""

from __future__ import annotations

import asyncio
import signal
import time

import pytest
from asyncua import ua
from test_serve import (
    LIMIT_PERIODS,
    LUFF_PUSH,
    PASSWORD,
    USER,
    AlarmEvents,
    Launched,
    Plc,
    certificate_pair,
    client,
    run,
)

from bwr_twin.serve.security import hash_password

OUT_OF_RANGE, TYPE_MISMATCH, GOOD = ua.StatusCodes.BadOutOfRange, ua.StatusCodes.BadTypeMismatch, ua.StatusCodes.Good


@pytest.fixture(scope="module")
def short_scene(tmp_path_factory):
    from conftest import write_short_scene

    return write_short_scene(tmp_path_factory.mktemp("services"))


@pytest.fixture(scope="module")
def secured(tmp_path_factory):
    folder = tmp_path_factory.mktemp("secured")
    users = folder / "users.txt"
    users.write_text(f"{USER}:{hash_password(PASSWORD)}\n")
    server_cert, server_key = certificate_pair(folder, "server")
    client_cert, client_key = certificate_pair(folder, "client", uri="urn:freeopcua:client")
    return {"users": users, "cert": server_cert, "key": server_key,
            "security": f"Basic256Sha256,SignAndEncrypt,{client_cert},{client_key}"}


@pytest.fixture(scope="module")
def servers(short_scene, secured):
    """A lockstep server open on loopback, and a real-time one with users on a secured endpoint
    (a watchdog of 5 periods), started together."""
    launched = {
        "lockstep": Launched(short_scene),
        "secured": Launched(short_scene, "--realtime", "--watchdog-periods", "5", "--users", str(secured["users"]),
                            "--certificate", str(secured["cert"]), "--private-key", str(secured["key"]),
                            stop_signal=signal.SIGTERM),
    }
    try:
        yield launched
    finally:
        for server in launched.values():
            assert server.stop() == 0 and "Traceback" not in server.stderr, server.stderr


async def call(plc: Plc, method: str, *arguments: ua.Variant, on=None) -> ua.CallMethodResult:
    """One CallMethodRequest as sent, its result as received (no exception for a Bad code)."""
    request = ua.CallMethodRequest(ObjectId=(on or plc.reclaimer).nodeid, MethodId=plc.methods[method].nodeid,
                                   InputArguments=list(arguments))
    (result,) = await plc.client.uaclient.call([request])
    return result


def codes(result: ua.CallMethodResult) -> tuple[int, list[int]]:
    return result.StatusCode.value, [code.value for code in result.InputArgumentResults]


def test_method_calls_get_part_4s_status_codes_and_change_nothing_when_refused(servers):
    uint32, double = ua.VariantType.UInt32, ua.VariantType.Double

    async def session():
        async with client(servers["lockstep"].ready()) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            travel = plc.axis["EncoderPosition"][0].nodeid.Identifier.rsplit(".", 1)[0]
            answers = {
                "none": await call(plc, "Step"),
                "two": await call(plc, "Step", ua.Variant(1, uint32), ua.Variant(1, uint32)),
                "a Double": await call(plc, "Step", ua.Variant(1.0, double)),
                "zero": await call(plc, "Step", ua.Variant(0, uint32)),
                "on Travel": await call(plc, "Step", ua.Variant(1, uint32),
                                        on=connection.get_node(ua.NodeId(travel, plc.ns))),
                "Reset with one": await call(plc, "Reset", ua.Variant(1, uint32)),
            }
            sim_time = await plc.value("SimTime")
            good = await call(plc, "Step", ua.Variant(2, uint32))
            return answers, sim_time, good

    answers, sim_time, good = run(session())
    assert codes(answers["none"]) == (ua.StatusCodes.BadArgumentsMissing, [])
    assert codes(answers["two"])[0] == ua.StatusCodes.BadTooManyArguments
    assert codes(answers["a Double"]) == (ua.StatusCodes.BadInvalidArgument, [TYPE_MISMATCH])
    assert codes(answers["zero"]) == (ua.StatusCodes.BadInvalidArgument, [OUT_OF_RANGE])
    assert codes(answers["on Travel"])[0] == ua.StatusCodes.BadMethodInvalid
    assert codes(answers["Reset with one"])[0] == ua.StatusCodes.BadTooManyArguments
    assert sim_time == 0.0  # none of them stepped
    assert codes(good) == (GOOD, [GOOD]) and good.OutputArguments[0].Value == pytest.approx(0.02)


def test_a_write_of_several_nodes_answers_and_applies_each_on_its_own(servers):
    async def session():
        async with client(servers["lockstep"].ready()) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            setpoints = plc.axis["DriveSetpoint"]
            # travel good, slew NaN, luff an integer, then a node that is not writable
            nodes = [*setpoints, plc.axis["EncoderPosition"][0]]
            values = [ua.Variant(1.0, ua.VariantType.Double), ua.Variant(float("nan"), ua.VariantType.Double),
                      ua.Variant(3, ua.VariantType.Int64), ua.Variant(5.0, ua.VariantType.Double)]
            items = [ua.WriteValue(NodeId=n.nodeid, AttributeId=ua.AttributeIds.Value, Value=ua.DataValue(v))
                     for n, v in zip(nodes, values)]
            results = await connection.uaclient.write(ua.WriteParameters(NodesToWrite=items))
            return [r.value for r in results], (await plc.read("DriveSetpoint"))[0].tolist()

    results, setpoints = run(session())
    assert results == [GOOD, OUT_OF_RANGE, TYPE_MISMATCH, ua.StatusCodes.BadUserAccessDenied]
    assert setpoints == [1.0, 0.0, 0.0]  # the good one applied, the refused ones left at zero


def test_the_last_period_brings_sim_time_to_the_paths_end(servers):
    server = servers["lockstep"]
    url = server.ready()

    async def session():
        async with client(url) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            periods = await plc.value("PeriodsLeft")
            await plc.step(periods - 1)
            before = await plc.value("PeriodsLeft"), await plc.value("SimTime")
            stepped_to = await plc.step(1)
            after = await plc.value("PeriodsLeft"), await plc.value("SimTime")
            with pytest.raises(ua.uaerrors.BadInvalidState):
                await plc.step(1)
            return periods, before, stepped_to, after

    periods, before, stepped_to, after = run(session())
    assert periods == 2000  # 20 s of 10 ms periods
    assert before == (1, pytest.approx(19.99))
    assert stepped_to == pytest.approx(20.0) and after == (0, pytest.approx(20.0))
    assert any(line.endswith("2000 control periods of 10 ms (20 s path)") for line in server.lines), server.lines
    server.wait_for("path completed: its last control period, at SimTime 20 s", 10.0)


def test_condition_refresh_sends_the_active_alarm_again_between_start_and_end(servers):
    async def session():
        async with client(servers["lockstep"].ready()) as connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            await plc.set_drives(LUFF_PUSH)
            await plc.step(LIMIT_PERIODS)  # the luff at its limit: an active alarm, before anyone subscribed
            events = AlarmEvents()
            subscription = await connection.create_subscription(20, events)
            await subscription.subscribe_events(connection.nodes.server, ua.ObjectIds.OffNormalAlarmType)
            condition_type = connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType))
            refresh = connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh))
            await condition_type.call_method(refresh, ua.Variant(subscription.subscription_id, ua.VariantType.UInt32))
            received = [await events.next()]
            while received[-1]["EventType"] != ua.NodeId(ua.ObjectIds.RefreshEndEventType):
                received.append(await events.next())
            with pytest.raises(ua.uaerrors.BadSubscriptionIdInvalid):
                await condition_type.call_method(refresh, ua.Variant(999999, ua.VariantType.UInt32))
            await plc.call("Reset")
            return received, plc.ns

    received, ns = run(session())
    types = [event["EventType"] for event in received]
    assert types == [ua.NodeId(ua.ObjectIds.RefreshStartEventType), ua.NodeId(ua.ObjectIds.OffNormalAlarmType),
                     ua.NodeId(ua.ObjectIds.RefreshEndEventType)]
    alarm = received[1]
    assert alarm["SourceNode"] == ua.NodeId("Reclaimer.Luff", ns) and alarm["Retain"] is True
    assert alarm["Message"].Text.startswith("Luff: limit switch closed")


def test_an_anonymous_session_reads_what_it_may_do_and_users_log_in_encrypted(servers, secured):
    server = servers["secured"]
    url = server.ready()

    async def rights(password):
        connection = client(url, password)
        await connection.set_security_string(secured["security"])
        async with connection:
            plc = await Plc.attach(connection)
            setpoint, step = plc.axis["DriveSetpoint"][0], plc.methods["Step"]
            found = (await setpoint.read_attribute(ua.AttributeIds.UserAccessLevel)).Value.Value, (
                await step.read_attribute(ua.AttributeIds.UserExecutable)).Value.Value
            endpoints = await connection.get_endpoints()
            # ConditionRefresh is anyone's: a SCADA that only watches asks for the active alarms again.
            refresh = connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType_ConditionRefresh))
            events = AlarmEvents()
            subscription = await connection.create_subscription(20, events)
            await subscription.subscribe_events(connection.nodes.server, ua.ObjectIds.OffNormalAlarmType)
            await connection.get_node(ua.NodeId(ua.ObjectIds.ConditionType)).call_method(
                refresh, ua.Variant(subscription.subscription_id, ua.VariantType.UInt32))
            bracket = [(await events.next())["EventType"], (await events.next())["EventType"]]
            refreshes = (await refresh.read_attribute(ua.AttributeIds.UserExecutable)).Value.Value, bracket
            return (*found, refreshes), endpoints

    async def sessions():
        anonymous, endpoints = await rights(None)
        user, _ = await rights(PASSWORD)
        return anonymous, user, endpoints

    anonymous, user, endpoints = run(sessions())
    read, write = ua.AccessLevel.CurrentRead.mask, ua.AccessLevel.CurrentWrite.mask
    bracket = [ua.NodeId(ua.ObjectIds.RefreshStartEventType), ua.NodeId(ua.ObjectIds.RefreshEndEventType)]
    assert anonymous == (read, False, (True, bracket)) and user == (read | write, True, (True, bracket))
    tokens = [(e.SecurityPolicyUri, t.SecurityPolicyUri) for e in endpoints for t in e.UserIdentityTokens
              if t.TokenType == ua.UserTokenType.UserName]
    assert tokens == [("http://opcfoundation.org/UA/SecurityPolicy#Basic256Sha256",) * 2]


def test_start_on_a_tripped_running_clock_is_refused(servers, secured):
    async def session():
        connection = client(servers["secured"].ready(), PASSWORD)
        await connection.set_security_string(secured["security"])
        async with connection:
            plc = await Plc.attach(connection)
            await plc.call("Reset")
            await plc.call("Start")
            deadline = time.monotonic() + 20.0  # s: a busy machine's; no setpoint written, it trips after 5 periods
            while not await plc.value("WatchdogTripped") and time.monotonic() < deadline:
                await asyncio.sleep(0.02)
            running = await plc.value("Running"), await plc.value("WatchdogTripped")
            with pytest.raises(ua.uaerrors.BadInvalidState):
                await plc.call("Start")
            await plc.call("Reset")
            await plc.call("Start")  # after Reset, Start is good again
            await plc.call("Stop")
            return running

    assert run(session()) == (True, True)
