"""Context nodes: rclpy nodes whose layered methods follow the Layer manager.

`ContextParticipant(node)` attaches the protocol to any existing node (injected, like
py_trees_ros's `setup(node=...)`); `ContextNode` is a Node that does it for itself.
A new state is applied inside the node's executor (the state subscription callback), with
the core's `set_active`, so layered calls made from the node's callbacks see either the old
configuration or the new one, and the acknowledgement is sent only once it really applied.
"""

from __future__ import annotations

import contextlib
import os
import threading
import time
import uuid
from collections.abc import Callable, Iterable
from typing import Any

from contextros_interfaces.msg import LayerState as LayerStateMsg
from contextros_interfaces.msg import ParticipantStatus
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node

from contextros.core import (
    Layer,
    SwitchResult,
    active_layers,
    defined_layers,
    in_critical_section,
    layer_named,
    set_active,
)
from contextros.errors import LayerError, UnknownLayerError
from contextros.protocol import (
    DEFAULT_HEARTBEAT_PERIOD,
    DEFAULT_MANAGER_TIMEOUT,
    LEAVE_REPEAT_AFTER,
    ApplyState,
    LayerDeclaration,
    LayerState,
    ManagerFound,
    ManagerLost,
    ParticipantAction,
    ParticipantProtocol,
    PublishStatus,
    StateRejected,
)
from contextros.ros.messages import state_from_msg
from contextros.ros.status_wire import StateDecoder, StatusEncoder
from contextros.ros.topics import (
    HEARTBEAT_QOS,
    HEARTBEAT_TOPIC,
    PROPOSAL_QOS,
    PROPOSAL_TOPIC,
    STATE_QOS,
    STATE_TOPIC,
    STATUS_QOS,
    STATUS_TOPIC,
)

StateListener = Callable[[LayerState], object]
# Called with True when the manager is lost (not heard for the liveness bound), with False
# when it is heard again. The node keeps its layers meanwhile; a listener may switch to a
# safe configuration (with the core's `activate`/`set_active`): once the manager is heard
# again, its newer state or else the state applied last replaces it.
ManagerListener = Callable[[bool], object]
# Asked about an atomic activation's proposed state: return why this node cannot apply it
# ("" or None: it can). Called once per proposal, in a thread of its own (the node's
# executor, heartbeats included, goes on meanwhile); docs/protocol.md says what it may do.
Veto = Callable[[LayerState], "str | None"]
# How long closing a participant waits for a veto still thinking (as the C++ participant).
VETO_PATIENCE = 5.0


def declaration_of(layer: Layer) -> LayerDeclaration:
    return LayerDeclaration(
        name=layer.name,
        excludes=frozenset(layer.excludes),
        requires=frozenset(layer.requires),
        group=layer.group or "",
        after=frozenset(layer.after),
        implies=frozenset(layer.implies),
    )


def declarations_of(layers: Iterable[Layer | str] | None) -> tuple[LayerDeclaration, ...]:
    """The declarations of `layers` (by default, every layer defined in the process)."""
    chosen = defined_layers() if layers is None else layers
    return tuple(
        declaration_of(layer if isinstance(layer, Layer) else layer_named(layer))
        for layer in chosen
    )


def _layer_for(name: str) -> Layer:
    # A layer this node has no partials for is still part of the configuration (it keeps
    # the composition order identical everywhere); a bare layer is transparent.
    try:
        return layer_named(name)
    except UnknownLayerError:
        return Layer(name)


