"""Asking a manager's registry (its query service) now and then, one question at a time:
the dashboard and `contextros watch` poll it."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from contextros_interfaces.srv import QueryRegistry
from rclpy.node import Node

from contextros.ros.topics import QUERY_QOS

QUERY_TIMEOUT = 5.0  # an answer not back by then is given up


class RegistryPoller:
    """Calls `on_answer(answer, asked)` with each QueryRegistry answer of the service at
    `service` (`asked`: time.monotonic() when it was sent), asking every `period` seconds
    once the previous question was answered or given up."""

    def __init__(
        self,
        node: Node,
        service: str,
        on_answer: Callable[[Any, float], object],
        period: float,
    ) -> None:
        self._client: Any = node.create_client(QueryRegistry, service, qos_profile=QUERY_QOS)
        self._on_answer = on_answer
        self._pending: tuple[Any, float] | None = None
        self.timer = node.create_timer(period, self.ask)

    def ask(self) -> None:
        now = time.monotonic()
        if self._pending is not None:
            future, sent = self._pending
            if now - sent < QUERY_TIMEOUT:
                return
            self._client.remove_pending_request(future)  # the manager went away meanwhile
            self._pending = None
        if not self._client.service_is_ready():
            return
        future = self._client.call_async(QueryRegistry.Request())
        self._pending = (future, now)
        future.add_done_callback(lambda f, asked=now: self._answered(f, asked))

    def _answered(self, future: Any, asked: float) -> None:
        self._pending = None
        response = future.result()
        if response is not None:
            self._on_answer(response, asked)
