"""How `contextros status` and `watch` show the layers' bindings: what each sets, what the
manager read on the node, and drift (docs/ros-integration.md). Pure: `registry_to_dict`'s
data in, text out."""

from __future__ import annotations

import time
from typing import Any


def binding_rows(data: dict[str, Any]) -> tuple[list[str], list[list[str]]]:
    """The bindings table: header and rows."""
    rows = [
        [
            b["layer"],
            b["node"],
            f"{b['parameter']} = {b['value']}" if b["kind"] == "parameter" else b["value"],
            b.get("policy") or "report",
            _seen(b),
            ("ok: " if b["ok"] else "FAILED: ") + b["last_result"] if b["last_result"] else "-",
        ]
        for b in data["bindings"]
    ]
    return ["BINDING", "NODE", "SETS", "ON DRIFT", "SEEN", "LAST RESULT"], rows


def _seen(binding: dict[str, Any]) -> str:
    observed = binding.get("observed", "")
    if not observed:
        return "-"
    if binding.get("drifted"):
        return f"{observed} DRIFTED"
    return f"{observed} (holds)" if binding.get("holds") else observed


def drift_lines(data: dict[str, Any], now: float | None = None) -> list[str]:
    """One line per binding in force that no longer holds."""
    now = time.time() if now is None else now
    return [drift_line(b, now) for b in data["bindings"] if b.get("drifted")]


def drift_line(binding: dict[str, Any], now: float) -> str:
    """'DRIFT: layer Slow sets /base max_speed = 0.3, the node has 1.5 since 05:24:21 UTC
    (12.3 s); on drift report'."""
    what = (
        f"{binding['node']} {binding['parameter']} = {binding['value']}"
        if binding["kind"] == "parameter"
        else f"lifecycle node {binding['node']} {binding['value']}"
    )
    since = binding.get("drifted_since") or now
    clock = time.strftime("%H:%M:%S", time.gmtime(since))
    line = (
        f"DRIFT: layer {binding['layer']} sets {what}, the node has {binding['observed']} "
        f"since {clock} UTC ({max(now - since, 0):.1f} s); on drift {binding['policy']}"
    )
    return line + (f": {binding['drift_action']}" if binding.get("drift_action") else "")


def actual_line(data: dict[str, Any]) -> str:
    """Target against actual: the layers the manager made active that set something, and
    the layers whose bindings all hold on the nodes ("" without bindings)."""
    if not data["bindings"]:
        return ""
    bound = {b["layer"] for b in data["bindings"]}
    target = [name for name in data["active"] if name in bound]
    actual = data.get("actual", [])
    verdict = "the same" if sorted(target) == sorted(actual) else "they DIFFER"
    return (
        f"bound layers: target [{', '.join(target) or 'none'}], actual (bindings all hold) "
        f"[{', '.join(actual) or 'none'}]: {verdict}"
    )


# What a watch keeps of the manager's answers at most (they come from the network).
MAX_BINDINGS = 1000
MAX_TEXT = 500


class DriftWatch:
    """`contextros watch`'s drift events, from the manager's registry answers (polled):
    `drift` when a binding in force stops holding (or what the manager did about it
    changes), `drift-over` when it holds again or is no longer in force."""

    def __init__(self) -> None:
        self._drifted: dict[tuple[str, str, str], tuple[float, str]] = {}

    def bindings(self, bindings: list[dict[str, Any]]) -> list[dict[str, Any]]:
        records: list[dict[str, Any]] = []
        now: dict[tuple[str, str, str], tuple[float, str]] = {}
        for b in bindings[:MAX_BINDINGS]:
            b = {k: v[:MAX_TEXT] if isinstance(v, str) else v for k, v in b.items()}
            key = (b["layer"], b["node"], b["parameter"])
            if not b.get("drifted"):
                if key in self._drifted:
                    records.append({"event": "drift-over", **_named(b), "seen": b["observed"]})
                continue
            now[key] = (b.get("drifted_since") or 0.0, b.get("drift_action", ""))
            if self._drifted.get(key) != now[key]:
                records.append(
                    {
                        "event": "drift",
                        **_named(b),
                        "sets": b["value"],
                        "seen": b["observed"],
                        "since": b.get("drifted_since"),
                        "policy": b.get("policy", "report"),
                        "action": b.get("drift_action", ""),
                    }
                )
        self._drifted = now
        return records


def _named(binding: dict[str, Any]) -> dict[str, Any]:
    return {
        "layer": binding["layer"],
        "kind": binding["kind"],
        "node": binding["node"],
        "parameter": binding["parameter"],
    }


def drift_record_line(record: dict[str, Any]) -> str:
    """A `drift` or `drift-over` record as `watch` prints it."""
    if record["event"] == "drift-over":
        what = record["parameter"] or "lifecycle state"
        return (
            f"drift over: layer {record['layer']}'s {record['node']} {what} holds again "
            f"({record['seen'] or 'not read'}, or its layer is no longer active)"
        )
    binding = {
        **record,
        "value": record["sets"],
        "observed": record["seen"],
        "drifted_since": record["since"],
        "drift_action": record["action"],
    }
    return drift_line(binding, time.time())
