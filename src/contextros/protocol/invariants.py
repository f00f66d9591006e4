"""The promises of docs/protocol.md as checks on what a run of the whole protocol does.

The simulation (random runs at scale, `simulation.py`) and the explorer (every interleaving
up to a bound, `explorer.py`) drive the same pure `ManagerProtocol` and
`ParticipantProtocol`, and feed one `Invariants` with what they see: every action a manager
or a participant returns, every command, the manager's crashes and restarts and every time
a node's application is asked to veto a proposal. Each check has a name (`ALL`); a run may
leave some out (the simulation's tests leave out those the code is known to break, and
check them on their own).

Everything it keeps is plain data (the explorer copies and hashes it with the rest of a
state): a history, not a model of the protocol.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from contextros.protocol.events import (
    ActivationCommand,
    ActivationResult,
    ApplyState,
    ManagerAction,
    ParticipantAction,
    ParticipantDropped,
    ParticipantReport,
    PublishProposal,
    PublishState,
    PublishStatus,
    Reply,
    StateRejected,
)
from contextros.protocol.state import LayerState

# An epoch names one layer set among the states published and applied.
EPOCHS = "epochs"
# ... and among the proposals too, whichever manager made them, forever (issue 24 item 1:
# a manager killed mid-vote and restarted with its state file reused the proposed epoch).
PROPOSAL_EPOCHS = "proposal-epochs"
# A participant incarnation applies strictly increasing epochs.
NO_REGRESSION = "no-regression"
# An aborted atomic activation's epoch is never published nor applied.
ABORTS = "aborts"
# One answer per command; a success carries its epoch's layers; a synchronous success
# reached a node, and every node it names applied its epoch.
ANSWERS = "answers"
# A synchronous (or atomic) success names every node live in the manager when the command
# arrived, unless the manager dropped it since.
SYNC_NAMES_LIVE = "sync-names-live"
# ... and after a restart with a state file, every node its predecessor knew live, until
# the new manager drops it or has not heard it for `liveness_timeout` since its start
# (issue 24 item 2: the first sync after a restart claimed success with one of two nodes).
SYNC_NAMES_KNOWN = "sync-names-known"
# A node's vote on one proposal (manager, epoch) never changes in its reports.
ONE_VOTE = "one-vote"
# A node's application is asked to veto one proposal once (issue 24 item 4: the veto ran
# at every repeat of the proposal).
ONE_VETO = "one-veto"

ALL = frozenset(
    {
        EPOCHS,
        PROPOSAL_EPOCHS,
        NO_REGRESSION,
        ABORTS,
        ANSWERS,
        SYNC_NAMES_LIVE,
        SYNC_NAMES_KNOWN,
        ONE_VOTE,
        ONE_VETO,
    }
)

# What the protocol is known to break: runs leave it out unless asked to check everything.
# Nothing since a node remembers the newest proposal it voted on per manager (issue 24 item
# 4: a late copy of an older proposal was voted on, and its vetoes asked, again).
KNOWN_BROKEN: frozenset[str] = frozenset()


def add_check_all_option(parser: argparse.ArgumentParser) -> None:
    """`--check-all` for a command running the protocol (simulation, explorer)."""
    known = ", ".join(sorted(KNOWN_BROKEN)) or "nothing at present"
    parser.add_argument(
        "--check-all",
        action="store_true",
        help=f"check also what the protocol is known to break ({known})",
    )


def checked_invariants(check_all: bool) -> frozenset[str]:
    """The invariants a run checks: all, or all but the known broken ones."""
    return ALL if check_all else ALL - KNOWN_BROKEN


# How an answer says which proposed epoch an atomic activation aborted.
_ABORTED = re.compile(r"atomic activation of epoch (\d+) aborted")


class InvariantViolation(AssertionError):
    """A guarantee of docs/protocol.md broke in a run; `invariant` names which one."""

    def __init__(self, message: str, invariant: str = "") -> None:
        super().__init__(message)
        self.invariant = invariant


@dataclass
class _Asked:
    command: ActivationCommand
    manager_id: str
    # Node names a synchronous success must name (as `required_known`, those only the
    # predecessor of a restarted manager knew live).
    required: set[str] = field(default_factory=set)
    required_known: set[str] = field(default_factory=set)
    answered: bool = False


@dataclass
class _Restart:
    """What a manager started with a state file has reason to believe: its predecessor's
    live nodes, until it drops one or `until`."""

    known: frozenset[str]
    until: float
    dropped: set[str] = field(default_factory=set)


@dataclass
class Invariants:
    checked: frozenset[str] = ALL
    # Turns what broke into the violation's message (say, with the seed that replays it).
    describe: Callable[[str], str] | None = field(default=None, compare=False, repr=False)
    # Epoch -> its layers and whether a proposal named it first (`named_by`: who, in words).
    layers_of_epoch: dict[int, tuple[tuple[str, ...], bool]] = field(default_factory=dict)
    named_by: dict[int, str] = field(default_factory=dict)
    proposed: set[tuple[str, int]] = field(default_factory=set)  # (manager id, epoch)
    published: set[tuple[str, int]] = field(default_factory=set)
    aborted: set[tuple[str, int]] = field(default_factory=set)
    last_applied: dict[tuple[str, str], int] = field(default_factory=dict)
    ever_applied: dict[str, int] = field(default_factory=dict)
    votes: dict[tuple[str, str, str, int], tuple[bool, str]] = field(default_factory=dict)
    vetoes_asked: set[tuple[str, str, str, int]] = field(default_factory=set)
    asked: dict[int, _Asked] = field(default_factory=dict)
    restart: _Restart | None = None

    def fingerprint(self) -> tuple[object, ...]:
        """The history as far as later checks depend on it, whatever order it came in (for
        the explorer's state hashing): no descriptions, sets for dictionaries."""
        restart = self.restart
        return (
            frozenset((epoch, *known) for epoch, known in self.layers_of_epoch.items()),
            frozenset(self.proposed),
            frozenset(self.published),
            frozenset(self.aborted),
            frozenset(self.last_applied.items()),
            frozenset(self.ever_applied.items()),
            frozenset(self.votes.items()),
            frozenset(self.vetoes_asked),
            frozenset(
                (request, a.manager_id, frozenset(a.required), frozenset(a.required_known))
                for request, a in self.asked.items()
                if not a.answered
            ),
            frozenset(request for request, a in self.asked.items() if a.answered),
            None if restart is None else (restart.known, restart.until, frozenset(restart.dropped)),
        )

    # -- what the driver reports ------------------------------------------------------------

    def manager_started(
        self, manager_id: str, now: float, liveness_timeout: float, state_file: bool
    ) -> None:
        """A manager (re)started; with a state file it knows its predecessor's live nodes
        (`manager_crashed` said which)."""
        known = self.restart.known if self.restart is not None else frozenset()
        if not state_file or not known:
            self.restart = None
        else:
            self.restart = _Restart(known, now + liveness_timeout)

    def manager_crashed(self, live_nodes: Sequence[str], now: float) -> None:
        self.restart = _Restart(frozenset(self._believed_live(live_nodes, now)), 0.0)

    def command(
        self, command: ActivationCommand, manager_id: str, live_nodes: Sequence[str], now: float
    ) -> None:
        """`command` reached the manager `manager_id`, which had these live nodes."""
        if command.request_id in self.asked:
            self._fail(ANSWERS, f"request {command.request_id} asked twice (a driver's bug)")
        asked = _Asked(command, manager_id)
        if command.synchronous or command.atomic:
            asked.required = set(live_nodes)
            asked.required_known = self._believed_live(live_nodes, now) - asked.required
        self.asked[command.request_id] = asked

    def veto_asked(self, node: str, incarnation: str, proposal: LayerState) -> None:
        """The application of `node` was asked whether it vetoes `proposal`."""
        key = (node, incarnation, proposal.manager_id, proposal.epoch)
        if key in self.vetoes_asked:
            self._fail(
                ONE_VETO,
                f"{node}'s veto was asked again about proposal {proposal.epoch} "
                f"{proposal.active} of manager {proposal.manager_id}",
            )
        self.vetoes_asked.add(key)

    def manager_actions(
        self, manager_id: str, actions: Sequence[ManagerAction], now: float
    ) -> None:
        for action in actions:
            if isinstance(action, PublishState):
                self._published(manager_id, action.state)
            elif isinstance(action, PublishProposal):
                self._proposed(manager_id, action.state)
            elif isinstance(action, Reply):
                self._answered(manager_id, action.request_id, action.result)
            elif isinstance(action, ParticipantDropped):
                self._dropped(manager_id, action.node)

    def participant_actions(
        self, node: str, incarnation: str, actions: Sequence[ParticipantAction]
    ) -> None:
        for action in actions:
            if isinstance(action, ApplyState):
                self._applied(node, incarnation, action.state)
            elif isinstance(action, PublishStatus):
                self._reported(action.report)
            elif isinstance(action, StateRejected):
                self._fail(ANSWERS, f"{node} rejected a state of the manager: {action.problems}")

    # -- the checks -------------------------------------------------------------------------

    def _fail(self, invariant: str, what: str) -> None:
        if invariant not in self.checked:
            return
        what = f"{what} [{invariant}]"
        raise InvariantViolation(self.describe(what) if self.describe else what, invariant)

    def _check_epoch(self, state: LayerState, where: str, proposal: bool = False) -> None:
        known = self.layers_of_epoch.get(state.epoch)
        if known is None:
            self.layers_of_epoch[state.epoch] = (state.active, proposal)
            self.named_by[state.epoch] = where
        elif known[0] != state.active:
            self._fail(
                PROPOSAL_EPOCHS if proposal or known[1] else EPOCHS,
                f"epoch {state.epoch} names two layer sets: {known[0]} "
                f"({self.named_by[state.epoch]}) and {state.active} ({where})",
            )

    def _proposed(self, manager_id: str, state: LayerState) -> None:
        self.proposed.add((manager_id, state.epoch))
        if PROPOSAL_EPOCHS in self.checked:
            self._check_epoch(state, f"proposed by manager {manager_id}", proposal=True)

    def _published(self, manager_id: str, state: LayerState) -> None:
        self._check_epoch(state, f"published by manager {manager_id}")
        if (manager_id, state.epoch) in self.aborted:
            self._fail(ABORTS, f"epoch {state.epoch} was published after its atomic abort")
        self.published.add((manager_id, state.epoch))

    def _applied(self, node: str, incarnation: str, state: LayerState) -> None:
        before = self.last_applied.get((node, incarnation), 0)
        if state.epoch <= before:
            self._fail(NO_REGRESSION, f"{node} went back from epoch {before} to {state}")
        if (state.manager_id, state.epoch) in self.aborted:
            self._fail(ABORTS, f"{node} applied aborted epoch {state.epoch}")
        self._check_epoch(state, f"applied by {node}")
        self.last_applied[(node, incarnation)] = state.epoch
        self.ever_applied[node] = max(self.ever_applied.get(node, 0), state.epoch)

    def _reported(self, report: ParticipantReport) -> None:
        if not report.vote_epoch:
            return
        key = (report.node, report.incarnation, report.vote_manager_id, report.vote_epoch)
        vote = (report.vote_yes, report.vote_reason)
        before = self.votes.setdefault(key, vote)
        if before != vote:
            self._fail(
                ONE_VOTE,
                f"{report.node} voted {before} and then {vote} on proposal "
                f"{report.vote_epoch} of manager {report.vote_manager_id}",
            )

    def _dropped(self, manager_id: str, label: str) -> None:
        if " (incarnation " in label:
            return  # another process still reports under that name
        for asked in self.asked.values():
            if asked.manager_id == manager_id:
                asked.required.discard(label)
                asked.required_known.discard(label)
        if self.restart is not None:
            self.restart.dropped.add(label)

    def _believed_live(self, live_nodes: Sequence[str], now: float) -> set[str]:
        """The live nodes, and those the predecessor of a restarted manager knew live."""
        believed = set(live_nodes)
        restart = self.restart
        if restart is not None and now < restart.until and SYNC_NAMES_KNOWN in self.checked:
            believed |= restart.known - restart.dropped
        return believed

    def _answered(self, manager_id: str, request_id: int, result: ActivationResult) -> None:
        asked = self.asked.get(request_id)
        if asked is None:
            self._fail(ANSWERS, f"an answer to request {request_id}, never asked")
            return
        if asked.answered:
            self._fail(ANSWERS, f"a second answer to request {request_id}: {result.message}")
        asked.answered = True
        command = asked.command
        aborted = _ABORTED.search(result.message) if command.atomic else None
        if aborted is not None and not result.success:
            epoch = int(aborted.group(1))
            if (manager_id, epoch) in self.published:
                self._fail(ABORTS, f"atomic epoch {epoch} aborted after it was published")
            self.aborted.add((manager_id, epoch))
        if not result.success:
            return
        known = self.layers_of_epoch.get(result.epoch)
        if known is not None and known[0] != result.active:
            self._fail(
                ANSWERS,
                f"answer to {request_id} says epoch {result.epoch} is {result.active}, "
                f"it is {known[0]}",
            )
        if not (command.synchronous or command.atomic):
            return
        if not result.acknowledged:
            self._fail(ANSWERS, f"synchronous success of request {request_id} reached no node")
        for name in result.acknowledged:
            if self.ever_applied.get(name, 0) < result.epoch:
                self._fail(
                    ANSWERS, f"{name} is said to acknowledge epoch {result.epoch}, never applied it"
                )
        named = set(result.acknowledged)
        missing = sorted(asked.required - named)
        if missing:
            self._fail(
                SYNC_NAMES_LIVE,
                f"synchronous success of request {request_id} ({result.message}) leaves out "
                f"{missing}, live when it arrived",
            )
        missing = sorted(asked.required_known - named)
        if missing:
            self._fail(
                SYNC_NAMES_KNOWN,
                f"synchronous success of request {request_id} ({result.message}) leaves out "
                f"{missing}, live before the manager's restart and not dropped since",
            )
