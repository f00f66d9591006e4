"""The activation client: what `contextros activate/status` and user programs call."""

from __future__ import annotations

import os
import time
from collections.abc import Iterable
from typing import Any

import rclpy
from contextros_interfaces.srv import Activate, QueryRegistry
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter

from contextros.identity import default_requester
from contextros.protocol import (
    ActivationCommand,
    ActivationFailed,
    ActivationResult,
    ManagerError,
)
from contextros.protocol.validation import command_problems
from contextros.ros.messages import command_to_request, result_from_response
from contextros.ros.topics import ACTIVATE_QOS, ACTIVATE_SERVICE, QUERY_QOS, QUERY_SERVICE

# A command's timeout is its deadline, counted from its arrival at the manager: the manager
# answers within it, or refuses a command it could not start by then (docs/protocol.md).
# The client gives up REPLY_MARGIN after the timeout (a command without one: after
# ASSUMED_DEFAULT_TIMEOUT, above the manager's default of 5 s), so a command is over within
# its timeout plus this margin, and the manager never starts one its caller gave up on.
REPLY_MARGIN = 2.0
ASSUMED_DEFAULT_TIMEOUT = 10.0
# A reply can be lost while the manager's reply writer has not yet matched a new client's
# reader (a known Fast DDS discovery race, ros2/rmw_fastrtps#842). An asynchronous command
# unanswered after RESEND_AFTER is sent again (at most ATTEMPTS in all), with the time
# left as its timeout, if that leaves the manager time to answer before the client gives
# up (else the client waits for the attempts sent); an answer to any attempt counts. A
# synchronous or atomic one is not (its answer may take until its timeout, and an aborted
# atomic vote must not be started again behind its caller's back).
RESEND_AFTER = 2.0
ATTEMPTS = 3
# Discovery: how often to look for the manager's services, how long to wait for a probe.
POLL = 0.01
PROBE = 0.2
PROBE_MAX = 1.6


