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
import threading
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from contextros_interfaces.msg import LayerState as LayerStateMsg
from contextros_interfaces.msg import ParticipantStatus
from contextros_interfaces.srv import Activate, QueryRegistry
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node

from contextros.bindings import Bindings
from contextros.protocol import (
    ActivationCommand,
    ActivationResult,
    LayerState,
    ManagerAction,
    ManagerMemory,
    ManagerProtocol,
    ManagerSettings,
    ParticipantConflict,
    ParticipantDropped,
    ParticipantJoined,
    PublishHeartbeat,
    PublishProposal,
    PublishState,
    Reply,
    ReportRejected,
)
from contextros.protocol.events import DURABLE
from contextros.ros.durable_file import partial_path, write_durably
from contextros.ros.messages import (
    command_from_request,
    fill_query_response,
    fill_response,
    state_to_msg,
)
from contextros.ros.node_log import NodeLog
from contextros.ros.status_wire import StatusDecoder
from contextros.rules import Firing, RuleSet

if TYPE_CHECKING:
    from contextros.ros.binding_watch import BindingWatch, WatchJob
    from contextros.ros.bindings import BindingDriver, Deadline
    from contextros.ros.graph_observer import GraphObserver
    from contextros.ros.rules import RuleRunner
from contextros.ros.topics import (
    ACTIVATE_QOS,
    ACTIVATE_SERVICE,
    HEARTBEAT_QOS,
    HEARTBEAT_TOPIC,
    MANAGER_NODE_NAME,
    PROPOSAL_QOS,
    PROPOSAL_TOPIC,
    QUERY_QOS,
    QUERY_SERVICE,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)

# Statuses handled per executor wake-up at most (the service and the timer get their turn).
STATUS_BATCH = 256
# While a synchronous activation waits for more acknowledgements, the manager pauses this
# long after handling statuses: the ones arriving meanwhile are taken in one wake-up, not
# one each (a wake-up costs more than a status; issue 26).
STATUS_LINGER = 0.0005
# After a reconcile failed: its first retry, doubling up to the maximum (seconds).
RECONCILE_RETRY = 1.0
RECONCILE_RETRY_MAX = 30.0
# How often the graph observer looks for bound or ruled nodes that appeared, left or restarted.
GRAPH_PERIOD = 0.5


# What a command waited for when the adapter refuses it at its deadline.
BEHIND_A_DRIVE = "behind the parameters and lifecycle states of the command before it"
# A tick this much later than due means the manager's process did not run meanwhile.
STALL = 0.5


