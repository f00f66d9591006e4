"""The records the manager keeps: one per live participant, per synchronous activation
waiting for its nodes, per atomic activation in its vote. Plain data, used by every part."""

from __future__ import annotations

from dataclasses import dataclass, field

from contextros.protocol.events import ActivationCommand, ParticipantReport
from contextros.protocol.state import KnownParticipant, LayerState

# A participant is one process under one incarnation; a node name may (wrongly) be used
# by two live processes at once, so the registry is keyed by both.
Key = tuple[str, str]


@dataclass
class ParticipantRecord:
    report: ParticipantReport
    last_heard: float
    # Known from the state file, not heard since this manager started.
    presumed: bool = False
    # What the state file keeps of it (`known`), made once per record.
    _known: KnownParticipant | None = field(default=None, repr=False, compare=False)

    def known(self) -> KnownParticipant:
        if self._known is None:
            report = self.report
            self._known = KnownParticipant(report.node, report.incarnation, report.hosted)
        return self._known


@dataclass
class PendingActivation:
    command: ActivationCommand
    state: LayerState
    started: float
    deadline: float
    waiting: set[Key]
    acknowledged: set[Key] = field(default_factory=set)
    lost: dict[Key, str] = field(default_factory=dict)
    failed: dict[Key, str] = field(default_factory=dict)
    changed: bool = True
    # How the declared `after` orders moved the requested layers ("" if they did not).
    note: str = ""


@dataclass
class Transaction:
    """An atomic activation in its voting phase: `proposal` is committed only if every
    target votes yes before `deadline`."""

    command: ActivationCommand
    proposal: LayerState
    started: float
    deadline: float
    targets: set[Key]
    timeout: float
    # Kept by `_count_votes` between full counts: the targets that voted.
    voted: set[Key] = field(default_factory=set)
    counted: bool = False
    # The proposal's layers asked for explicitly (None: as `_publish` derives them).
    explicit: tuple[str, ...] | None = None
