"""A client command's answer, from a LayerClient: the same JSON (cli/daemon/wire.py)
whether the daemon asks the manager or the command does it itself."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from contextros.cli.daemon.wire import result_as_dict
from contextros.errors import LayerError
from contextros.identity import default_requester

if TYPE_CHECKING:
    from contextros.ros import LayerClient


def client_answer(client: LayerClient, request: dict[str, Any]) -> dict[str, Any]:
    """The answer to `request`, a "status" or "activate" request as the command line
    sends it to the daemon (checked by `wire.request_problem`)."""
    try:
        client.wait_for_manager(request["wait_manager"], commands=request["command"] != "status")
        if request["command"] == "status":
            from contextros.ros.messages import registry_to_dict

            return {"outcome": "registry", "registry": registry_to_dict(client.query())}
    except LayerError as error:
        return {"outcome": "no_manager", "message": str(error)}
    client.requester = request["requester"] or default_requester()
    try:
        result = client.request(
            request["on"],
            request["off"],
            synchronous=request["sync"],
            timeout=request["timeout"],
            reason=request["reason"],
            expect_nodes=request["expect"],
            expect_count=request["expect_count"],
            atomic=request["atomic"],
        )
    except LayerError as error:
        return {"outcome": "failed", "message": str(error)}
    return {"outcome": "result", "result": result_as_dict(result)}
