"""Feeds the dashboard's model from the ROS graph: the state, heartbeat and status topics of
each robot namespace, and the manager's query service (rules, bindings, twins) twice a second.

Everything here comes from the network, where any process may publish: the model bounds
what it keeps, and the page shows it as text, never as markup.
"""

from __future__ import annotations

import os
from typing import Any

from contextros_interfaces.msg import LayerState, ParticipantStatus
from rclpy.node import Node

from contextros.dashboard.model import DashboardModel
from contextros.ros.messages import registry_to_dict, report_from_msg, stamp_to_seconds
from contextros.ros.registry_polling import RegistryPoller
from contextros.ros.topics import (
    HEARTBEAT_QOS,
    HEARTBEAT_TOPIC,
    QUERY_SERVICE,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)

QUERY_PERIOD = 0.5


class DashboardNode(Node):
    def __init__(
        self, model: DashboardModel, namespaces: list[str], query_period: float = QUERY_PERIOD
    ) -> None:
        super().__init__(f"contextros_dashboard_{os.getpid()}")
        self.model = model
        self._pollers: list[RegistryPoller] = []
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
            self._pollers.append(
                RegistryPoller(
                    self, f"{base}/{QUERY_SERVICE}", self._answered(namespace), query_period
                )
            )

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

    def _answered(self, namespace: str) -> Any:
        def on_answer(answer: Any, asked: float) -> None:
            self.model.registry(namespace, registry_to_dict(answer))

        return on_answer
