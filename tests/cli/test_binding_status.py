"""How status and watch show the bindings' actual state (pure: registry data in, text and
records out)."""

from __future__ import annotations

from typing import Any

from contextros.cli.binding_status import (
    DriftWatch,
    actual_line,
    binding_rows,
    drift_lines,
    drift_record_line,
)


def binding(layer: str = "Slow", **changes: Any) -> dict[str, Any]:
    data = {
        "layer": layer,
        "kind": "parameter",
        "node": "/base",
        "parameter": "max_speed",
        "value": "0.3",
        "ok": True,
        "last_result": "set to 0.3 for Slow",
        "policy": "report",
        "observed": "0.3",
        "holds": True,
        "drifted": False,
        "drifted_since": None,
        "drift_action": "",
    }
    return data | changes


DRIFTED = {"observed": "1.5", "holds": False, "drifted": True, "drifted_since": 100.0}


def test_status_shows_what_the_node_has_and_each_drift() -> None:
    data = {"active": ["Slow", "Night"], "actual": [], "bindings": [binding(**DRIFTED)]}
    header, rows = binding_rows(data)
    assert header[3:5] == ["ON DRIFT", "SEEN"] and rows[0][3:5] == ["report", "1.5 DRIFTED"]
    assert drift_lines(data, now=112.5) == [
        "DRIFT: layer Slow sets /base max_speed = 0.3, the node has 1.5 since 00:01:40 UTC "
        "(12.5 s); on drift report"
    ]
    assert actual_line(data) == (
        "bound layers: target [Slow], actual (bindings all hold) [none]: they DIFFER"
    )
    holding = {"active": ["Slow"], "actual": ["Slow"], "bindings": [binding()]}
    assert binding_rows(holding)[1][0][4] == "0.3 (holds)" and drift_lines(holding) == []
    assert actual_line(holding).endswith("[Slow]: the same")


def test_watch_reports_a_drift_once_what_was_done_and_its_end() -> None:
    watch = DriftWatch()
    assert watch.bindings([binding()]) == []
    (drift,) = watch.bindings([binding(**DRIFTED)])
    assert (drift["event"], drift["sets"], drift["seen"], drift["since"]) == (
        "drift",
        "0.3",
        "1.5",
        100.0,
    )
    assert watch.bindings([binding(**DRIFTED)]) == [], "polled again: nothing new"
    (acted,) = watch.bindings([binding(**DRIFTED, drift_action="set back at 00:01:40")])
    assert drift_record_line(acted).endswith("on drift report: set back at 00:01:40")
    (over,) = watch.bindings([binding()])
    assert over["event"] == "drift-over"
    assert drift_record_line(over).startswith("drift over: layer Slow's /base max_speed holds")


def test_what_a_watch_keeps_is_bounded() -> None:
    drifted = DRIFTED | {"observed": "x" * 10_000}
    records = DriftWatch().bindings([binding(f"L{i}", **drifted) for i in range(5_000)])
    assert len(records) == 1_000 and {len(r["seen"]) for r in records} == {500}