class ContextParticipant:
    """The protocol's participant side, attached to an existing rclpy node.

    `layers` are the layers this node implements (announced with their relations); by
    default every layer defined in the process when the participant is created.

    Each newer state is applied in the node's executor with the core's `set_active` (the
    manager's state replaces whatever was activated locally) and acknowledged once applied.
    A `with critical():` section held by another thread defers the switch without blocking
    the executor; the acknowledgement follows when the section ends. The decisive
    configuration belongs to the process, so one participant per process is enough.
    """

    def __init__(
        self,
        node: Node,
        layers: Iterable[Layer | str] | None = None,
        *,
        heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD,
        manager_timeout: float = DEFAULT_MANAGER_TIMEOUT,
        _previous: ContextParticipant | None = None,
    ) -> None:
        self.node = node
        declarations = declarations_of(layers)
        self._own_layers = declarations
        self._hosted: dict[str, tuple[Node, tuple[LayerDeclaration, ...]]] = {}
        self.protocol = ParticipantProtocol(
            node=node.get_fully_qualified_name(),
            incarnation=f"{os.getpid()}-{uuid.uuid4().hex[:8]}",
            layers=declarations,
            heartbeat_period=heartbeat_period,
            manager_timeout=manager_timeout,
        )
        self.state: LayerState | None = None
        if _previous is not None:  # a hand-over: the process's epoch and layers carry on
            self.protocol.continue_from(_previous.protocol)
            self.state = _previous.state
        self._listeners: list[StateListener] = []
        self._manager_listeners: list[ManagerListener] = []
        self._vetoes: list[Veto] = []
        # Deferred switches settle on whichever thread closes the critical section, and
        # vetoes think in a worker thread: both are handed back to the executor through
        # one guard condition (every entity costs each wake-up of the executor).
        self._deferred: list[tuple[LayerState, SwitchResult]] = []
        self._deferred_lock = threading.Lock()
        self._asking: tuple[int, str] | None = None  # the proposal whose vetoes think
        self._veto_workers: list[threading.Thread] = []
        self._answers: list[tuple[LayerState, str]] = []
        self._answers_lock = threading.Lock()
        self._handed_back = node.create_guard_condition(self._on_handed_back)
        # rclpy's QoS event handlers (two per publisher and subscription, each waited on
        # at every wake-up) on the state subscription only: its QoS (reliable, transient
        # local) is the one a peer would not match; a manager not heard is logged anyway.
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        self._status_pub = node.create_publisher(
            ParticipantStatus,
            STATUS_TOPIC,
            STATUS_QOS,
            event_callbacks=PublisherEventCallbacks(use_default_callbacks=False),
        )
        self._statuses = StatusEncoder()
        # States are taken as bytes and decoded once per process (status_wire).
        self._state_sub = node.create_subscription(
            LayerStateMsg, STATE_TOPIC, self._on_state, STATE_QOS, raw=True
        )
        self._heartbeat_sub = node.create_subscription(
            LayerStateMsg,
            HEARTBEAT_TOPIC,
            self._on_state,
            HEARTBEAT_QOS,
            raw=True,
            event_callbacks=quiet,
        )
        self._proposal_sub = node.create_subscription(
            LayerStateMsg,
            PROPOSAL_TOPIC,
            self._on_proposal,
            PROPOSAL_QOS,
            raw=True,
            event_callbacks=quiet,
        )
        self._heartbeat = node.create_timer(heartbeat_period, self._on_heartbeat)
        # Repeats of a new report, shortly after it (a lossy link may have lost it); the
        # timer runs only while repeats are due.
        self._repeat_timer = node.create_timer(0.05, self._on_heartbeat)
        self._repeat_timer.cancel()
        self._repeating = False  # (asking rclpy costs more than the rest of a report)
        self._run(self.protocol.announce(time.monotonic()))

    @property
    def applied_epoch(self) -> int:
        return self.protocol.applied_epoch

    def add_listener(self, listener: StateListener) -> None:
        """Call `listener(state)` in the executor after each state this node applied."""
        self._listeners.append(listener)

    def add_manager_listener(self, listener: ManagerListener) -> None:
        """Call `listener(lost)` in the executor when the manager is lost (True: not heard
        for `manager_timeout`) or heard again (False)."""
        self._manager_listeners.append(listener)

    def add_veto(self, veto: Veto) -> None:
        """Let `veto(state)` refuse an atomic activation's proposed state with a reason.

        It is called once per proposal, in a worker thread (the executor goes on), and
        must neither switch layers nor spin the node; the vote follows its answer, and the
        activation aborts if that comes after the command's timeout (docs/protocol.md).
        Besides, the node votes no while a critical section is open and when the proposed
        layers break a relation it declares."""
        self._vetoes.append(veto)

    @property
    def manager_lost(self) -> bool:
        """This node has not heard the manager for its liveness bound."""
        return self.protocol.manager_lost

    def host(self, node: Node, layers: Iterable[Layer | str] | None = None) -> None:
        """Speak for another node of this process too (its layers join the announced ones).

        The decisive configuration is per process, so the states this participant applies
        are that node's too; the manager lists it and counts this participant's
        acknowledgement for it.
        """
        self._hosted[node.get_fully_qualified_name()] = (node, declarations_of(layers))
        self._announce_hosting()

    def release(self, node: Node) -> None:
        """Stop speaking for `node` (it is being destroyed)."""
        if self._hosted.pop(node.get_fully_qualified_name(), None) is not None:
            self._announce_hosting()

    @property
    def hosted_nodes(self) -> tuple[str, ...]:
        return tuple(sorted(self._hosted))

    def hosted(self) -> list[Node]:
        """The other nodes this participant speaks for, in the order they joined."""
        return [node for node, _ in self._hosted.values()]

    def _announce_hosting(self) -> None:
        union: dict[str, LayerDeclaration] = {}
        hosted = (d for _, declarations in self._hosted.values() for d in declarations)
        for declaration in (*self._own_layers, *hosted):
            union.setdefault(declaration.name, declaration)
        self._run(self.protocol.host(self.hosted_nodes, tuple(union.values()), time.monotonic()))

    def leave(self) -> None:
        """Tell the manager this node is going away (it is dropped at once, not after a timeout)."""
        with contextlib.suppress(Exception):
            self._run(self.protocol.leave(time.monotonic()))
            time.sleep(LEAVE_REPEAT_AFTER)
            self._run(self.protocol.leave(time.monotonic()))

    def close(self) -> None:
        """Leave, and wait (up to VETO_PATIENCE s) for a veto still thinking: user code
        left running past the node (and the interpreter) is what this avoids."""
        self.leave()
        deadline = time.monotonic() + VETO_PATIENCE
        for worker in self._veto_workers:
            if worker is not threading.current_thread():
                worker.join(max(0.0, deadline - time.monotonic()))
        if any(worker.is_alive() for worker in self._veto_workers):
            self.node.get_logger().warning(
                f"a veto still runs {VETO_PATIENCE:g} s after the participant closed: left "
                "to finish on its own"
            )
        self.node.destroy_timer(self._heartbeat)
        self.node.destroy_timer(self._repeat_timer)
        self.node.destroy_subscription(self._state_sub)
        self.node.destroy_subscription(self._heartbeat_sub)
        self.node.destroy_subscription(self._proposal_sub)
        self.node.destroy_publisher(self._status_pub)
        self.node.destroy_guard_condition(self._handed_back)

    # -- executor callbacks -----------------------------------------------------------------

    def _state_of(self, msg: bytes | Any) -> LayerState | None:
        """The state in a message taken raw (or a `LayerState` message); None if damaged."""
        if not isinstance(msg, bytes):
            return state_from_msg(msg)
        try:
            return _states.decode(msg)
        except ValueError as error:
            self.node.get_logger().warning(
                f"ignored a layer state: {error}", throttle_duration_sec=10.0
            )
            return None

    def _on_state(self, msg: bytes | Any) -> None:
        state = self._state_of(msg)
        if state is not None:
            self._run(self.protocol.receive_state(state, time.monotonic()))

    def _on_proposal(self, msg: bytes | Any) -> None:
        """A proposal (repeated every 50 ms while the vote is open): without vetoes the node
        votes at once; with vetoes they are asked once, in a worker thread, and the vote
        follows their answer (`_on_vetoes_answered`)."""
        proposal = self._state_of(msg)
        if proposal is None:
            return
        now = time.monotonic()
        self.protocol.critical_section_open = in_critical_section()
        if not self._vetoes or not self.protocol.wants_vote(proposal):
            self._run(self.protocol.receive_proposal(proposal, now))
            return
        self._run(self.protocol.receive_proposal(proposal, now, vote=False))
        asked = (proposal.epoch, proposal.manager_id)
        if self._asking == asked:
            return  # its vetoes are still thinking
        self._asking = asked
        vetoes = list(self._vetoes)
        worker = threading.Thread(
            target=self._ask_vetoes, args=(proposal, vetoes), name="contextros-veto", daemon=True
        )
        self._veto_workers = [w for w in self._veto_workers if w.is_alive()] + [worker]
        worker.start()

    def _ask_vetoes(self, proposal: LayerState, vetoes: list[Veto]) -> None:
        reasons = []
        for veto in vetoes:
            try:
                reason = veto(proposal)
            except Exception as failure:  # a veto that fails says no, and is logged
                reason = f"veto {getattr(veto, '__name__', veto)!r} failed: {failure!r}"
                self.node.get_logger().error(f"{reason} (epoch {proposal.epoch}: voting no)")
            if reason:
                reasons.append(str(reason))
        with self._answers_lock:
            self._answers.append((proposal, "; ".join(reasons)))
        with contextlib.suppress(Exception):  # the node was destroyed meanwhile
            self._handed_back.trigger()

    def _on_handed_back(self) -> None:
        self._on_deferred_settled()
        self._on_vetoes_answered()

    def _on_vetoes_answered(self) -> None:
        with self._answers_lock:
            answers, self._answers = self._answers, []
        for proposal, veto in answers:
            if (proposal.epoch, proposal.manager_id) != self._asking:
                continue  # a newer proposal came meanwhile: this one is over
            self._asking = None
            self.protocol.critical_section_open = in_critical_section()
            self._run(self.protocol.receive_proposal(proposal, time.monotonic(), veto))

    def _on_heartbeat(self) -> None:
        self._run(self.protocol.tick(time.monotonic()))

    def _on_deferred_settled(self) -> None:
        with self._deferred_lock:
            settled = [(s, r) for s, r in self._deferred if r.done]
            self._deferred = [(s, r) for s, r in self._deferred if not r.done]
        for state, result in settled:
            self._settle(state, result.applied, result.error)

    # -- actions ----------------------------------------------------------------------------

    def _run(self, actions: list[ParticipantAction]) -> None:
        self.protocol.critical_section_open = in_critical_section()
        for action in actions:
            if isinstance(action, ApplyState):
                self._apply(action.state)
            elif isinstance(action, PublishStatus):
                # As bytes (status_wire): the same message, written at a third of the cost.
                self._status_pub.publish(self._statuses.encode(action.report, time.time()))
            elif isinstance(action, StateRejected):
                self.node.get_logger().warning(
                    f"ignored a layer state: {'; '.join(action.problems)}",
                    throttle_duration_sec=10.0,
                )
            elif isinstance(action, ManagerLost | ManagerFound):
                if isinstance(action, ManagerFound) and not any(
                    isinstance(other, ApplyState) for other in actions
                ):
                    self._restore_applied()
                self._manager_changed(action)
        # Wake up for the next repeat of a report, if one is due; else sleep.
        repeating = self.protocol.next_repeat is not None
        if repeating != self._repeating:
            self._repeating = repeating
            if repeating:
                self._repeat_timer.reset()
            else:
                self._repeat_timer.cancel()

    def _restore_applied(self) -> None:
        """The manager is back with no newer state: a configuration set while it was lost
        (a safe fallback) gives way to the state applied last (the heartbeat is not newer)."""
        current = tuple(layer.name for layer in active_layers())
        if self.state is None or current == self.state.active:
            return
        self.node.get_logger().info(f"back to the layers of epoch {self.state.epoch}")
        self._apply(self.state)  # acknowledged already: the protocol ignores its outcome

    def _manager_changed(self, event: ManagerLost | ManagerFound) -> None:
        lost = isinstance(event, ManagerLost)
        joined = bool(self.protocol.applied_manager_id)  # (a node started before its manager)
        if isinstance(event, ManagerLost):
            self.node.get_logger().warning(
                f"no Layer manager heard {'for' if joined else 'in the first'} "
                f"{event.silent_for:.1f} s: keeping layers "
                f"[{', '.join(self.protocol.active)}] (epoch {self.protocol.applied_epoch})"
            )
        else:
            who = f" {event.manager_id}" if event.manager_id else ""
            again = "again" if joined else "for the first time"
            self.node.get_logger().info(f"Layer manager{who} heard {again}")
        for listener in list(self._manager_listeners):
            try:
                listener(lost)
            except Exception as failure:  # a listener must not stop the node
                self.node.get_logger().error(f"manager listener {listener!r} failed: {failure!r}")

    def _apply(self, state: LayerState) -> None:
        try:
            result = set_active([_layer_for(name) for name in state.active])
        except LayerError as error:
            self._settle(state, applied=False, error=error)
            return
        if result.deferred and not result.done:
            with self._deferred_lock:
                self._deferred.append((state, result))
            self._run(self.protocol.deferred(state, time.monotonic()))
            threading.Thread(target=self._wait_for, args=(result,), daemon=True).start()
            return
        self._settle(state, result.applied, result.error)

    def _wait_for(self, result: SwitchResult) -> None:
        result.wait()
        self._handed_back.trigger()

    def _settle(self, state: LayerState, applied: bool, error: LayerError | None) -> None:
        now = time.monotonic()
        # An on_activate hook that raised still leaves the new configuration installed.
        installed = tuple(layer.name for layer in active_layers()) == state.active
        if error is not None and installed:
            self.node.get_logger().warning(f"epoch {state.epoch} applied, but {error}")
        if state.epoch <= self.protocol.applied_epoch:
            return  # a deferred older switch settling after a newer one applied directly
        if applied or installed:
            self.state = state
            self._run(self.protocol.applied(state, now))
            for listener in list(self._listeners):
                try:
                    listener(state)
                except Exception as failure:  # a listener must not stop the node
                    self.node.get_logger().error(f"state listener {listener!r} failed: {failure!r}")
        else:
            why = str(error) if error else "the switch was dropped"
            self.node.get_logger().error(f"cannot apply epoch {state.epoch}: {why}")
            self._run(self.protocol.failed(state, why, now))


