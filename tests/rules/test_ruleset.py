"""Static checks of rule sets: fields against a message type, contradicting rules."""

from __future__ import annotations

from pathlib import Path

import pytest

from contextros.language.diagnostics import LayerSyntaxError
from contextros.language.flavours import parse_with_diagnostics
from contextros.rules import Rule, RuleSet

KINDS = {
    ("percentage",): "number",
    ("present",): "bool",
    ("location",): "string",
    ("cell_voltage",): "array",
    ("header",): "message",
}


def field_errors(text: str) -> list[str]:
    rules = RuleSet.from_rules([Rule("R", text)], path="robot.layers")
    found = rules.check_fields(
        "battery", lambda path: KINDS.get(path), "sensor_msgs/msg/BatteryState"
    )
    return [d.render() for d in found]


def test_a_field_the_type_lacks_is_an_error_at_its_column() -> None:
    (error,) = field_errors("LowBattery while battery.percent < 20")
    head, quoted, caret = error.splitlines()
    assert head == (
        "robot.layers:1:26: error: sensor_msgs/msg/BatteryState (the type of topic 'battery') "
        "has no field 'percent'"
    )
    assert caret.index("^") - 4 == quoted.index("battery.percent") - 4


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        (
            "LowBattery while battery.percentage == 'low'",
            "cannot be compared with the string 'low'",
        ),
        ("LowBattery while battery.location < 'x'", "compared with == or != only"),
        ("LowBattery while battery.percentage", "must be a bool field"),
        ("LowBattery while battery.cell_voltage > 3", "name one of its fields"),
        ("LowBattery while battery.header == 1", "name one of its fields"),
    ],
)
def test_kinds_must_fit(text: str, problem: str) -> None:
    (error,) = field_errors(text)
    assert problem in error


def test_fitting_fields_pass() -> None:
    assert field_errors("LowBattery while battery.percentage < 20 and battery.present") == []
    assert field_errors("LowBattery while other.x > 1") == [], "another topic's fields: later"


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        (
            "LowBattery while battery.percentage == battery.location",
            "'battery.percentage' (a number field of sensor_msgs/msg/BatteryState) cannot be "
            "compared with 'battery.location' (a string field of sensor_msgs/msg/BatteryState)",
        ),
        (
            "LowBattery while battery.location < battery.location",
            "are string fields: a string is compared with == or != only",
        ),
    ],
)
def test_a_field_compared_with_a_field_of_the_same_topic_must_fit(text: str, problem: str) -> None:
    (error,) = field_errors(text)
    assert error.startswith("robot.layers:1:"), error
    assert problem in error


def test_fields_of_two_topics_are_checked_once_both_types_are_known() -> None:
    rules = RuleSet.from_rules(
        [Rule("R", "LowBattery while battery.percentage > dock.name")], path="robot.layers"
    )
    battery = ("sensor_msgs/msg/BatteryState", lambda path: KINDS.get(path))
    dock = ("example/msg/Dock", lambda path: {("name",): "string"}.get(path))
    # The battery's type comes first: the dock's is not known, nothing to say yet.
    assert rules.check_fields("battery", battery[1], battery[0]) == []
    # Then the dock's, with the battery's known: the mismatch, at the dock's field.
    (error,) = rules.check_fields("dock", dock[1], dock[0], {"battery": (battery[1], battery[0])})
    head = error.render().splitlines()[0]
    assert head.startswith("robot.layers:1:"), head
    assert error.source_line[error.col - 1 :].startswith("dock.name")
    assert "cannot be compared with 'dock.name' (a string field of example/msg/Dock)" in head
    fitting = RuleSet.from_rules([Rule("R", "LowBattery while battery.percentage > dock.x")])
    known = {"battery": (battery[1], battery[0])}
    assert fitting.check_fields("dock", lambda p: "number", "example/msg/Dock", known) == []


def test_duplicate_names_are_errors(tmp_path: Path) -> None:
    path = tmp_path / "robot.layers"
    path.write_text("rule A: X while a.b > 1\nrule A: Y while a.b < 1\n", encoding="utf-8")
    with pytest.raises(LayerSyntaxError, match=r"rule 'A' is already declared at robot\.layers:1"):
        RuleSet.from_files([path])


