"""The actual state of what layers set, as pure logic: readings in, drift, restores and
inferred switches out (docs/ros-integration.md, "Drift")."""

from __future__ import annotations

import pytest

from contextros.bindings import Bindings
from contextros.bindings.actual import ActualState, Reading
from contextros.bindings.inference import actual_layers, infer, layers_holding
from contextros.language.flavours import parse_with_diagnostics

LAYERS = """\
parameter Slow: base max_speed = 0.3 on drift infer
parameter Fast: base max_speed = 3 on drift infer
parameter Fast: base mode = 'sport'
parameter Eco: base mode = 'eco' on drift restore
lifecycle Outdoor: propeller active on drift restore
lifecycle Indoor: propeller inactive
"""


def state(text: str = LAYERS) -> ActualState:
    tree, problems = parse_with_diagnostics(text, "robot.layers")
    assert not problems
    bindings = Bindings(tree.parameters, tree.lifecycles)
    return ActualState(bindings, lambda name: "/" + name.lstrip("/"), restore_limit=2)


def read(actual: ActualState, node: str, name: str, value: object, at: float) -> None:
    actual.read((node, name), Reading(value, repr(value), at, at))  # type: ignore[arg-type]


def test_a_binding_in_force_drifts_when_the_node_has_another_value() -> None:
    actual = state()
    read(actual, "/base", "max_speed", 0.3, 1.0)
    actual.configuration(["Slow"])
    assert actual.drifts() == []
    read(actual, "/base", "max_speed", 1.5, 2.0)
    (drift,) = actual.drifts()
    assert (drift.layer, drift.key, drift.seen, drift.sets, drift.since) == (
        "Slow",
        ("/base", "max_speed"),
        "1.5",
        "0.3",
        2.0,
    )
    assert drift.describe() == "/base max_speed = 1.5 (layer Slow sets 0.3)"
    read(actual, "/base", "max_speed", 1.5, 3.0)
    assert actual.drifts()[0].since == 2.0, "read again unchanged: drifted since the first"
    read(actual, "/base", "max_speed", 0.3, 4.0)
    assert actual.drifts() == [], "holds again"


def test_only_active_layers_and_the_outermost_binding_drift() -> None:
    actual = state()
    read(actual, "/base", "max_speed", 1.0, 1.0)
    assert actual.drifts() == [], "no layer active"
    actual.configuration(["Slow", "Fast"])  # Fast outermost: its 3 is in force
    read(actual, "/base", "max_speed", 3, 2.0)
    assert actual.drifts() == [] and not actual.state(0).in_force and actual.state(1).in_force
    assert not actual.state(0).holds and actual.state(1).holds


@pytest.mark.parametrize(
    ("value", "holding"),
    [(3, True), (3.0, True), ("3", False), (True, False), (None, False)],
)
def test_a_number_is_a_number_and_a_boolean_only_a_boolean(value: object, holding: bool) -> None:
    actual = state()
    read(actual, "/base", "max_speed", value, 1.0)
    assert actual.state(1).holds is holding


def test_lifecycle_drift_and_its_policy() -> None:
    actual = state()
    actual.configuration(["Outdoor"])
    read(actual, "/propeller", "", "active", 1.0)
    assert actual.drifts() == []
    read(actual, "/propeller", "", "inactive", 2.0)
    (drift,) = actual.drifts()
    assert (drift.layer, drift.seen, drift.sets, drift.policy) == (
        "Outdoor",
        "'inactive'",
        "active",
        "restore",
    )


def test_restores_are_bounded_until_a_switch_sets_the_binding() -> None:
    actual = state()
    actual.configuration(["Eco"])
    for at in (1.0, 2.0):
        read(actual, "/base", "mode", "sport", at)
        assert len(actual.restore_due(at)) == 1
        read(actual, "/base", "mode", "eco", at + 0.1)  # set back
    read(actual, "/base", "mode", "sport", 3.0)
    assert actual.restore_due(3.0) == [], "two restores within the window: given up"
    assert "set back 2 times within 30 s" in actual.state(3).action
    assert actual.restore_due(100.0) == [], "still given up, however late"
    actual.configuration(["Eco"], changed=[("/base", "mode")])
    assert len(actual.restore_due(101.0)) == 1, "a switch set it: set back again"


