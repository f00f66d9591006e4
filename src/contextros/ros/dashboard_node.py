"""Feeds the dashboard's model from the ROS graph: the state, heartbeat and status topics of
each robot namespace, and the manager's query service (rules, bindings, twins) twice a second.

Everything here comes from the network, where any process may publish: the model bounds
what it keeps, and the page shows it as text, never as markup.
"""

from __future__ import annotations

import os
import time
from typing import Any

from contextros_interfaces.msg import LayerState, ParticipantStatus
from contextros_interfaces.srv import QueryRegistry
from rclpy.node import Node

from contextros.dashboard.model import DashboardModel
from contextros.ros.messages import registry_to_dict, report_from_msg, stamp_to_seconds
from contextros.ros.topics import (
    HEARTBEAT_QOS,
    HEARTBEAT_TOPIC,
    QUERY_QOS,
    QUERY_SERVICE,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)

QUERY_PERIOD = 0.5
QUERY_TIMEOUT = 5.0  # an answer not back by then is given up


class DashboardNode(Node):
    def __init__(
        self, model: DashboardModel, namespaces: list[str], query_period: float = QUERY_PERIOD
    ) -> None:
        super().__init__(f"contextros_dashboard_{os.getpid()}")
        self.model = model
        self._queries: dict[str, tuple[Any, list[Any]]] = {}
        for namespace in namespaces:
            base = namespace.rstrip("/")
            self.create_subscription(
                LayerState, f"{base}/{STATE_TOPIC}", self._state(namespace, False), STATE_QOS
            )
            self.create_subscription(
                LayerState, f"{base}/{HEARTBEAT_TOPIC}", self._state(namespace, True), HEARTBEAT_QOS
            )
            self.create_subscription(
                ParticipantStatus, f"{base}/{STATUS_TOPIC}", self._status(namespace), STATUS_QOS
            )
            client: Any = self.create_client(
                QueryRegistry, f"{base}/{QUERY_SERVICE}", qos_profile=QUERY_QOS
            )
            self._queries[namespace] = (client, [])
        self.create_timer(query_period, self._query)

    def _state(self, namespace: str, heartbeat: bool) -> Any:
        def on_state(msg: Any) -> None:
            self.model.state(
                namespace,
                msg.epoch,
                msg.active_layers,
                msg.requester,
                msg.reason,
                stamp_to_seconds(msg.stamp),
                msg.manager_id,
                heartbeat=heartbeat,
            )

        return on_state

    def _status(self, namespace: str) -> Any:
        def on_status(msg: Any) -> None:
            try:
                report = report_from_msg(msg)
            except (AttributeError, TypeError, ValueError):  # a foreign sender: not shown
                return
            self.model.status(
                namespace, report, language=msg.language, stamp=stamp_to_seconds(msg.stamp)
            )

        return on_status

    def _query(self) -> None:
        now = time.monotonic()
        for namespace, (client, pending) in self._queries.items():
            if pending:
                future, sent = pending[0]
                if now - sent < QUERY_TIMEOUT:
                    continue
                client.remove_pending_request(future)  # the manager went away meanwhile
                pending.clear()
            if not client.service_is_ready():
                continue
            future = client.call_async(QueryRegistry.Request())
            pending.append((future, now))
            future.add_done_callback(lambda f, ns=namespace: self._answered(ns, f))

    def _answered(self, namespace: str, future: Any) -> None:
        self._queries[namespace][1].clear()
        response = future.result()
        if response is not None:
            self.model.registry(namespace, registry_to_dict(response))