class StateFile:
    """The manager's memory across restarts (`ManagerMemory`: the last published state,
    the highest epoch proposed, the participants known), written atomically (a new file
    renamed over the old one, fsynced) before what changed it goes on the wire, so no
    epoch is ever handed out twice."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def load(self) -> ManagerMemory | None:
        return ManagerMemory.read(self.path)

    def check_writable(self) -> None:
        """Raise OSError (naming the file and the reason) unless the file can be written:
        its directory exists (it is not created: a mistyped path must not be) and takes
        a new file."""
        partial = self._partial()
        partial.open("w", encoding="utf-8").close()
        partial.unlink()

    def save(self, memory: ManagerMemory | LayerState) -> None:
        if isinstance(memory, LayerState):
            memory = ManagerMemory(memory)
        write_durably(self.path, memory.to_json(wall_time=time.time()))

    def _partial(self) -> Path:
        return partial_path(self.path)


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

    def answer_all(self, result: Any) -> None:
        """Answer every request still awaited with `result` (the manager stops)."""
        for request_id in list(self._open):
            self.answer(request_id, result)

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
        rules: RuleSet | None = None,
        bindings: Bindings | None = None,
        binding_timeout: float = 10.0,
        **node_options: Any,
    ) -> None:
        # Every entity of the node is waited on at every wake-up (a wake-up costs the
        # manager more CPU than a status: issue 16): it has no parameters to serve.
        node_options.setdefault("start_parameter_services", False)
        super().__init__(node_name, **node_options)
        self.log = NodeLog(self.get_logger())
        self.manager_id = f"{os.getpid()}-{uuid.uuid4().hex[:8]}"
        # The layers with bindings are applied by the manager itself (before it publishes):
        # a synchronous command naming only those needs no participant (docs/protocol.md).
        self.settings = dataclasses.replace(
            settings or ManagerSettings(),
            manager_id=self.manager_id,
            applied_by_manager=bindings.layers() if bindings else frozenset(),
        )
        self.state_file = StateFile(state_file) if state_file else None
        saved = self.state_file.load() if self.state_file else None
        self.protocol = ManagerProtocol(time.monotonic(), self.settings, saved)
        self._saved_memory = saved
        self._next_request_id = 0
        # Log lines of the activation path wait until its reply is sent (or the next tick):
        # an rclpy log call costs ~0.3 ms, longer than a whole topic round trip.
        self._postponed_logs: list[str] = []
        # No QoS event handlers (rclpy's default: two per publisher and subscription, each
        # waited on): a node whose QoS does not match is told so on its own side.
        quiet = PublisherEventCallbacks(use_default_callbacks=False)
        self._state_pub = self.create_publisher(
            LayerStateMsg, STATE_TOPIC, STATE_QOS, event_callbacks=quiet
        )
        self._heartbeat_pub = self.create_publisher(
            LayerStateMsg, HEARTBEAT_TOPIC, HEARTBEAT_QOS, event_callbacks=quiet
        )
        self._proposal_pub = self.create_publisher(
            LayerStateMsg, PROPOSAL_TOPIC, PROPOSAL_QOS, event_callbacks=quiet
        )
        # Another manager in this namespace: its states and heartbeats carry its id (see
        # `_on_manager_message`). Why this one stepped down, once it did.
        self.stepped_down = ""
        self._rivals_logged: set[str] = set()
        # Listened to while recovering, then only while the ROS graph shows another
        # activate service (every tick asks, a graph query): otherwise they bring this
        # manager its own states and heartbeats, a wake-up each, and each entity costs
        # every wake-up (issue 26).
        self._rival_subscriptions: list[Any] = []
        self._listen_for_rivals(True)
        self._save_error = ""  # the state file's last write error, logged once
        self._status_subscription = self.create_subscription(
            ParticipantStatus,
            STATUS_TOPIC,
            self._on_status,
            STATUS_QOS,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            raw=True,  # read by status_wire, not built as a Python message first
        )
        self._statuses = StatusDecoder()
        activate = self.create_service(
            Activate, ACTIVATE_SERVICE, self._on_activate, qos_profile=ACTIVATE_QOS
        )
        self._responses = _DeferredResponses(
            activate, lambda error: self.log.warning(f"a reply was lost: {error}")
        )
        self.create_service(QueryRegistry, QUERY_SERVICE, self._on_query, qos_profile=QUERY_QOS)
        self._tick_period = tick_period
        self._last_tick = time.monotonic()
        self.create_timer(tick_period, self._on_tick)
        origin = (
            f"state file {state_file} (epoch {saved.state.epoch}, "
            f"{len(saved.participants)} participant(s) known)"
            if saved
            else "participants"
        )
        self.log.info(f"Layer manager {self.manager_id} recovering from {origin}")
        # Context rules run here, in the manager's executor: their commands enter the
        # protocol directly, in one order with the clients' (docs/rules.md says why).
        self._rule_requests: dict[int, Firing] = {}
        self._next_rule_request = 0
        self._retried_at = 0  # the epoch after which refused rule firings were tried again
        # Layers that drive ROS: parameters and lifecycle states set before a state is
        # published (docs/ros-integration.md); commands wait their turn meanwhile.
        self.bindings: BindingDriver | None = None
        # What the nodes actually have, against what the layers set (drift, inference).
        self.watch: BindingWatch | None = None
        # Commands waiting for the ROS side, with when each arrived (its deadline and its
        # answer's `elapsed` count from there).
        self._commands: deque[tuple[ActivationCommand, float]] = deque()
        self._driving = False
        self._driving_to: tuple[str, ...] = ()
        self._driven: list[tuple[tuple[ActivationCommand, float] | None, str]] = []
        self._watch_jobs_done: list[WatchJob] = []  # (under `_driven_lock` too)
        self._driven_lock = threading.Lock()
        self._driven_guard = self.create_guard_condition(self._on_driven)
        # A failed reconcile (a bound node is down) is tried again later, with a growing
        # delay, and never ahead of the commands waiting: one of them may heal it.
        self._reconcile_failures = 0
        self._reconcile_failed_for: tuple[str, ...] | None = None
        self._reconcile_target: tuple[str, ...] = ()
        self._reconcile_heals = False  # it finishes a switch that did not end (killed, failed)
        self._reconcile_after = 0.0
        self._graph_observer: GraphObserver | None = None
        if bindings:
            from contextros.ros.bindings import BindingDriver

            # With a state file, what ROS reflects and the values to restore are kept next
            # to it: a restarted manager still restores the values from before its layers.
            memory = (
                state_file.with_name(f"{state_file.name}.bindings.json") if state_file else None
            )
            # Each parameter or lifecycle call waits `binding_timeout` for its answer (within
            # a command, no longer than its caller waits: `_drive`).
            self.bindings = BindingDriver(
                self, bindings, call_timeout=binding_timeout, memory=memory
            )
            from contextros.ros.binding_watch import BindingWatch

            self.watch = BindingWatch(self.bindings, self.log, self._graph())
        self.rules: RuleRunner | None = None
        if rules is not None and rules.rules:
            from contextros.ros.rules import RuleRunner

            self.rules = RuleRunner(
                self, rules, self._submit_rule, self._relations, graph=self._graph
            )

    def _graph(self) -> GraphObserver:
        """The one reader of lifecycle states and parameters, shared by the bindings' watch
        and the rules (one subscription per topic, one read per event): made when needed."""
        if self._graph_observer is None:
            from contextros.ros.graph_observer import GraphObserver

            self._graph_observer = GraphObserver(self, period=GRAPH_PERIOD)
        return self._graph_observer

    # -- executor callbacks -----------------------------------------------------------------

    def _on_status(self, data: bytes) -> None:
        """A status, and every other one already waiting (the participants of a synchronous
        activation answer at once): handled in one go, not one executor wake-up each."""
        now = time.monotonic()
        actions: list[ManagerAction] = []
        for message in self._waiting_statuses(data):
            try:
                report = self._statuses.decode(message)
            except (AttributeError, TypeError, ValueError) as error:  # a foreign sender
                self.log.error(f"ignored an unreadable status message: {error}")
                continue
            actions += self.protocol.receive_status(report, now)
        self._run(actions)
        if self._commands and not self._driving:  # an atomic vote or a held layer may be over
            self._next_command()
        if self.protocol.awaiting_acknowledgements:
            time.sleep(STATUS_LINGER)

    def _on_manager_message(self, msg: Any) -> None:
        """A state or heartbeat of another live manager in this namespace: the two would
        re-assert over each other's epochs without end. A manager still recovering (it
        published no state yet) steps down before a running one; between two alike, the one
        with the greater id. Stepping down ends the spin (`contextros manager` exits 2)."""
        other = str(msg.manager_id)
        if not other or other == self.manager_id or self.stepped_down:
            return
        if len(other) > 64 or not other.isprintable():  # not a manager's id: not logged
            return
        if self.count_services(ACTIVATE_SERVICE) < 2:
            # No second manager's service in the graph: a message alone (any process may
            # publish one) is no manager; heard again once discovery shows its service.
            return
        other_recovering = msg.epoch == 0 and msg.reason == "recovering"
        recovering = self.protocol.recovering
        # A newcomer yields to a running manager; between two alike, the greater id yields.
        steps_down = self.manager_id > other if recovering == other_recovering else recovering
        where = f"namespace {self.get_namespace()}"
        nodes = sorted(
            {
                f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                for info in self.get_publishers_info_by_topic(HEARTBEAT_TOPIC)
            }
        )
        rival = (
            f"another Layer manager is live in {where}: id {other} (process "
            f"{other.split('-')[0]}; manager nodes {', '.join(nodes) or '?'})"
        )
        if steps_down:
            self.stepped_down = (
                f"{rival}; this manager ({self.manager_id}) "
                f"{'did not start' if recovering else 'steps down (the greater id)'}: "
                "two managers in one namespace would re-assert over each other's epochs. "
                "Stop the other one, or give this one its own --namespace"
            )
            self._flush_logs()  # the states it published, before it says why it stops
            self.log.error(self.stepped_down)
            # Its callers hear why now, not at their deadline (an unsettled command's state
            # may be out: `status`, asked of the manager that stays, says).
            state = self.protocol.state
            self._responses.answer_all(
                ActivationResult(
                    False,
                    f"the Layer manager stopped before deciding this command: {rival}; "
                    "whether a state it published is applied is unknown (`contextros status`)",
                    state.epoch,
                    state.active,
                )
            )
        elif other not in self._rivals_logged:
            self._rivals_logged.add(other)
            self.log.error(f"{rival}; it steps down, this manager ({self.manager_id}) stays")

    def _listen_for_rivals(self, listen: bool) -> None:
        """Subscribe to the state and heartbeat topics while another manager may be live."""
        if listen and not self._rival_subscriptions:
            self._rival_subscriptions = [
                self.create_subscription(
                    LayerStateMsg,
                    topic,
                    self._on_manager_message,
                    qos,
                    event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
                )
                for topic, qos in ((STATE_TOPIC, STATE_QOS), (HEARTBEAT_TOPIC, HEARTBEAT_QOS))
            ]
        elif not listen and self._rival_subscriptions:
            for subscription in self._rival_subscriptions:
                self.destroy_subscription(subscription)
            self._rival_subscriptions = []

    def _waiting_statuses(self, first: bytes) -> Iterator[bytes]:
        yield first
        handle = self._status_subscription.handle
        for _ in range(STATUS_BATCH - 1):
            with handle:
                taken = handle.take_message(ParticipantStatus, True)
            if taken is None:
                return
            yield taken[0]

    def _on_tick(self) -> None:
        now = time.monotonic()
        stall, self._last_tick = now - self._last_tick - self._tick_period, now
        if stall > STALL:  # this process did not run: a loaded machine, SIGSTOP
            self.protocol.resumed_after(stall)
            self.log.warning(
                f"the manager did not run for {stall:.1f} s: that time does not count as "
                "the nodes' silence"
            )
        servers = self.count_services(ACTIVATE_SERVICE)
        self._listen_for_rivals(servers > 1 or self.protocol.recovering)
        if self.protocol.recovering and servers > 1:
            # Another manager's service is in the graph (a graph query, microseconds):
            # no first state before its state or heartbeat is heard (`_on_manager_message`).
            self.protocol.prolong_recovery(now + 2 * self._tick_period)
        self._run(self.protocol.tick(now))
        if self.rules is not None:
            self.rules.tick()
            if self._retried_at != self.protocol.state.epoch:
                self._retried_at = self.protocol.state.epoch
                self.rules.retry()
        if self._commands and self._driving:
            self._expire_behind_the_drive(now)
        if self._commands:
            self._next_command()
        self._reconcile()
        self._watch_next()
        self._flush_logs()

    # -- commands, with the ROS side of layers first ----------------------------------------

    def _command(self, command: ActivationCommand) -> None:
        if self.bindings is None:
            self._run(self.protocol.receive_command(command, time.monotonic()))
            return
        self._commands.append((command, time.monotonic()))
        self._next_command()

    def _next_command(self) -> None:
        """Run queued commands; one whose layers set parameters or lifecycle states waits
        until those are done (in a worker thread) and is refused, naming what failed, if
        they cannot be."""
        assert self.bindings is not None
        # A command the protocol would hold (the manager recovers, an atomic vote is open, a
        # layer nobody implements yet within the grace period) waits here, with those behind
        # it: held there, it would be published on its release past the ROS side. The tick
        # and the statuses bring it back.
        while self._commands and not self._driving:
            command, received = self._commands[0]
            now = time.monotonic()
            held = self.protocol.would_hold(command, now)
            if held and not self.protocol.expired(command, now, received):
                return
            self._commands.popleft()
            problem, planned = self.protocol.preview(command)
            applied = self.bindings.applied
            refusal = "" if problem or not command.atomic else self._atomic_refusal(planned)
            if refusal:
                state = self.protocol.state
                self._reply(
                    command.request_id, ActivationResult(False, refusal, state.epoch, state.active)
                )
            elif self.protocol.expired(command, now, received) and not held:
                # Nothing driven; not held by the protocol: it waited behind a drive.
                self._run(self.protocol.refusal_if_expired(command, now, received, BEHIND_A_DRIVE))
            elif held or problem or not self.bindings.plan(applied, planned):
                # (held and expired: the protocol refuses it, saying what held it)
                self._run(self.protocol.receive_command(command, now, received))
            else:
                self._drive((command, received), applied, planned)

    def _expire_behind_the_drive(self, now: float) -> None:
        """Refuse, at their deadline, the commands waiting while a command's parameters
        and lifecycle states are being set (each of those calls may take seconds)."""
        kept: deque[tuple[ActivationCommand, float]] = deque()
        for command, received in self._commands:
            refusal = self.protocol.refusal_if_expired(command, now, received, BEHIND_A_DRIVE)
            if refusal:
                self._run(refusal)
            else:
                kept.append((command, received))
        self._commands = kept

    def _atomic_refusal(self, planned: tuple[str, ...]) -> str:
        """Why an atomic command that would change ROS parameters or lifecycle states is
        refused ("" if it would not): its participants vote, the bound nodes cannot, and
        an aborted vote must leave nothing changed anywhere (docs/ros-integration.md)."""
        assert self.bindings is not None
        current = self.protocol.state.active
        if not self.bindings.plan(current, planned):
            return ""
        bound = self.bindings.bindings.layers()
        names = sorted((set(planned) ^ set(current)) & bound) or sorted(set(planned) & bound)
        return (
            "atomic activation not started, nothing changed: "
            f"{', '.join(names)} set{'s' if len(names) == 1 else ''} ROS parameters or "
            "lifecycle states, which an atomic vote cannot include; switch without atomic"
        )

    def _drive(
        self,
        command: tuple[ActivationCommand, float] | None,
        old: tuple[str, ...],
        new: tuple[str, ...],
    ) -> None:
        assert self.bindings is not None
        self._driving = True
        self._driving_to = new
        driver = self.bindings
        deadline = self._calls_deadline(*command) if command else None

        def work() -> None:
            from contextros.ros.bindings import BindingError

            try:
                driver.switch(old, new, deadline)
                error = ""
            except BindingError as failure:
                error = str(failure)
            except Exception as failure:  # a bug must not leave the manager stuck
                error = f"internal error: {failure!r}"
            with self._driven_lock:
                self._driven.append((command, error))
            self._driven_guard.trigger()

        threading.Thread(target=work, name="contextros-bindings", daemon=True).start()

    def destroy_node(self) -> None:
        """Stopped (Ctrl-C, SIGTERM) while setting parameters and lifecycle states: say what
        that leaves, and answer the commands still waiting, before going."""
        if self._driving and not self.stepped_down:
            after = (
                f"a manager restarted with the state file {self.state_file.path} gives them back"
                if self.state_file
                else "nothing gives them back (no --state-file)"
            )
            stopped = (
                "the Layer manager stopped while setting the parameters and lifecycle states "
                f"of [{', '.join(self._driving_to)}]: the nodes keep what was set so far; {after}"
            )
            self.log.warning(stopped)
            self._flush_logs()
            state = self.protocol.state
            self._responses.answer_all(
                ActivationResult(False, f"{stopped}; no state published", state.epoch, state.active)
            )
        super().destroy_node()

    def _calls_deadline(self, command: ActivationCommand, received: float) -> Deadline:
        """When a command's parameter and lifecycle calls must be over: when its caller gives
        up (its deadline + REPLY_MARGIN, as LayerClient does). A drive started before the
        deadline is carried through (`_on_driven`), but not past that: no one would hear its
        outcome, and a call cut short is rolled back."""
        from contextros.ros.bindings import Deadline
        from contextros.ros.client import REPLY_MARGIN

        # (the protocol's deadline: the command's timeout, or the manager's default)
        timeout = command.timeout if command.timeout > 0 else self.settings.default_timeout
        why = f"what was left of the command's timeout of {timeout:g} s + {REPLY_MARGIN:g} s"
        return Deadline(received + timeout + REPLY_MARGIN, why)

    def _on_driven(self) -> None:
        with self._driven_lock:
            driven, self._driven = self._driven, []
            watched, self._watch_jobs_done = self._watch_jobs_done, []
        for job in watched:
            self._driving = False
            assert self.watch is not None
            self.watch.finished(job)
        for queued, error in driven:
            self._driving = False
            if self.watch is not None:
                self.watch.switched()
            if queued is None:
                self._reconciled(error)
                continue
            command, received = queued
            if error:
                result = ActivationResult(
                    False,
                    error,  # what failed and what became of the changes (the driver says)
                    self.protocol.state.epoch,
                    self.protocol.state.active,
                    elapsed=time.monotonic() - received,
                )
                self._reply(command.request_id, result)
            elif self.protocol.would_hold(command, time.monotonic()):
                # Its layer's only participant left meanwhile: back to the front of the
                # queue; the reconcile brings ROS back to the published state.
                self._commands.appendleft(queued)
            else:
                # Received when it arrived: the binding phase is part of its `elapsed`.
                # Started before its deadline: carried through, whenever the drive ended
                # (refused now, ROS would go there and back).
                now = time.monotonic()
                self._run(self.protocol.receive_command(command, now, received, started=True))
        # Waiting commands first: a failed reconcile must not starve them (each of its
        # tries may take seconds), and one whose plan reaches its target heals it anyway.
        self._next_command()
        self._reconcile()
        self._watch_next()

    def _reconcile(self) -> None:
        """States not made by a command (recovery), a command whose outcome differed
        from its preview, or a switch left half-done (the manager was killed during it, a
        rollback failed): bring the ROS side to the published state. After a failure, the
        same target is tried again only after a delay (`RECONCILE_RETRY`, doubling)."""
        if self.bindings is None or self._driving or self.protocol.recovering:
            return
        active = self.protocol.state.active
        if self.bindings.applied == active and not self.bindings.unsettled:
            self._reconcile_failures, self._reconcile_failed_for = 0, None
            return
        if not self.bindings.plan(self.bindings.applied, active):
            self.bindings.settled(active)
            return
        if active == self._reconcile_failed_for and time.monotonic() < self._reconcile_after:
            return
        self._reconcile_target = active
        self._reconcile_heals = self.bindings.unsettled
        self._drive(None, self.bindings.applied, active)

    def _reconciled(self, error: str) -> None:
        """A reconcile's outcome: on failure, when to try again."""
        if not error:
            self._reconcile_failures, self._reconcile_failed_for = 0, None
            if self._reconcile_heals:
                self.log.info(
                    "layers' ROS side brought to "
                    f"[{', '.join(self._reconcile_target)}] after a switch that did not end: "
                    "what it changed is given back"
                )
            return
        target = self._reconcile_target
        if target != self._reconcile_failed_for:
            self._reconcile_failures = 0
        self._reconcile_failures += 1
        self._reconcile_failed_for = target
        delay = min(RECONCILE_RETRY * 2 ** (self._reconcile_failures - 1), RECONCILE_RETRY_MAX)
        self._reconcile_after = time.monotonic() + delay
        self.log.error(
            f"layers' ROS side not reached: {error} (try {self._reconcile_failures}; "
            f"again in {delay:g} s, or with the next command)"
        )

    def _watch_next(self) -> None:
        """Read what events say changed, set drifted bindings back, switch to an inferred
        configuration: only while no switch runs or waits (docs/ros-integration.md)."""
        if self.watch is None or self._driving or self._commands or self.protocol.recovering:
            return
        inferred = self.watch.inference(self.protocol.state.active)
        if inferred is not None:
            self._submit_inferred(inferred.activate, inferred.deactivate, inferred.reason)
            return
        job = self.watch.next_job()
        if job is None:
            return
        self._driving = True
        driver = self.bindings
        assert driver is not None

        def work() -> None:
            try:
                job.run(driver)
            except Exception as failure:  # a bug must not leave the manager stuck
                self.log.error(f"watching the layers' bindings: internal error: {failure!r}")
            with self._driven_lock:
                self._watch_jobs_done.append(job)
            self._driven_guard.trigger()

        threading.Thread(target=work, name="contextros-binding-watch", daemon=True).start()

    def _submit_inferred(
        self, activate: tuple[str, ...], deactivate: tuple[str, ...], reason: str
    ) -> None:
        """A switch inferred from what the nodes have (an `infer` drift): an ordinary
        command (the watch logged why); a refusal is logged as any is."""
        self._next_rule_request -= 1
        command = ActivationCommand(
            request_id=self._next_rule_request,
            activate=activate,
            deactivate=deactivate,
            synchronous=True,
            requester="contextros-inference",
            reason=reason,
        )
        if not self._refused_when_full(command):
            self._command(command)

    def _reply(self, request_id: int, result: ActivationResult) -> None:
        if request_id in self._rule_requests:
            self._rule_outcome(self._rule_requests.pop(request_id), result)
        else:
            self._responses.answer(request_id, result)
            if not result.success:
                self._log_failure(result)

    # -- rules ------------------------------------------------------------------------------

    def _submit_rule(self, firing: Firing) -> None:
        """A rule's firing is an ordinary synchronous command (negative request ids)."""
        self._next_rule_request -= 1
        self._rule_requests[self._next_rule_request] = firing
        command = ActivationCommand(
            request_id=self._next_rule_request,
            activate=firing.activate,
            deactivate=firing.deactivate,
            synchronous=True,
            requester=firing.requester,
            reason=firing.reason,
        )
        if not self._refused_when_full(command):
            self._command(command)

    def _relations(self) -> dict[str, tuple[frozenset[str], frozenset[str]]]:
        return {
            name: (declaration.groups, declaration.excludes)
            for name, declaration in self.protocol.declarations().items()
        }

    def _rule_outcome(self, firing: Firing, result: ActivationResult) -> None:
        # "to Night", "to Night, Slow off", "Slow off": what the firing asked for.
        asked = [f"to {', '.join(firing.activate)}"] if firing.activate else []
        asked += [f"{', '.join(firing.deactivate)} off"] if firing.deactivate else []
        target = ", ".join(asked).removeprefix("to ") if firing.activate else ", ".join(asked)
        switched = "switched to" if firing.activate else "switched"
        if result.success and result.message.startswith("no change"):
            outcome = "already in force (no change)"
            self.log.info(f"rule {firing.rule}: {target} {outcome}")
        elif result.success:
            outcome = (
                f"epoch {result.epoch}: {len(result.acknowledged)} node(s) applied it in "
                f"{result.elapsed * 1000:.1f} ms"
            )
            self.log.info(
                f"rule {firing.rule} {switched} {target}: {len(result.acknowledged)} node(s) "
                f"applied it in {result.elapsed * 1000:.1f} ms (epoch {result.epoch}, "
                f"[{', '.join(result.active)}])"
            )
        else:
            outcome = f"refused: {result.message} (tried again after the next state)"
            self.log.warning(
                f"rule {firing.rule} could not {switched.replace('switched', 'switch')} "
                f"{target}: {result.message} "
                "(tried again after the next state)"
            )
        if self.rules is not None:
            self.rules.outcome(firing, outcome)
            if not result.success:
                self.rules.refused(firing)

    def _log_failure(self, result: ActivationResult) -> None:
        """A refused command changed nothing; a published epoch that was not confirmed is
        not a refusal (its nodes may well have applied it since)."""
        published = result.message.startswith("epoch ")
        self.log.warning(f"{'answered' if published else 'refused'}: {result.message}")

    def _flush_logs(self) -> None:
        logs, self._postponed_logs = self._postponed_logs, []
        for line in logs:
            self.log.info(line)

    def _on_activate(self, request: Any, response: Any) -> Any:
        self._next_request_id += 1
        request_id = self._next_request_id
        self._responses.expect(request_id, response)
        command = command_from_request(request_id, request)
        if not self._refused_when_full(command):
            self._command(command)
        return response

    def _refused_when_full(self, command: ActivationCommand) -> bool:
        """Commands waiting for the layers' ROS side are bounded like the protocol's (anyone
        in the domain can send them): beyond the cap, refused at once naming it."""
        cap = self.settings.max_waiting_commands
        if len(self._commands) < cap:
            return False
        message = (
            f"refused: {len(self._commands)} commands are waiting in the manager already, "
            f"at most {cap} (max_waiting_commands); nothing changed, try again later"
        )
        state = self.protocol.state
        self._reply(command.request_id, ActivationResult(False, message, state.epoch, state.active))
        return True

    def _on_query(self, request: Any, response: Any) -> Any:
        del request
        view = self.protocol.registry(time.monotonic())
        fill_query_response(response, view, self.manager_id)
        if self.rules is not None:
            response.rules = self.rules.infos()
        if self.bindings is not None:
            response.bindings = self.bindings.infos(self.watch.actual if self.watch else None)
        return response

    # -- actions ----------------------------------------------------------------------------

    def _save(self) -> None:
        """Write the manager's memory if it changed: before the actions that changed it
        go out (a state, a proposal), and when a participant joins or is dropped."""
        assert self.state_file is not None
        memory = self.protocol.memory()
        if memory == self._saved_memory:
            return
        try:
            self.state_file.save(memory)
        except OSError as error:
            # Keep switching: the participants still carry the epoch across a restart.
            # Logged when writing starts failing (or fails otherwise), not at every state.
            if str(error) != self._save_error:
                self._save_error = str(error)
                self.log.error(
                    f"state file {self.state_file.path} not written (epoch "
                    f"{memory.state.epoch}): {error}; the manager keeps running, a restart "
                    "relies on the nodes' reports (logged again when this changes)"
                )
            return
        self._saved_memory = memory
        if self._save_error:
            self._save_error = ""
            self.log.info(f"state file {self.state_file.path} written again")

    def _run(self, actions: list[ManagerAction]) -> None:
        if self.stepped_down:  # another manager runs this namespace: nothing goes out
            return
        if self.state_file and any(isinstance(a, DURABLE) for a in actions):
            self._save()
        for action in actions:
            if isinstance(action, PublishState):
                if self.rules is not None:  # a manual command's state drops refused firings
                    self.rules.published(action.state)
                self._state_pub.publish(state_to_msg(action.state, time.time()))
                self._postponed_logs.append(
                    f"epoch {action.state.epoch}: [{', '.join(action.state.active)}] "
                    f"({action.state.requester or '?'}: {action.state.reason or '-'})"
                )
            elif isinstance(action, PublishProposal):
                self._proposal_pub.publish(state_to_msg(action.state, time.time()))
            elif isinstance(action, PublishHeartbeat):
                self._heartbeat_pub.publish(state_to_msg(action.state, time.time()))
            elif isinstance(action, Reply) and action.request_id in self._rule_requests:
                self._flush_logs()
                self._rule_outcome(self._rule_requests.pop(action.request_id), action.result)
            elif isinstance(action, Reply):
                self._responses.answer(action.request_id, action.result)
                self._flush_logs()
                if not action.result.success:  # logged after the answer: it costs ~0.3 ms
                    self._log_failure(action.result)
            elif isinstance(action, ParticipantJoined):
                verb = "restarted" if action.restarted else "joined"
                self.log.info(f"participant {action.node} {verb}")
            elif isinstance(action, ParticipantDropped):
                self.log.warning(f"participant {action.node} dropped: {action.reason}")
            elif isinstance(action, ReportRejected):
                self.log.warning(
                    f"ignored a status from {action.node!r}: {'; '.join(action.problems)}"
                )
            elif isinstance(action, ParticipantConflict):
                self.log.error(
                    f"two live processes are named {action.node}: both are tracked and each "
                    "must acknowledge for itself; give each context node a unique name "
                    "(or namespace)"
                )