def test_report_policy_is_never_set_back() -> None:
    actual = state()
    actual.configuration(["Slow"])
    read(actual, "/base", "max_speed", 9, 1.0)
    assert actual.drifts() and actual.restore_due(1.0) == []


def test_the_actual_layers_are_those_whose_bindings_all_hold() -> None:
    actual = state()
    assert actual_layers(actual) == [], "nothing read yet"
    read(actual, "/base", "max_speed", 3, 1.0)
    read(actual, "/base", "mode", "sport", 1.0)
    read(actual, "/propeller", "", "inactive", 1.0)
    assert actual_layers(actual) == ["Fast", "Indoor"]
    read(actual, "/base", "mode", "eco", 2.0)
    assert actual_layers(actual) == ["Eco", "Indoor"]
    assert layers_holding([("A", True), ("B", True), ("A", False)]) == ["B"]


def test_an_infer_drift_matching_another_layer_switches_to_it() -> None:
    actual = state()
    read(actual, "/base", "max_speed", 3, 1.0)
    read(actual, "/base", "mode", "sport", 1.0)
    actual.configuration(["Fast"])
    assert infer(actual, ["Fast"]) is None, "no drift"
    read(actual, "/base", "max_speed", 0.3, 2.0)
    inference = infer(actual, ["Fast"])
    assert inference is not None
    assert (inference.activate, inference.deactivate) == (("Slow",), ("Fast",))
    assert inference.reason == (
        "inferred: /base max_speed = 0.3 (layer Fast sets 3) is what layer Slow sets (and its "
        "bindings all hold)"
    )


def test_no_inference_without_the_infer_policy_or_a_matching_layer() -> None:
    actual = state()
    actual.configuration(["Slow"])
    read(actual, "/base", "max_speed", 7.0, 1.0)
    assert actual.drifts() and infer(actual, ["Slow"]) is None, "no layer sets 7"
    actual.configuration(["Eco"])
    read(actual, "/base", "mode", "sport", 1.0)
    # Fast sets mode 'sport', but Eco's binding is `restore`, not `infer`.
    assert infer(actual, ["Eco"]) is None


def test_several_matching_layers_are_ambiguous() -> None:
    actual = state(LAYERS + "parameter Crawl: base max_speed = 0.3\n")
    actual.configuration(["Fast"])
    read(actual, "/base", "mode", "sport", 1.0)
    read(actual, "/base", "max_speed", 0.3, 2.0)
    inference = infer(actual, ["Fast"])
    assert inference is not None and inference.ambiguous == ("Crawl", "Slow")
    assert inference.activate == ()


def test_a_binding_policy_from_python_is_checked() -> None:
    from contextros.language.bindings import ParameterBinding
    from contextros.language.positions import Position, Ref

    at = Position(1, 1)
    binding = ParameterBinding(Ref("Slow", at), "/base", "max_speed", 0.3, at, policy="restore")
    assert binding.policy == "restore"
    with pytest.raises(ValueError, match="drift policy 'reset': expected report, restore or infer"):
        ParameterBinding(Ref("Slow", at), "/base", "max_speed", 0.3, at, policy="reset")


def test_a_node_gone_from_the_graph_drifts_but_is_not_set_back() -> None:
    actual = state()
    actual.configuration(["Outdoor"])
    gone = Reading(None, "(node not in the ROS graph)", 1.0, 1.0, absent=True)
    actual.read(("/propeller", ""), gone)
    (drift,) = actual.drifts()
    assert drift.seen == "(node not in the ROS graph)" and drift.policy == "restore"
    assert actual.restore_due(1.0) == [], "no one to set"
    read(actual, "/propeller", "", "unconfigured", 2.0)  # back, restarted
    assert len(actual.restore_due(2.0)) == 1


def test_the_actual_state_and_inference_import_without_ros() -> None:
    import subprocess
    import sys

    probe = (
        "import sys, contextros.bindings.actual, contextros.bindings.inference;"
        "loaded = [m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'rcl_interfaces', 'lifecycle_msgs', 'contextros_interfaces') "
        "or m.startswith('contextros.ros')];"
        "assert not loaded, loaded"
    )
    subprocess.run([sys.executable, "-c", probe], check=True)
