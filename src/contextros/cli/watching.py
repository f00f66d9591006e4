"""What `contextros watch` reports, as pure logic: messages in, records out.

The ROS side (`ros_commands.run_watch`) only feeds the state and status messages it
receives, with the clocks' readings, and prints the records; the decisions (which nodes
must apply an epoch, when it counts as applied by all, what is a replayed old state)
live here, where tests can drive any order of arrival.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from contextros.protocol import DEFAULT_MANAGER_TIMEOUT

Record = dict[str, Any]


@dataclass
class _Epoch:
    published: float  # wall-clock stamp of the state message
    nodes: set[str]  # the live nodes that must apply it
    pending: set[str]
    done_at: float  # wall clock when the last of them was seen applying it


@dataclass
class SwitchWatch:
    """Follows the layer states and the participants' statuses.

    - The first state (the manager's transient-local state as it stood when the watch
      connected), and any state stamped before the watch started, is a *replayed* one:
      it carries its age, not a delivery latency.
    - A switch is applied by all once every node live at its publication has reported
      an applied epoch at least as new, whichever of the state and the status reached
      the watch first.
    - A watch knows every live node only once it has listened for the liveness bound
      (each is heard every heartbeat, once discovery matched it): a switch in its first
      seconds also waits for the nodes first heard until then (`tick` says when the
      bound has passed), and is not "applied by all 0 live node(s)" for want of them.
    """

    started: float  # wall clock when the watch subscribed
    # A node silent this long is no longer counted: the manager's liveness bound.
    liveness: float = DEFAULT_MANAGER_TIMEOUT
    switches: int = 0
    last_switch: float = 0.0  # monotonic
    _seen_state: bool = False
    _waiting: dict[int, _Epoch] = field(default_factory=dict)
    _last_heard: dict[str, float] = field(default_factory=dict)
    _applied: dict[str, int] = field(default_factory=dict)

    def live_nodes(self, now: float) -> set[str]:
        return {n for n, t in self._last_heard.items() if now - t < self.liveness}

    def knows_every_node(self, wall: float) -> bool:
        return wall - self.started >= self.liveness

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
        pending = {n for n in live if self._applied.get(n, 0) < epoch}
        self._waiting[epoch] = _Epoch(published, live, pending, done_at=wall)
        if not pending and self.knows_every_node(wall):
            records.append(self._applied_record(epoch))
        return records

    def status(
        self, node: str, applied_epoch: int, leaving: bool, wall: float, now: float
    ) -> list[Record]:
        records: list[Record] = []
        if leaving:
            if self._last_heard.pop(node, None) is not None:
                records.append({"event": "node-left", "node": node})
        else:
            if node not in self.live_nodes(now):
                records.append({"event": "node", "node": node})
            self._last_heard[node] = now
        self._applied[node] = max(self._applied.get(node, 0), applied_epoch)
        learning = not self.knows_every_node(wall)
        for epoch, waiting in sorted(self._waiting.items()):
            if learning and not leaving and node not in waiting.nodes:
                waiting.nodes.add(node)  # live all along, heard only now
                if applied_epoch < epoch:  # (one that applied it already: not timed)
                    waiting.pending.add(node)
            if node in waiting.pending and (applied_epoch >= epoch or leaving):
                waiting.pending.discard(node)
                waiting.done_at = wall
            if leaving:
                waiting.nodes.discard(node)
        return records + self.tick(wall)

    def tick(self, wall: float) -> list[Record]:
        """The switches applied by all that can be reported now (call it now and then: a
        switch in the watch's first seconds is reported once it knows every node)."""
        if not self.knows_every_node(wall):
            return []
        done = [epoch for epoch, waiting in sorted(self._waiting.items()) if not waiting.pending]
        return [self._applied_record(epoch) for epoch in done]

    def _applied_record(self, epoch: int) -> Record:
        waiting = self._waiting.pop(epoch)
        latency = (waiting.done_at - waiting.published) * 1000
        return {
            "event": "applied",
            "epoch": epoch,
            "nodes": len(waiting.nodes),
            "latency_ms": round(latency, 3),
        }

    def finished(self, count: int | None, now: float, wall: float) -> bool:
        """After the last counted switch, wait (a little) for its acknowledgements too,
        once the watch knows every node."""
        if count is None or self.switches < count:
            return False
        if not self._waiting:
            return True
        return self.knows_every_node(wall) and now - self.last_switch > 2.0
