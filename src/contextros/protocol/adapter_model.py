"""What the rclpy adapter (`contextros.ros`) does around the pure protocol that the checks
of a whole run depend on: what the state file holds and when it is written, and when a
node's application is asked to veto a proposal. The simulation and the explorer both
drive the protocol through these; keep them in step with the adapter.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from contextros.protocol.events import DURABLE, ManagerAction, ParticipantAction
from contextros.protocol.invariants import Invariants
from contextros.protocol.manager import ManagerProtocol
from contextros.protocol.participant import ParticipantProtocol
from contextros.protocol.state import LayerState, ManagerMemory


def state_file(
    saved: ManagerMemory | None, manager: ManagerProtocol, actions: Sequence[ManagerAction]
) -> ManagerMemory | None:
    """What the state file holds once the manager handled an event, holding `saved`
    before, and returned `actions`: its memory (state, highest epoch proposed, participants
    known live), written before those actions go out if one of them is durable."""
    if any(isinstance(action, DURABLE) for action in actions):
        return manager.memory()
    return saved


def deliver_proposal(
    invariants: Invariants,
    protocol: ParticipantProtocol,
    proposal: LayerState,
    now: float,
    application_veto: Callable[[LayerState], str],
) -> list[ParticipantAction]:
    """A proposal reaches a participant whose application has vetoes, handled as the
    adapter's `_on_proposal` handles it: the vetoes are asked only when the protocol wants
    a vote (`wants_vote`), then the node votes. (The adapter asks them in a thread and
    votes when they answer; here they answer at once, one of the interleavings.)"""
    if not protocol.wants_vote(proposal):
        return protocol.receive_proposal(proposal, now)
    invariants.veto_asked(protocol.node, protocol.incarnation, proposal)
    return protocol.receive_proposal(proposal, now, application_veto(proposal))
