"""What `contextros watch` reports, as pure logic: messages in, records out.

The ROS side (`ros_commands.run_watch`) only feeds the state and status messages it
receives, the manager's registry answers, with the clocks' readings, and prints the
records; the decisions (which nodes must apply an epoch, whether each applied, refused or
skipped it, what is a replayed old state) live here, where tests can drive any order of
arrival.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from contextros.protocol import DEFAULT_MANAGER_TIMEOUT
from contextros.protocol.relations import LayerDeclaration, implied_by
from contextros.protocol.validation import MAX_LAYERS

Record = dict[str, Any]
# Epochs remembered per node (applied, refused): enough for the switches still waited for.
HISTORY = 64
# Longest text (a node's name, a refusal's reason) a record carries: everything comes from
# the network.
MAX_TEXT = 500
# A node heard this shortly before a registry query may not be registered yet when the
# manager answers: it is not taken for dropped.
REGISTRY_GRACE = 0.5
# Layer declarations remembered from the statuses (to show which layers imply which).
MAX_DECLARED = 4096


@dataclass
class _Node:
    last_heard: float  # monotonic
    first_applied: int  # its applied epoch when first heard: older epochs cannot be judged
    applied: int = 0
    hosted: tuple[str, ...] = ()
    applied_seen: deque[int] = field(default_factory=lambda: deque(maxlen=HISTORY))
    refused: OrderedDict[int, str] = field(default_factory=OrderedDict)


@dataclass
class _Epoch:
    published: float  # wall-clock stamp of the state message
    nodes: set[str]  # the live nodes that must apply it
    pending: set[str]
    done_at: float  # wall clock when the last of them was seen settling it
    learning: bool  # published before the watch knew every live node
    refused: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, int] = field(default_factory=dict)  # node: the epoch it went to


# After the liveness bound, the time for one more registry answer (polled twice a second).
UNSETTLED_GRACE = 1.0


@dataclass
class SwitchWatch:
    """Follows the layer states, the participants' statuses and the manager's registry.

    - The first state (the manager's transient-local state as it stood when the watch
      connected), and any state stamped before the watch started, is a *replayed* one:
      it carries its age, not a delivery latency.
    - The nodes that must apply a switch are the ones the manager counts: the participants
      its registry lists (`registry`, the latest answer), plus any heard since that query
      was sent, each with the nodes of its process it speaks for (hosted nodes). Before a
      first answer (or without a manager answering), the nodes heard within the liveness
      bound.
    - A switch is applied by all once every such node reported applying that very epoch,
      whichever of the state and the status reached the watch first. A node that refused
      it (its status names the epoch it could not apply, and why) or went on to a newer
      epoch without applying it is reported, and the switch is then *not* applied by all.
    - A watch knows every live node once the registry answered or it has listened for the
      liveness bound: a switch before then also waits for the nodes first heard until
      then (`tick` says when it knows), and is not "applied by all 0 live node(s)".
    """

    started: float  # wall clock when the watch subscribed
    # Without a registry answer, a node silent this long is no longer counted.
    liveness: float = DEFAULT_MANAGER_TIMEOUT
    switches: int = 0
    last_switch: float = 0.0  # monotonic
    _seen_state: bool = False
    _waiting: dict[int, _Epoch] = field(default_factory=dict)
    _nodes: dict[str, _Node] = field(default_factory=dict)
    # The manager's live participants (with their hosted nodes) and when that was asked.
    _registry: dict[str, tuple[str, ...]] | None = None
    _registry_asked: float = 0.0  # monotonic
    _left: dict[str, float] = field(default_factory=dict)  # left (monotonic), not yet in an answer
    _declared: dict[str, LayerDeclaration] = field(default_factory=dict)  # by layer name

    def live_nodes(self, now: float) -> set[str]:
        if self._registry is None:
            return {n for n, r in self._nodes.items() if now - r.last_heard < self.liveness}
        recent = self._registry_asked - REGISTRY_GRACE
        since = {n for n, r in self._nodes.items() if r.last_heard >= recent}
        return (set(self._registry) | since) - set(self._left)

    def knows_every_node(self, wall: float) -> bool:
        return self._registry is not None or wall - self.started >= self.liveness

    def state(
        self,
        epoch: int,
        active: list[str],
        requester: str,
        reason: str,
        published: float,
        wall: float,
        now: float,
    ) -> list[Record]:
        replayed = not self._seen_state or published < self.started
        self._seen_state = True
        record: Record = {
            "event": "current" if replayed else "state",
            "epoch": epoch,
            "active": list(active),
            "requester": requester,
            "reason": reason,
            "replayed": replayed,
        }
        implied = implied_by(active, self._declared)
        if implied:  # {"Propulsion": ["Flight"]}: which active layers imply which
            record["implied_by"] = {name: list(by) for name, by in implied.items()}
        if replayed:
            record["age_s"] = round(wall - published, 3)
        else:
            record["delivery_ms"] = round((wall - published) * 1000, 3)
        self.last_switch = now
        records = [record]
        if replayed:
            return records
        self.switches += 1
        live = self.live_nodes(now)
        waiting = _Epoch(
            published, live, set(live), done_at=wall, learning=not self.knows_every_node(wall)
        )
        self._waiting[epoch] = waiting
        for node in sorted(live):
            records += self._judge(epoch, waiting, node, wall, timed=False)
        return records + self.tick(wall)

    def declared(self, layers: Iterable[LayerDeclaration]) -> None:
        """What a participant's status declares (the watch shows what implies what)."""
        for layer in list(layers)[:MAX_LAYERS]:
            known = self._declared.get(layer.name)
            self._declared[layer.name] = layer if known is None else known.merged(layer)
        while len(self._declared) > MAX_DECLARED:
            self._declared.pop(next(iter(self._declared)))

    def status(
        self,
        node: str,
        applied_epoch: int,
        leaving: bool,
        wall: float,
        now: float,
        failed_epoch: int = 0,
        error: str = "",
        hosted: tuple[str, ...] = (),
    ) -> list[Record]:
        """A participant's status: `failed_epoch` the newest epoch it could not apply and
        `error` why, `hosted` the other nodes of its process it speaks for."""
        node = node[:MAX_TEXT]
        records: list[Record] = []
        known = self._nodes.get(node)
        if leaving:
            if known is not None and node in self.live_nodes(now):
                records.append({"event": "node-left", "node": node})
            self._nodes.pop(node, None)
            if self._registry is not None:  # (without one, silence decides)
                self._left[node] = now
            for waiting in self._waiting.values():
                waiting.nodes.discard(node)
                if node in waiting.pending:
                    waiting.pending.discard(node)
                    waiting.done_at = wall
            return records + self.tick(wall)
        if node not in self.live_nodes(now):
            records.append({"event": "node", "node": node})
        self._left.pop(node, None)
        first = known is None
        if known is None:
            known = self._nodes[node] = _Node(now, first_applied=applied_epoch)
        known.last_heard = now
        known.hosted = tuple(h[:MAX_TEXT] for h in hosted[:HISTORY])
        if applied_epoch > known.applied:
            known.applied = applied_epoch
            known.applied_seen.append(applied_epoch)
        elif first:
            known.applied_seen.append(applied_epoch)
        if failed_epoch and failed_epoch not in known.refused:
            known.refused[failed_epoch] = error[:MAX_TEXT]
            while len(known.refused) > HISTORY:
                known.refused.popitem(last=False)
        learning = not self.knows_every_node(wall)
        for epoch, waiting in sorted(self._waiting.items()):
            if waiting.learning and learning and node not in waiting.nodes:
                waiting.nodes.add(node)  # live all along, heard only now
                waiting.pending.add(node)
            records += self._judge(epoch, waiting, node, wall, timed=not first)
        return records + self.tick(wall)

    def registry(
        self, nodes: dict[str, tuple[str, ...]], asked: float, wall: float
    ) -> list[Record]:
        """The manager's answer to a registry query sent at `asked` (monotonic): its live
        participants, each with the nodes it hosts. The nodes it no longer lists (and not
        heard since the query) were dropped: no switch waits for them any more."""
        first = self._registry is None
        before = self.live_nodes(asked)
        self._registry = {
            node[:MAX_TEXT]: tuple(h[:MAX_TEXT] for h in hosted[:HISTORY])
            for node, hosted in nodes.items()
        }
        self._registry_asked = asked
        self._left = {node: at for node, at in self._left.items() if at >= asked}
        live = self.live_nodes(asked)
        records: list[Record] = [{"event": "node", "node": n} for n in sorted(live - before)]
        for node in sorted(set(self._nodes) - live):
            del self._nodes[node]
            if node in before:
                records.append({"event": "node-left", "node": node, "dropped": True})
        for waiting in self._waiting.values():
            if waiting.learning and first:
                waiting.pending |= live - waiting.nodes
                waiting.nodes |= live
            for node in sorted(waiting.pending - live):
                waiting.nodes.discard(node)
                waiting.pending.discard(node)
                waiting.done_at = wall
        return records + self.tick(wall)

    def _judge(
        self, epoch: int, waiting: _Epoch, node: str, wall: float, timed: bool
    ) -> list[Record]:
        """Whether `node` applied, refused or skipped `epoch`, if its statuses say so yet."""
        known = self._nodes.get(node)
        if node not in waiting.pending or known is None:
            return []
        records: list[Record] = []
        went_to = max(known.applied, *known.refused) if known.refused else known.applied
        if epoch in known.refused:
            waiting.refused[node] = known.refused[epoch]
            records.append(
                {"event": "refused", "epoch": epoch, "node": node, "error": known.refused[epoch]}
            )
        elif epoch in known.applied_seen or epoch < known.first_applied:
            pass  # applied (first heard past it: applied before, not timed)
        elif went_to > epoch:
            waiting.skipped[node] = went_to
            records.append({"event": "skipped", "epoch": epoch, "node": node, "went_to": went_to})
        else:
            return []  # not there yet
        waiting.pending.discard(node)
        if timed:
            waiting.done_at = wall
        return records

    def tick(self, wall: float) -> list[Record]:
        """The switches every node settled that can be reported now (call it now and then:
        a switch in the watch's first seconds is reported once it knows every node)."""
        if not self.knows_every_node(wall):
            return []
        done = [epoch for epoch, waiting in sorted(self._waiting.items()) if not waiting.pending]
        return [self._settled_record(epoch) for epoch in done]

    def _names(self, nodes: set[str]) -> set[str]:
        """`nodes` with the nodes their processes host (the manager counts those too)."""
        names = set(nodes)
        for node in nodes:
            known = self._nodes.get(node)
            hosted = known.hosted if known is not None else ()
            names.update(hosted or (self._registry or {}).get(node, ()))
        return names

    def _settled_record(self, epoch: int) -> Record:
        waiting = self._waiting.pop(epoch)
        latency = round((waiting.done_at - waiting.published) * 1000, 3)
        if not waiting.refused and not waiting.skipped:
            return {
                "event": "applied",
                "epoch": epoch,
                "nodes": len(self._names(waiting.nodes)),
                "latency_ms": latency,
            }
        missed = set(waiting.refused) | set(waiting.skipped)
        return {
            "event": "not-applied",
            "epoch": epoch,
            "nodes": len(self._names(waiting.nodes)),
            "applied_by": sorted(self._names(waiting.nodes - missed)),
            "refused_by": sorted(self._names(set(waiting.refused))),
            "skipped_by": sorted(self._names(set(waiting.skipped))),
        }

    def finished(self, count: int | None, now: float, wall: float) -> bool:
        """After the last counted switch, wait (a little) for its acknowledgements too,
        once the watch knows every node."""
        if count is None or self.switches < count:
            return False
        if not self._waiting:
            return True
        if not self.knows_every_node(wall):
            return False
        if any(not waiting.pending for waiting in self._waiting.values()):
            return False  # settled: `tick` reports it first
        # A live node reports within the liveness bound, or the manager drops it (and the
        # registry says so): past that (and a poll), `unsettled` names who never answered.
        return now - self.last_switch > self.liveness + UNSETTLED_GRACE

    def unsettled(self) -> list[Record]:
        """The switches still waiting when a counted watch ends, with the nodes not heard
        applying them (call it once `finished` said so)."""
        records: list[Record] = []
        for epoch in sorted(self._waiting):
            waiting = self._waiting.pop(epoch)
            records.append(
                {
                    "event": "unsettled",
                    "epoch": epoch,
                    "nodes": len(self._names(waiting.nodes)),
                    "pending": sorted(self._names(waiting.pending)),
                }
            )
        return records