# The states every participant of the process received last, decoded once for all of them.
_states = StateDecoder()

# The participant each process's context nodes share, by rclpy context.
_shared_participants: dict[Any, ContextParticipant] = {}


class ContextNode(Node):
    """An rclpy Node that follows the Layer manager (see `ContextParticipant`).

    The layer configuration is per process, so the context nodes of one process share one
    participant (`share_participant=True`, the default): the first one carries it, the
    others are announced as hosted by it, and the manager waits for one acknowledgement per
    process. If the carrying node is destroyed first, the next one takes over, with a new
    incarnation but carrying on from the process's applied epoch, layers and manager.
    `share_participant=False` gives the node a participant of its own.
    """

    def __init__(
        self,
        node_name: str,
        *,
        layers: Iterable[Layer | str] | None = None,
        heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD,
        manager_timeout: float = DEFAULT_MANAGER_TIMEOUT,
        share_participant: bool = True,
        **node_options: Any,
    ) -> None:
        super().__init__(node_name, **node_options)
        self._context_layers = None if layers is None else tuple(layers)
        self._heartbeat_period = heartbeat_period
        self._manager_timeout = manager_timeout
        shared = _shared_participants.get(self.context) if share_participant else None
        if shared is not None:
            shared.host(self, self._context_layers)
            self.context_participant = shared
            return
        self.context_participant = ContextParticipant(
            self,
            self._context_layers,
            heartbeat_period=heartbeat_period,
            manager_timeout=manager_timeout,
        )
        if share_participant:
            _shared_participants[self.context] = self.context_participant

    def destroy_node(self) -> None:
        participant = self.context_participant
        if participant.node is not self:
            participant.release(self)
        else:
            hosted = [
                node
                for node in participant.hosted()
                if isinstance(node, ContextNode) and node.context_participant is participant
            ]
            participant.close()
            if _shared_participants.get(self.context) is participant:
                del _shared_participants[self.context]
            if hosted:
                _hand_over(participant, hosted)
        super().destroy_node()


def _hand_over(previous: ContextParticipant, hosted: list[ContextNode]) -> None:
    """The next context node of the process carries the shared participant from now on."""
    successor, *others = hosted
    participant = ContextParticipant(
        successor,
        successor._context_layers,
        heartbeat_period=successor._heartbeat_period,
        manager_timeout=successor._manager_timeout,
        _previous=previous,
    )
    participant._listeners = previous._listeners
    participant._manager_listeners = previous._manager_listeners
    participant._vetoes = previous._vetoes
    for node in others:
        participant.host(node, node._context_layers)
    for node in hosted:
        node.context_participant = participant
    _shared_participants[successor.context] = participant