class LayerClient:
    """Sends activation commands to the Layer manager from an existing node.

    `request`, `activate`, `deactivate` and `query` spin the node until the answer comes:
    call them from a main loop or another thread, not from one of the node's callbacks
    (there, use `request_async` and handle the future's result with `result_of`).

    One default everywhere, as on the command line: a command returns once the manager
    published the new state (`synchronous=False`); pass `synchronous=True` (the CLI's
    `--sync`) to return once every live node applied it. `request` returns the
    manager's answer, success or not; `activate` and `deactivate` raise
    `ActivationFailed` instead of returning a failed answer. See docs/client.md.
    """

    def __init__(
        self, node: Node, requester: str | None = None, executor: Executor | None = None
    ) -> None:
        self.node = node
        self.requester = requester or default_requester()
        # Spins use rclpy's global executor unless given one (a thread of its own needs one).
        self._executor = executor
        self._activate: Any = node.create_client(
            Activate, ACTIVATE_SERVICE, qos_profile=ACTIVATE_QOS
        )
        self._query: Any = node.create_client(QueryRegistry, QUERY_SERVICE, qos_profile=QUERY_QOS)

    def wait_for_manager(self, timeout: float = 5.0, *, commands: bool = True) -> None:
        """Return once the manager's services are discovered and answer this client (with
        `commands=False`, only its query service: enough for `query`).

        Polls every 10 ms (rclpy's own `wait_for_service` sleeps 0.25 s between looks),
        then asks the registry, again at growing intervals: a service can be discovered by
        the client before the manager has discovered the client's reply reader (Fast
        DDS, ros2/rmw_fastrtps#842), and a reply sent meanwhile is lost; a command sent
        after an answered query does not wait seconds for a lost reply.
        """
        deadline = time.monotonic() + timeout
        needed = [(self._activate, ACTIVATE_SERVICE)] if commands else []
        needed.append((self._query, QUERY_SERVICE))
        while missing := [name for client, name in needed if not client.service_is_ready()]:
            if time.monotonic() >= deadline or not self.node.context.ok():
                domain = os.environ.get("ROS_DOMAIN_ID", "0")
                service = self.node.resolve_service_name(missing[0])
                raise ManagerError(
                    f"no Layer manager answers on {service} (ROS_DOMAIN_ID={domain}) "
                    f"after {timeout:g} s; start one with `contextros manager` (in the same "
                    "namespace: `--ros-args -r __ns:=...`)"
                )
            time.sleep(POLL)
        # A probe is asked again, less and less often, and any probe's answer will do: on a
        # loaded machine an answer can take longer than the first wait (a probe dropped at
        # each wait would then never be answered in time).
        probes: list[Any] = []
        wait = PROBE
        try:
            while True:
                probes.append(self._query.call_async(QueryRegistry.Request()))
                if self._first_done(probes, min(time.monotonic() + wait, deadline)) is not None:
                    return
                if time.monotonic() >= deadline or not self.node.context.ok():
                    raise ManagerError(
                        "the Layer manager on "
                        f"{self.node.resolve_service_name(QUERY_SERVICE)} did not answer within "
                        f"{timeout:g} s"
                    )
                wait = min(2 * wait, PROBE_MAX)
        finally:
            for probe in probes:
                if not probe.done():
                    self._query.remove_pending_request(probe)

    def _first_done(self, futures: list[Any], until: float) -> Any | None:
        """Spin the node until one of `futures` is done (returned), or `until` (a
        monotonic time) passes or ROS shuts down (None). As rclpy's
        `spin_until_future_complete`, for any of several futures: the node is in the
        executor for the whole wait."""
        executor = self._executor or rclpy.get_global_executor()
        executor.add_node(self.node)
        try:
            while True:
                done = next((future for future in futures if future.done()), None)
                left = until - time.monotonic()
                if done is not None or left <= 0 or not self.node.context.ok():
                    return done
                executor.spin_once(timeout_sec=left)
        finally:
            executor.remove_node(self.node)

    @property
    def service_name(self) -> str:
        """The activation service's name as resolved in this node's namespace."""
        name: str = self.node.resolve_service_name(ACTIVATE_SERVICE)
        return name

    def request_async(
        self,
        activate: Iterable[str] = (),
        deactivate: Iterable[str] = (),
        *,
        synchronous: bool = False,
        timeout: float = 0.0,
        reason: str = "",
        expect_nodes: Iterable[str] = (),
        expect_count: int = 0,
        atomic: bool = False,
    ) -> Any:
        """Send one activation command; returns the rclpy Future of the service response.

        The command is checked here first (ActivationFailed names the field): rclpy cuts a
        string at a NUL byte, so 'Night\\x00evil' would reach the manager as 'Night'.
        """
        activate, deactivate, expect_nodes = tuple(activate), tuple(deactivate), tuple(expect_nodes)
        problems = command_problems(
            ActivationCommand(
                0,
                activate=activate,
                deactivate=deactivate,
                synchronous=synchronous,
                timeout=timeout,
                requester=self.requester,
                reason=reason,
                expect_nodes=expect_nodes,
                expect_count=expect_count,
                atomic=atomic,
            )
        )
        if problems:
            raise ActivationFailed(f"invalid command: {'; '.join(problems)}; nothing sent")
        request = command_to_request(
            activate,
            deactivate,
            synchronous,
            timeout,
            self.requester,
            reason,
            expect_nodes,
            expect_count,
            atomic,
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
        expect_nodes: Iterable[str] = (),
        expect_count: int = 0,
        atomic: bool = False,
    ) -> ActivationResult:
        """Send one activation command and wait (spinning the node) for the manager's answer.

        A synchronous command succeeds once every live participant applied the new state;
        `expect_nodes` and `expect_count` add what the requester knows must be reached
        (nodes the manager may have dropped, a number of nodes), and a command that
        reached no node at all never succeeds. `atomic=True`: every live participant
        votes first, and either all switch to the new epoch or none does (the answer names
        who vetoed and why). `timeout` bounds the whole command (for an atomic one, vote and
        acknowledgements): the manager answers within it, counted from the command's
        arrival, and this call raises `ManagerError` if no answer came `REPLY_MARGIN` (2 s)
        later (without a timeout: 10 s + 2 s).
        """
        activate, deactivate, expect_nodes = tuple(activate), tuple(deactivate), tuple(expect_nodes)
        started = time.monotonic()
        give_up = started + (timeout if timeout > 0 else ASSUMED_DEFAULT_TIMEOUT) + REPLY_MARGIN
        resend = not (synchronous or atomic)
        sent_timeout = timeout
        attempts: list[Any] = []  # an answer to any of them will do
        try:
            for attempt in range(1, ATTEMPTS + 1):
                attempts.append(
                    self.request_async(
                        activate,
                        deactivate,
                        synchronous=synchronous,
                        timeout=sent_timeout,
                        reason=reason,
                        expect_nodes=expect_nodes,
                        expect_count=expect_count,
                        atomic=atomic,
                    )
                )
                last = not resend or attempt == ATTEMPTS
                until = give_up if last else min(give_up, time.monotonic() + RESEND_AFTER)
                answered = self._first_done(attempts, until)
                # A command sent again must end before this client gives up, as the first:
                # where none would (a short timeout), those sent are waited for until then.
                sent_timeout = give_up - time.monotonic() - REPLY_MARGIN
                if answered is None and not last and sent_timeout <= 0:
                    answered, last = self._first_done(attempts, give_up), True
                if answered is not None:
                    return result_from_response(answered.result())
                if last or not self.node.context.ok():
                    break
        finally:
            for future in attempts:
                if not future.done():
                    self._activate.remove_pending_request(future)
        raise ManagerError(
            f"the Layer manager did not answer within {time.monotonic() - started:.1f} s; "
            "whether the command was carried out is unknown (see `contextros status`)"
        )

    def activate(
        self,
        *layers: str,
        synchronous: bool = False,
        timeout: float = 0.0,
        expect_nodes: Iterable[str] = (),
        expect_count: int = 0,
        atomic: bool = False,
    ) -> ActivationResult:
        """Activate `layers`; raise ActivationFailed with the manager's message on failure."""
        return _checked(
            self.request(
                layers,
                synchronous=synchronous,
                timeout=timeout,
                expect_nodes=expect_nodes,
                expect_count=expect_count,
                atomic=atomic,
            )
        )

    def deactivate(
        self,
        *layers: str,
        synchronous: bool = False,
        timeout: float = 0.0,
        expect_nodes: Iterable[str] = (),
        expect_count: int = 0,
        atomic: bool = False,
    ) -> ActivationResult:
        """Deactivate `layers`; raise ActivationFailed with the manager's message on failure."""
        return _checked(
            self.request(
                (),
                layers,
                synchronous=synchronous,
                timeout=timeout,
                expect_nodes=expect_nodes,
                expect_count=expect_count,
                atomic=atomic,
            )
        )

    def query(self, timeout: float = 5.0) -> Any:
        """The manager's registry (`QueryRegistry` response); asks again if a reply is lost."""
        for _ in range(ATTEMPTS):
            future = self._query.call_async(QueryRegistry.Request())
            rclpy.spin_until_future_complete(
                self.node, future, executor=self._executor, timeout_sec=timeout / ATTEMPTS
            )
            if future.done():
                return future.result()
            self._query.remove_pending_request(future)
        raise ManagerError(f"the Layer manager did not answer a query within {timeout:g} s")


def quiet_node(name: str, namespace: str | None = None) -> Node:
    """A node with nothing to serve, for a client: no parameter or type description
    services, no /rosout (fewer endpoints to create, and for the manager to discover)."""
    return Node(
        name,
        namespace=namespace,
        start_parameter_services=False,
        enable_rosout=False,
        parameter_overrides=[Parameter("start_type_description_service", value=False)],
    )


def _checked(result: ActivationResult) -> ActivationResult:
    if not result.success:
        raise ActivationFailed(result.message, result.not_acknowledged)
    return result
