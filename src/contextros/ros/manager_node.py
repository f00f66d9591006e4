"""The Layer manager node: the thin rclpy adapter around `ManagerProtocol`.

All protocol work happens in this node's executor callbacks (status subscription, service
requests, a tick timer), so the protocol needs no locks. A synchronous activation is
answered later, from whichever callback completes it, without blocking the executor: the
service's response is held back and sent with the request's header once the protocol
replies (see `_DeferredResponses`).
"""

from __future__ import annotations

import dataclasses
import os
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from contextros_interfaces.msg import LayerState as LayerStateMsg
from contextros_interfaces.msg import ParticipantStatus
from contextros_interfaces.srv import Activate, QueryRegistry
from rclpy.node import Node

from contextros.protocol import (
    LayerState,
    ManagerAction,
    ManagerProtocol,
    ManagerSettings,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    PublishState,
    Reply,
)
from contextros.ros.messages import (
    command_from_request,
    fill_query_response,
    fill_response,
    report_from_msg,
    state_to_msg,
)
from contextros.ros.topics import (
    ACTIVATE_SERVICE,
    MANAGER_NODE_NAME,
    QUERY_SERVICE,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)


class StateFile:
    """The manager's memory across restarts: the last published state, written atomically
    before it is published, so no epoch is ever handed out twice."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def load(self) -> LayerState | None:
        if not self.path.exists():
            return None
        return LayerState.from_json(self.path.read_text(encoding="utf-8"), str(self.path))

    def save(self, state: LayerState) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        with partial.open("w", encoding="utf-8") as stream:
            stream.write(state.to_json(wall_time=time.time()))
            stream.flush()
            os.fsync(stream.fileno())
        partial.replace(self.path)


class _DeferredResponses:
    """Lets a service callback return before its answer is known.

    rclpy's executor sends whatever the callback returns via `Service.send_response`; the
    wrapper below holds back responses still awaited and remembers their request headers,
    and `answer` sends them later. (An `async` callback would work too, but rclpy's
    executor re-polls a pending coroutine on every wake-up, which costs a core while a
    synchronous activation waits for its timeout.)
    """

    def __init__(self, service: Any, log_lost_reply: Callable[[Exception], object]) -> None:
        self._service = service
        self._log_lost_reply = log_lost_reply
        self._send = service.send_response
        self._open: dict[int, Any] = {}  # request id -> response object
        self._headers: dict[int, Any] = {}
        self._ids: dict[int, int] = {}  # id(response) -> request id
        service.send_response = self._send_or_hold

    def expect(self, request_id: int, response: Any) -> None:
        self._open[request_id] = response
        self._ids[id(response)] = request_id

    def answer(self, request_id: int, result: Any) -> None:
        response = self._open.pop(request_id, None)
        if response is None:
            return
        fill_response(response, result)
        del self._ids[id(response)]
        header = self._headers.pop(request_id, None)
        if header is not None:  # else the executor has not sent it yet: it will, filled in
            self._send_safely(response, header)

    def _send_or_hold(self, response: Any, header: Any) -> None:
        request_id = self._ids.get(id(response))
        if request_id is None:
            self._send_safely(response, header)
        else:
            self._headers[request_id] = header

    def _send_safely(self, response: Any, header: Any) -> None:
        # A client that vanished, or one not fully discovered yet, must not stop the manager;
        # clients ask again when a reply does not come (see LayerClient).
        try:
            self._send(response, header)
        except Exception as error:  # rclpy raises its RCLError, not exported as a type
            self._log_lost_reply(error)


class LayerManagerNode(Node):
    """The Layer manager: registry, activation command, state broadcast, liveness."""

    def __init__(
        self,
        *,
        settings: ManagerSettings | None = None,
        state_file: Path | None = None,
        node_name: str = MANAGER_NODE_NAME,
        tick_period: float = 0.05,
        **node_options: Any,
    ) -> None:
        super().__init__(node_name, **node_options)
        self.manager_id = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self.settings = dataclasses.replace(
            settings or ManagerSettings(), manager_id=self.manager_id
        )
        self.state_file = StateFile(state_file) if state_file else None
        saved = self.state_file.load() if self.state_file else None
        self.protocol = ManagerProtocol(time.monotonic(), self.settings, saved)
        self._next_request_id = 0
        # Log lines of the activation path wait until its reply is sent (or the next tick):
        # an rclpy log call costs ~0.3 ms, longer than a whole topic round trip.
        self._postponed_logs: list[str] = []
        self._state_pub = self.create_publisher(LayerStateMsg, STATE_TOPIC, STATE_QOS)
        self.create_subscription(ParticipantStatus, STATUS_TOPIC, self._on_status, STATUS_QOS)
        activate = self.create_service(Activate, ACTIVATE_SERVICE, self._on_activate)
        self._responses = _DeferredResponses(
            activate, lambda error: self.get_logger().warning(f"a reply was lost: {error}")
        )
        self.create_service(QueryRegistry, QUERY_SERVICE, self._on_query)
        self.create_timer(tick_period, self._on_tick)
        origin = f"state file {state_file} (epoch {saved.epoch})" if saved else "participants"
        self.get_logger().info(f"Layer manager {self.manager_id} recovering from {origin}")

    # -- executor callbacks -----------------------------------------------------------------

    def _on_status(self, msg: Any) -> None:
        try:
            report = report_from_msg(msg)
        except (AttributeError, TypeError, ValueError) as error:  # a foreign or broken sender
            self.get_logger().error(f"ignored an unreadable status message: {error}")
            return
        self._run(self.protocol.receive_status(report, time.monotonic()))

    def _on_tick(self) -> None:
        self._run(self.protocol.tick(time.monotonic()))
        self._flush_logs()

    def _flush_logs(self) -> None:
        logs, self._postponed_logs = self._postponed_logs, []
        for line in logs:
            self.get_logger().info(line)

    def _on_activate(self, request: Any, response: Any) -> Any:
        self._next_request_id += 1
        request_id = self._next_request_id
        self._responses.expect(request_id, response)
        command = command_from_request(request_id, request)
        self._run(self.protocol.receive_command(command, time.monotonic()))
        return response

    def _on_query(self, request: Any, response: Any) -> Any:
        del request
        view = self.protocol.registry(time.monotonic())
        return fill_query_response(response, view, self.manager_id)

    # -- actions ----------------------------------------------------------------------------

    def _save(self, state: LayerState) -> None:
        assert self.state_file is not None
        try:
            self.state_file.save(state)
        except OSError as error:
            # Keep switching: the participants still carry the epoch across a restart.
            self.get_logger().error(
                f"state file {self.state_file.path} not written for epoch {state.epoch}: {error}"
            )

    def _run(self, actions: list[ManagerAction]) -> None:
        for action in actions:
            if isinstance(action, PublishState):
                if self.state_file:
                    self._save(action.state)
                self._state_pub.publish(state_to_msg(action.state, time.time()))
                self._postponed_logs.append(
                    f"epoch {action.state.epoch}: [{', '.join(action.state.active)}] "
                    f"({action.state.requester or '?'}: {action.state.reason or '-'})"
                )
            elif isinstance(action, Reply):
                self._responses.answer(action.request_id, action.result)
                self._flush_logs()
            elif isinstance(action, ParticipantJoined):
                verb = "restarted" if action.restarted else "joined"
                self.get_logger().info(f"participant {action.node} {verb}")
            elif isinstance(action, ParticipantDropped):
                self.get_logger().warning(f"participant {action.node} dropped: {action.reason}")
            elif isinstance(action, ParticipantConflict):
                self.get_logger().error(
                    f"two live nodes are named {action.node}: their acknowledgements cannot be "
                    "told apart; give each context node a unique name (or namespace)"
                )
