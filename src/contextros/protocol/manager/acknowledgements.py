"""Synchronous activations waiting for their acknowledgements, and their honest answers.

One succeeds only if every participant live when it was issued, every node it named and at
least the count it asked for (one at least) applied its epoch or a newer one; else it fails
naming the nodes and why. A command naming a layer whose effect the manager applies itself
(`ManagerSettings.applied_by_manager`: its bindings, set before the state is published; or a
layer only its layer files declare), or one implying such a layer, needs no node: with none
live it is applied by 0 nodes. The
answer carries its own epoch and that epoch's active layers.
"""

from __future__ import annotations

from collections.abc import Iterable

from contextros.protocol.events import ActivationResult, ManagerAction, Reply
from contextros.protocol.manager.base import NO_CHANGE, ManagerBase
from contextros.protocol.manager.records import Key, PendingActivation
from contextros.protocol.relations import implied_layers
from contextros.protocol.validation import listing


class Acknowledgements(ManagerBase):
    """The pending synchronous activations (`_pending`)."""

    @property
    def awaiting_acknowledgements(self) -> bool:
        """A synchronous activation waits for acknowledgements still to come."""
        return any(pending.waiting for pending in self._pending)

    def _settle_pending(
        self, now: float, examine: Iterable[Key] | None = None
    ) -> list[ManagerAction]:
        """Answer the pending activations that are decided. Only the participants in
        `examine` changed since the last call (None: look at every one): a status is then
        one lookup per pending activation, not a pass over every node it waits for."""
        replies: list[ManagerAction] = []
        still_pending: list[PendingActivation] = []
        keys = None if examine is None else tuple(examine)
        for pending in self._pending:
            epoch = pending.state.epoch
            self._add_expected(pending, keys)
            for key in sorted(pending.waiting) if keys is None else keys:
                if key not in pending.waiting:
                    continue
                report = self._participants[key].report
                if report.applied_epoch >= epoch:
                    pending.waiting.discard(key)
                    pending.acknowledged.add(key)
                elif report.failed_epoch >= epoch:
                    pending.waiting.discard(key)
                    pending.failed[key] = f"failed to apply: {report.error or 'no reason given'}"
            if not pending.waiting:
                missing = self._missing(pending)
                # Expected nodes may still join; without expectations, nobody left to wait
                # for decides the answer (and reaching no node at all is a failure).
                expecting = pending.command.expect_nodes or pending.command.expect_count
                if not missing or pending.lost or pending.failed or not expecting:
                    replies.append(self._finish(pending, now, timed_out=False))
                    continue
            if now >= pending.deadline:
                replies.append(self._finish(pending, now, timed_out=True))
            else:
                still_pending.append(pending)
        self._pending = still_pending
        return replies

    def _add_expected(self, pending: PendingActivation, keys: tuple[Key, ...] | None) -> None:
        """A node that (re)joined after the command is waited for too when the requester
        named it, or while fewer nodes than `expect_count` acknowledged (`keys`: the
        participants to look at, None: all)."""
        wanted = set(pending.command.expect_nodes)
        count = pending.command.expect_count
        if not wanted and not count:
            return
        short = count > 0 and len(self._acknowledged_names(pending)) < count
        for key in self._participants if keys is None else keys:
            record = self._participants.get(key)
            if record is None or key in pending.waiting or key in pending.acknowledged:
                continue
            if key in pending.lost or key in pending.failed:
                continue
            if short or {key[0], *record.report.hosted} & wanted:
                pending.waiting.add(key)

    def _await_rejoined(self, key: Key) -> None:
        """A node the manager had dropped is back: a pending synchronous command waits for
        it too (its answer must not say "every node" without it), unless it was lost to
        that very command (its answer names it dropped already)."""
        for pending in self._pending:
            if key not in pending.acknowledged and key not in pending.lost:
                pending.waiting.add(key)

    def _acknowledged_names(self, pending: PendingActivation) -> set[str]:
        """Nodes every process of whose name applied the epoch, with the nodes they host."""
        refused = {key[0] for key in (*pending.waiting, *pending.lost, *pending.failed)}
        names: set[str] = set()
        for node, _ in pending.acknowledged:
            if node not in refused:
                names.add(node)
                names.update(self._hosted.get(node, ()))
        return names

    def _missing(self, pending: PendingActivation) -> list[str]:
        """What the requester asked for that is not (yet) acknowledged, as sentences."""
        acknowledged = self._acknowledged_names(pending)
        absent = [n for n in pending.command.expect_nodes if n not in acknowledged]
        problems = [f"expected node {listing(absent)} did not apply it"] if absent else []
        wanted = pending.command.expect_count
        if not wanted and not acknowledged and not self._applied_by_manager(pending):
            wanted = 1  # at least one node, unless the manager applies its effect itself
        if len(acknowledged) < wanted:
            problems.append(
                f"applied by {len(acknowledged)} node(s), {wanted} expected"
                if pending.command.expect_count
                else "it reached no node"
            )
        return problems

    def _finish(self, pending: PendingActivation, now: float, timed_out: bool) -> Reply:
        conflicts = set(self.conflicts())
        reasons: dict[str, str] = {}
        for key, why in [*pending.lost.items(), *pending.failed.items()]:
            reasons[key[0]] = why
        if timed_out:
            for key in pending.waiting:
                reasons[key[0]] = self._why_not_applied(key, pending.state.epoch)
        for node in list(reasons):
            if node in conflicts:
                reasons[node] += "; two live processes are named so"
        # A participant speaks for the other nodes of its process: name them too.
        for node, why in list(reasons.items()):
            for hosted in self._hosted.get(node, ()):
                reasons[hosted] = f"hosted by {node}, {why}"
        acknowledged = self._acknowledged_names(pending) - set(reasons)
        missing = self._missing(pending)
        epoch = pending.state.epoch
        if reasons or missing:
            parts = []
            if reasons:
                limit = f" within {pending.deadline - pending.started:g} s" if timed_out else ""
                shown = sorted(reasons.items())
                listing_ = "; ".join(f"{node} ({why})" for node, why in shown[:20])
                if len(shown) > 20:
                    listing_ += f"; and {len(shown) - 20} more"
                parts.append(f"not acknowledged{limit} by {listing_}")
            parts += missing
            message = f"epoch {epoch} failed: {'; '.join(parts)}"
            if not reasons:
                message = f"epoch {epoch} not confirmed: {'; '.join(parts)}"
        elif not pending.changed:
            message = f"{NO_CHANGE}: epoch {epoch} already has that configuration"
        else:
            message = f"epoch {epoch} applied by {len(acknowledged)} node(s){pending.note}"
            if not acknowledged:
                message += ", its layers' ROS parameters and lifecycle states by the manager"
        result = ActivationResult(
            success=not reasons and not missing,
            message=message,
            epoch=epoch,
            active=pending.state.active,
            acknowledged=tuple(sorted(acknowledged)),
            not_acknowledged=tuple(sorted(set(reasons) | set(self._absent(pending)))),
            elapsed=now - pending.started,
        )
        return Reply(pending.command.request_id, result)

    def _applied_by_manager(self, pending: PendingActivation) -> bool:
        """The manager itself applies the effect of a layer the command names, or of one
        they imply (a system's mode: its parts' parameters and lifecycle states): one with
        bindings, or one its layer files declare and no live participant implements (it
        took that layer on its own word: its effect is the manager's, its rules' and what
        it implies)."""
        implemented = {
            d.name for record in self._participants.values() for d in record.report.layers
        }
        own = frozenset(d.name for d in self.settings.layer_files) - implemented
        applied = self.settings.applied_by_manager | own
        if not applied:
            return False
        declarations = self.declarations()
        named = (*pending.command.activate, *pending.command.deactivate)
        return any(
            layer in applied
            for name in named
            for layer in (name, *implied_layers(name, declarations))
        )

    def _absent(self, pending: PendingActivation) -> list[str]:
        acknowledged = self._acknowledged_names(pending)
        return [n for n in pending.command.expect_nodes if n not in acknowledged]

    def _why_not_applied(self, key: Key, epoch: int) -> str:
        report = self._participants[key].report
        if report.pending_epoch >= epoch or report.in_critical_section:
            return f"in a critical section, still on epoch {report.applied_epoch}"
        return f"still on epoch {report.applied_epoch}"
