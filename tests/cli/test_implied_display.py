"""`contextros status` and `watch` say which active layers are implied, and by what
(issue 28, item 1): `Propulsion (implied by Flight)`."""

from __future__ import annotations

import pytest

from contextros.cli.ros_commands import _print_watch, _registry_as_text
from contextros.cli.watching import SwitchWatch
from contextros.protocol.relations import LayerDeclaration

HIERARCHY = (
    LayerDeclaration("Mission", implies=frozenset({"Flight"})),
    LayerDeclaration("Flight", implies=frozenset({"Propulsion", "CameraHigh"})),
    LayerDeclaration("Propulsion"),
    LayerDeclaration("CameraHigh"),
)
ACTIVE = ["CameraHigh", "Propulsion", "Flight", "Mission"]


def test_watch_records_and_prints_what_implies_what(capsys: pytest.CaptureFixture[str]) -> None:
    watch = SwitchWatch(started=90.0)
    watch.declared(HIERARCHY)
    (record,) = watch.state(4, ACTIVE, "cli", "go", published=100.0, wall=100.001, now=1.0)
    assert record["implied_by"] == {
        "CameraHigh": ["Flight"],
        "Flight": ["Mission"],
        "Propulsion": ["Flight"],
    }
    _print_watch(False, record)
    line = capsys.readouterr().out
    assert (
        "[CameraHigh (implied by Flight), Propulsion (implied by Flight), "
        "Flight (implied by Mission), Mission]" in line
    )


def test_a_state_without_implied_layers_has_no_such_field() -> None:
    watch = SwitchWatch(started=90.0)
    watch.declared(HIERARCHY)
    (record,) = watch.state(4, ["Propulsion"], "cli", "", published=100.0, wall=100.0, now=1.0)
    assert "implied_by" not in record


def test_status_text_shows_the_implied_layers_and_the_implies_column() -> None:
    data = {
        "epoch": 7,
        "active": ACTIVE,
        "requester": "cli",
        "reason": "",
        "recovering": False,
        "declared_order": [],
        "implied_by": {"CameraHigh": ["Flight"], "Flight": ["Mission"], "Propulsion": ["Flight"]},
        "layers": [
            {
                "name": d.name,
                "group": "",
                "excludes": [],
                "requires": [],
                "after": [],
                "implies": sorted(d.implies),
                "implemented_by": ["/drone"],
            }
            for d in HIERARCHY
        ],
        "participants": [],
        "conflicts": [],
        "dropped": [],
        "rules": [],
        "bindings": [],
    }
    text = _registry_as_text(data)
    assert "active [CameraHigh (implied by Flight), Propulsion (implied by Flight)," in text
    rows = {line.split()[0]: line for line in text.splitlines() if line.startswith(("F", "M"))}
    assert "implied by Mission" in rows["Flight"] and "CameraHigh, Propulsion" in rows["Flight"]
    assert "yes" in rows["Mission"] and "IMPLIES" in text