def test_contradictions_unless_the_conditions_exclude_each_other() -> None:
    relations = {n: (frozenset({"location"}), frozenset()) for n in ("Indoor", "Outdoor")}
    rules = RuleSet.from_rules(
        [
            Rule("Gps", "Outdoor while gps.status >= 0"),
            Rule("NoGps", "Indoor while gps.status < 0"),
            Rule("Dark", "Indoor while light.lux < 10"),
        ]
    )
    warnings = [d.message for d in rules.check(relations)]
    # Gps and NoGps never hold together; Dark may hold with either, and NoGps turns Indoor
    # off (gps >= 0) while Dark turns it on.
    assert len(warnings) == 2, warnings
    assert warnings[0].startswith("rules Gps (<rules>:1) and Dark may hold at the same time")
    assert "both of exclusive group 'location'" in warnings[0]
    assert warnings[1].startswith("rules NoGps (<rules>:2) and Dark")
    assert "one activates Indoor while the other deactivates it" in warnings[1]


def test_a_rules_file_with_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "robot.layers"
    path.write_text("\ufeffrule A: X while a.b > 1\n", encoding="utf-8")
    assert [rule.name for rule in RuleSet.from_files([path]).rules] == ["A"]


# -- `topic` declarations ------------------------------------------------------------------


def test_declarations_of_several_files_are_merged_and_must_agree(tmp_path: Path) -> None:
    sensors = tmp_path / "sensors.layers"
    sensors.write_text("topic battery: sensor_msgs/msg/BatteryState\n", encoding="utf-8")
    robot = tmp_path / "robot.layers"
    robot.write_text("rule Low: Night while battery.percentage < 20\n", encoding="utf-8")
    rules = RuleSet.from_files([sensors, robot])
    assert rules.topic_types["battery"].type_name == "sensor_msgs/msg/BatteryState"
    other = tmp_path / "other.layers"
    other.write_text("\n\ntopic battery: std_msgs/msg/Float32\n", encoding="utf-8")
    with pytest.raises(LayerSyntaxError) as raised:
        RuleSet.from_files([sensors, robot, other])
    assert str(raised.value).startswith(
        f"{other}:3:16: error: topic 'battery' is already declared as "
        "sensor_msgs/msg/BatteryState at sensors.layers:1: a topic has one message type"
    )


def test_offline_fields_of_two_declared_topics_are_compared_like_at_run_time(
    tmp_path: Path,
) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(
        "topic battery: sensor_msgs/msg/BatteryState\n"
        "topic gps: sensor_msgs/msg/NavSatFix\n"
        "rule Odd: Night while gps.status.status == battery.location\n",
        encoding="utf-8",
    )
    rules = RuleSet.from_files([path])
    types = {
        "sensor_msgs/msg/BatteryState": {("location",): "string"},
        "sensor_msgs/msg/NavSatFix": {("status", "status"): "number", ("status",): "message"},
    }
    found = rules.check_declared_fields(lambda name: types[name].get)
    assert [d.render().splitlines()[0] for d in found] == [
        f"{path}:3:44: error: 'gps.status.status' (a number field of sensor_msgs/msg/NavSatFix) "
        "cannot be compared with 'battery.location' (a string field of "
        "sensor_msgs/msg/BatteryState)"
    ]


def test_a_type_other_than_the_declared_one_names_both_and_the_declaration() -> None:
    rules = RuleSet.from_rules([Rule("Low", "Night while battery.percentage < 20")])
    assert rules.type_mismatch("battery", "/battery", "std_msgs/msg/Float32") is None, "undeclared"
    declared = RuleSet(
        rules.rules,
        {"robot.layers": "topic battery: sensor_msgs/msg/BatteryState\n"},
        parse_with_diagnostics("topic battery: sensor_msgs/msg/BatteryState\n", "robot.layers")[
            0
        ].topics,
    )
    assert declared.type_mismatch("battery", "/r/battery", "sensor_msgs/msg/BatteryState") is None
    mismatch = declared.type_mismatch("battery", "/r/battery", "std_msgs/msg/Float32")
    assert mismatch is not None and mismatch.is_error
    assert mismatch.render().splitlines() == [
        "robot.layers:1:16: error: topic /r/battery is published as std_msgs/msg/Float32, but "
        "topic 'battery' is declared as sensor_msgs/msg/BatteryState: the rules reading it "
        "(Low) stay off",
        "    topic battery: sensor_msgs/msg/BatteryState",
        "                   ^",
    ]


# -- contradictions through hysteresis -----------------------------------------------------


