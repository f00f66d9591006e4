"""The activation client: what `contextros activate/status` and user programs call."""

from __future__ import annotations

import getpass
import os
from collections.abc import Iterable
from typing import Any

import rclpy
from contextros_interfaces.srv import Activate, QueryRegistry
from rclpy.node import Node

from contextros.protocol import ActivationFailed, ActivationResult, ManagerError
from contextros.ros.messages import command_to_request, result_from_response
from contextros.ros.topics import ACTIVATE_SERVICE, QUERY_SERVICE

# How long to wait for an answer beyond the activation's own timeout, and how often to ask.
# A reply can be lost while the manager's reply writer has not yet matched a new client's
# reader (a known Fast DDS discovery race, ros2/rmw_fastrtps#842); commands describe a
# target configuration, so asking again is safe: a repeated command changes nothing more.
REPLY_MARGIN = 2.0
ATTEMPTS = 3
# A synchronous command without a timeout waits the manager's default (5 s unless set).
ASSUMED_DEFAULT_TIMEOUT = 10.0


def default_requester() -> str:
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "unknown"
    return f"{user}@pid{os.getpid()}"


class LayerClient:
    """Sends activation commands to the Layer manager from an existing node.

    `request`, `activate`, `deactivate` and `query` spin the node until the answer comes:
    call them from a main loop or another thread, not from one of the node's callbacks
    (there, use `request_async` and handle the future's result with `result_of`).
    """

    def __init__(self, node: Node, requester: str | None = None) -> None:
        self.node = node
        self.requester = requester or default_requester()
        self._activate: Any = node.create_client(Activate, ACTIVATE_SERVICE)
        self._query: Any = node.create_client(QueryRegistry, QUERY_SERVICE)

    def wait_for_manager(self, timeout: float = 5.0) -> None:
        if not self._activate.wait_for_service(timeout_sec=timeout):
            domain = os.environ.get("ROS_DOMAIN_ID", "0")
            raise ManagerError(
                f"no Layer manager answers on {ACTIVATE_SERVICE} (ROS_DOMAIN_ID={domain}) "
                f"after {timeout:g} s; start one with `contextros manager`"
            )

    def request_async(
        self,
        activate: Iterable[str] = (),
        deactivate: Iterable[str] = (),
        *,
        synchronous: bool = False,
        timeout: float = 0.0,
        reason: str = "",
    ) -> Any:
        """Send one activation command; returns the rclpy Future of the service response."""
        request = command_to_request(
            activate, deactivate, synchronous, timeout, self.requester, reason
        )
        return self._activate.call_async(request)

    @staticmethod
    def result_of(future: Any) -> ActivationResult:
        """The manager's answer carried by a completed `request_async` future."""
        return result_from_response(future.result())

    def request(
        self,
        activate: Iterable[str] = (),
        deactivate: Iterable[str] = (),
        *,
        synchronous: bool = False,
        timeout: float = 0.0,
        reason: str = "",
    ) -> ActivationResult:
        """Send one activation command and wait (spinning the node) for the manager's answer."""
        if synchronous:
            wait = (timeout if timeout > 0 else ASSUMED_DEFAULT_TIMEOUT) + REPLY_MARGIN
        else:
            wait = REPLY_MARGIN
        for _ in range(ATTEMPTS):
            future = self.request_async(
                activate, deactivate, synchronous=synchronous, timeout=timeout, reason=reason
            )
            rclpy.spin_until_future_complete(self.node, future, timeout_sec=wait)
            if future.done():
                return result_from_response(future.result())
            self._activate.remove_pending_request(future)
        raise ManagerError(
            f"the Layer manager did not answer {ATTEMPTS} attempts of {wait:g} s each"
        )

    def activate(
        self, *layers: str, synchronous: bool = True, timeout: float = 0.0
    ) -> ActivationResult:
        """Activate `layers`; raise ActivationFailed with the manager's message on failure."""
        return _checked(self.request(layers, synchronous=synchronous, timeout=timeout))

    def deactivate(
        self, *layers: str, synchronous: bool = True, timeout: float = 0.0
    ) -> ActivationResult:
        return _checked(self.request((), layers, synchronous=synchronous, timeout=timeout))

    def query(self, timeout: float = 5.0) -> Any:
        """The manager's registry (`QueryRegistry` response); asks again if a reply is lost."""
        for _ in range(ATTEMPTS):
            future = self._query.call_async(QueryRegistry.Request())
            rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout / ATTEMPTS)
            if future.done():
                return future.result()
            self._query.remove_pending_request(future)
        raise ManagerError(f"the Layer manager did not answer a query within {timeout:g} s")


def _checked(result: ActivationResult) -> ActivationResult:
    if not result.success:
        raise ActivationFailed(result.message, result.not_acknowledged)
    return result
