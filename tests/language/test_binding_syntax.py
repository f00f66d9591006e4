"""`on drift POLICY` after a parameter or lifecycle binding: the policy in the syntax tree,
bad policies located at file:line:col, in both flavours and through `contextros check`."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from contextros.language.flavours import parse_with_diagnostics

HEADER = "layer Slow:\n    def f(): ...\n"


def test_policies_of_parameters_and_lifecycle_items() -> None:
    tree, problems = parse_with_diagnostics(
        HEADER
        + "parameter Slow: base max_speed = 0.3 on drift restore  # set it back\n"
        + "parameter Slow: base mode = 'eco' on drift infer\n"
        + "parameter Slow: base x = 1\n"
        + "lifecycle Slow: prop active on drift restore, wheel inactive, "
        + "cam active on drift infer\n",
        "robot.layers",
    )
    assert problems == []
    assert [(p.name, p.value, p.policy) for p in tree.parameters] == [
        ("max_speed", 0.3, "restore"),
        ("mode", "eco", "infer"),
        ("x", 1, "report"),
    ]
    assert [(c.node, c.state, c.policy, c.at.col) for c in tree.lifecycles] == [
        ("prop", "active", "restore", 17),
        ("wheel", "inactive", "report", 47),
        ("cam", "active", "infer", 63),
    ]


def located(line: str) -> list[tuple[int, int, str]]:
    _, problems = parse_with_diagnostics(HEADER + line + "\n", "robot.layers")
    return [(d.line, d.col, d.message) for d in problems]


def test_an_unknown_policy_is_an_error_at_the_policy() -> None:
    assert located("parameter Slow: base y = 1 on drift restart") == [
        (3, 37, "drift policy 'restart': expected report, restore or infer")
    ]
    assert located("lifecycle Slow: prop active on drift restart, w inactive") == [
        (3, 38, "drift policy 'restart': expected report, restore or infer")
    ]


def test_anything_else_after_a_binding_is_an_error_where_it_starts() -> None:
    expected = (
        "unexpected {!r} after the binding: expected 'on drift POLICY' (POLICY report, "
        "restore or infer) or the end of the line"
    )
    assert located("parameter Slow: base z = 1 on drift") == [(3, 28, expected.format("on drift"))]
    assert located("lifecycle Slow: prop active restore") == [(3, 29, expected.format("restore"))]


def test_the_cpp_flavour_reads_the_same_policy(tmp_path: Path) -> None:
    source = "Layer Slow [\nint f() { return 1; }\n]\nparameter Slow: base v = 2 on drift infer;\n"
    tree, problems = parse_with_diagnostics(source, "robot.cpp.layers")
    assert problems == [] and [p.policy for p in tree.parameters] == ["infer"]


def test_contextros_check_reports_a_bad_policy_with_its_place(tmp_path: Path) -> None:
    layers = tmp_path / "robot.layers"
    layers.write_text(HEADER + "parameter Slow: base y = 1 on drift sometimes\n", "utf-8")
    checked = subprocess.run(
        [sys.executable, "-m", "contextros", "check", str(layers)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert checked.returncode != 0
    assert f"{layers}:3:37: error: drift policy 'sometimes'" in checked.stdout + checked.stderr


def test_check_warns_when_an_infer_drift_can_match_no_other_layer() -> None:
    from contextros.language import check_source

    source = (
        "layer Slow:\n    def f(): ...\nlayer Fast excludes Slow:\n    def f(): ...\n"
        "parameter Fast: base max_speed = 3.0 on drift infer\n"
        "parameter Fast: base mode = 'sport' on drift infer\n"
        "parameter Slow: base max_speed = 0.3\n"
    )
    found = [(d.severity.value, d.line, d.col, d.message) for d in check_source(source, "t.layers")]
    assert found == [
        (
            "warning",
            6,
            17,
            "on drift infer: no other layer of this file binds parameter base mode, so no layer "
            "can be inferred from its drift (it is only reported)",
        )
    ]
