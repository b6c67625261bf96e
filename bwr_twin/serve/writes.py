"""A Write of several nodes answered node by node, as OPC UA Part 4 says (5.10.4): each node's own
status code, each applied or not on its own. asyncua lets a value setter's refusal (a
non-finite setpoint: BadOutOfRange; a tripped watchdog: BadInvalidState) end the whole request
as a service fault, after the nodes before it were applied; here each node is written as a
request of its own, and a refusal is that node's result.
"""

from __future__ import annotations

from asyncua import Server, ua


def write_each_node(server: Server) -> None:
    """Make the Write service of `server` answer, and apply, node by node."""
    service = server.iserver.attribute_service
    write_one_request = service.write

    async def write(params: ua.WriteParameters, **session) -> list[ua.StatusCode]:
        results = []
        for item in params.NodesToWrite:
            try:
                (result,) = await write_one_request(ua.WriteParameters(NodesToWrite=[item]), **session)
            except ua.UaStatusCodeError as refusal:  # a value setter's: this node is left as it was
                result = ua.StatusCode(refusal.code)
            results.append(result)
        return results

    service.write = write