def contradictions(*rules: tuple[str, str]) -> list[str]:
    relations: dict[str, tuple[frozenset[str], frozenset[str]]] = {
        n: (frozenset({"location"}), frozenset()) for n in ("Indoor", "Outdoor")
    }
    found = RuleSet.from_rules([Rule(name, text) for name, text in rules]).check(relations)
    return [d.message for d in found]


def test_a_contradiction_only_through_hysteresis_is_reported_and_says_so() -> None:
    # Low holds from below 20 until the battery reaches 25; Up turns Night off at 22.
    (warning,) = contradictions(
        ("Low", "Night while battery.percentage < 20 hysteresis 5"),
        ("Up", "deactivate Night when battery.percentage >= 22"),
    )
    assert warning.startswith(
        "rules Low (<rules>:1) and Up may hold at the same time (Low's hysteresis 5 keeps it "
        "holding past its threshold) and one activates Night while the other deactivates it"
    )
    # Past the margin, or without hysteresis, the conditions exclude each other.
    assert not contradictions(
        ("Low", "Night while battery.percentage < 20 hysteresis 5"),
        ("Up", "deactivate Night when battery.percentage >= 25"),
    )
    assert not contradictions(
        ("Low", "Night while battery.percentage < 20"),
        ("Up", "deactivate Night when battery.percentage >= 22"),
    )


def test_hysteresis_widens_the_held_outcome_not_the_else_branch() -> None:
    # Outdoor holds from gps >= 0 down to gps >= -1: Indoor at gps < -0.5 may meet it.
    (warning,) = contradictions(
        ("Gps", "Outdoor while gps.status >= 0 hysteresis 1"),
        ("Lost", "Indoor while gps.status < -0.5"),
    )
    assert "(Gps's hysteresis 1 keeps" in warning
    assert "both of exclusive group 'location'" in warning
    # The else branch (Outdoor) is in force from the strict threshold (gps >= 0), not from
    # the relaxed one (gps >= 1): it meets an Indoor rule between 0.2 and 0.8.
    (warning,) = contradictions(
        ("Gps", "Indoor while gps.status < 0 hysteresis 1 else Outdoor"),
        ("Near", "activate Indoor when gps.status >= 0.2 and gps.status < 0.8"),
    )
    assert "both of exclusive group 'location'" in warning
    assert "hysteresis" not in warning, "it holds without the hysteresis too"


def test_hysteresis_under_not_widens_the_other_way_as_the_engine_evaluates_it() -> None:
    # `not lux > 10 hysteresis 5` holds until lux > 15 (the engine: test_engine.py).
    (warning,) = contradictions(
        ("Dark", "Night while not light.lux > 10 hysteresis 5"),
        ("Bright", "deactivate Night when light.lux > 12"),
    )
    assert "(Dark's hysteresis 5 keeps" in warning
    assert not contradictions(
        ("Dark", "Night while not light.lux > 10 hysteresis 5"),
        ("Bright", "deactivate Night when light.lux > 15"),
    )


# -- topic types that do not exist ----------------------------------------------------------


def test_a_misspelt_declared_type_is_an_error_an_uninstalled_package_a_note() -> None:
    from contextros.rules.ruleset import FieldLookup, NoSuchMessageType

    def message_types(name: str) -> FieldLookup:
        if name.startswith("sensor_msgs/"):
            raise NoSuchMessageType("sensor_msgs.msg has no message type 'BateryState'")
        raise ValueError("message package 'robot_msgs' is not installed here")

    source = (
        "topic battery: sensor_msgs/msg/BateryState\n"
        "topic dock: robot_msgs/msg/Dock\n"
        "rule Low: Night while battery.percentage < 20\n"
        "rule Docked: Home while dock.contact\n"
    )
    layer_file = parse_with_diagnostics(source, "robot.layers")[0]
    rules = RuleSet(layer_file.rules, {"robot.layers": source}, layer_file.topics)
    found = rules.check_declared_fields(message_types)
    assert [(d.severity.value, d.line, d.col) for d in found] == [
        ("error", 1, 16),
        ("note", 4, 25),
    ]
    assert found[0].message == (
        "the declared type of topic 'battery' does not exist: sensor_msgs.msg has no message "
        "type 'BateryState'"
    )
    assert "robot_msgs/msg/Dock (robot.layers:2) is not available here" in found[1].message
