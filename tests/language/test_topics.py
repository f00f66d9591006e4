"""`topic NAME: PACKAGE/msg/TYPE` declarations: read the same in both flavours, errors at
their column, conflicts across declarations, and rule fields checked offline against them."""

from __future__ import annotations

import pytest

from contextros.language.checker import check_source
from contextros.language.flavours import parse_with_diagnostics
from contextros.language.lines import is_line_declaration
from contextros.rules.ruleset import FieldLookup

LAYERS = (
    "group location: Indoor, Outdoor\n"
    "layer Indoor:\n    def f() -> int:\n        return 1\n"
    "layer Outdoor:\n    def f() -> int:\n        return 2\n\n"
)
CPP_LAYERS = (
    "#include <string>\n"
    "group location: Indoor, Outdoor;\n"
    "Layer Indoor [\nint f() { return 1; }\n]\n"
    "Layer Outdoor [\nint f() { return 2; }\n]\n"
)
ROW = LAYERS.count("\n") + 1  # the first line after LAYERS (and CPP_LAYERS)
DECLARATIONS = [
    "topic battery: sensor_msgs/msg/BatteryState",
    "topic /robot1/gps/fix: sensor_msgs/msg/NavSatFix",
    "topic ~/dock:std_msgs/msg/Bool",
]


def topics(source: str, path: str) -> list[tuple[str, str, int, int, int]]:
    layer_file, diagnostics = parse_with_diagnostics(source, path)
    assert [d.render() for d in diagnostics if d.is_error] == []
    return [(t.topic, t.type_name, t.at.line, t.at.col, t.type_at.col) for t in layer_file.topics]


def test_declarations_read_the_same_in_both_flavours() -> None:
    python = LAYERS + "\n".join(f"{line}  # a comment" for line in DECLARATIONS) + "\n"
    cpp = CPP_LAYERS + "\n".join(f"{line};  // a comment" for line in DECLARATIONS) + "\n"
    expected = [
        ("battery", "sensor_msgs/msg/BatteryState", ROW, 7, 16),
        ("/robot1/gps/fix", "sensor_msgs/msg/NavSatFix", ROW + 1, 7, 24),
        ("~/dock", "std_msgs/msg/Bool", ROW + 2, 7, 14),
    ]
    assert topics(python, "robot.layers") == expected
    assert topics(cpp, "robot.cpp.layers") == expected


@pytest.mark.parametrize(
    ("line", "col", "message"),
    [
        ("topic battery sensor_msgs/msg/BatteryState", 15, "expected ':' after the topic name"),
        ("topic battery:", 15, "expected the message type of topic 'battery' after ':'"),
        (
            "topic battery.percentage: sensor_msgs/msg/BatteryState",
            7,
            "'battery.percentage' is not a topic name: a topic name has no '.'",
        ),
        ("topic gps/9fix: sensor_msgs/msg/NavSatFix", 7, "'gps/9fix' is not a topic name"),
        (
            "topic battery: sensor_msgs/BatteryState",
            16,
            "write the message type as PACKAGE/msg/NAME: sensor_msgs/msg/BatteryState",
        ),
        ("topic battery: std_srvs/srv/Trigger", 16, "is a srv type: a topic carries a message"),
        ("topic battery: Sensor_msgs/msg/batteryState", 16, "is not a message type name"),
        (
            "topic battery: sensor_msgs/msg/BatteryState extra",
            45,
            "expected the end of the declaration after the type, found 'extra'",
        ),
    ],
)
@pytest.mark.parametrize("flavour", ["python", "cpp"])
def test_a_malformed_declaration_is_an_error_at_its_column(
    line: str, col: int, message: str, flavour: str
) -> None:
    if flavour == "python":
        source, path, row = LAYERS + line + "\n", "robot.layers", ROW
    else:
        source, path, row = CPP_LAYERS + line + ";\n", "robot.cpp.layers", ROW
    errors = [d for d in check_source(source, path) if d.is_error]
    assert [(e.line, e.col) for e in errors] == [(row, col)], [e.render() for e in errors]
    assert message in errors[0].message
    assert errors[0].render().startswith(f"{path}:{row}:{col}: error: ")


@pytest.mark.parametrize(
    "line",
    [
        "topic = 'battery'",
        "topic: str = 'battery'",
        "topic in topics",
        "topic if topics else None",
        "topic / scale",
        "topic /scale",
        "topic.name",
        "topics battery: x",
    ],
)
def test_python_that_starts_with_topic_stays_python(line: str) -> None:
    assert not is_line_declaration(line)


@pytest.mark.parametrize("line", ["topic x = 1;", "topic *x;", "topic x;", "topic x{1};"])
def test_cpp_that_starts_with_topic_stays_cpp(line: str) -> None:
    assert not is_line_declaration(line)


def test_a_topic_declared_with_two_types_is_an_error_at_the_second() -> None:
    source = (
        LAYERS + "topic battery: sensor_msgs/msg/BatteryState\n"
        "topic battery: sensor_msgs/msg/BatteryState\n"
        "topic battery: std_msgs/msg/Float32\n"
        "rule Low: Indoor while battery.percentage < 20\n"
    )
    errors = [d.render().splitlines()[0] for d in check_source(source, "robot.layers")]
    assert errors == [
        f"robot.layers:{ROW + 2}:16: error: topic 'battery' is already declared as "
        f"sensor_msgs/msg/BatteryState at robot.layers:{ROW}: a topic has one message type"
    ]


def test_a_declared_topic_no_rule_reads_is_a_warning() -> None:
    source = (
        LAYERS + "topic batery: sensor_msgs/msg/BatteryState\n"
        "rule Low: Indoor while battery.percentage < 20\n"
    )
    (warning,) = check_source(source, "robot.layers")
    assert warning.render().startswith(
        f"robot.layers:{ROW}:7: warning: no rule reads topic 'batery'"
    )


# -- fields checked offline (a message type lookup passed in, as `contextros check` does) --

BATTERY = {("percentage",): "number", ("location",): "string", ("present",): "bool"}


def message_types(type_name: str) -> FieldLookup:
    if type_name == "sensor_msgs/msg/BatteryState":
        return lambda path: BATTERY.get(path)
    raise ValueError(f"message package {type_name.split('/')[0]!r} is not installed here")


def offline(
    rules: str, declarations: str = "topic battery: sensor_msgs/msg/BatteryState\n"
) -> list[str]:
    source = LAYERS + declarations + rules
    return [d.render() for d in check_source(source, "robot.layers", message_types=message_types)]


def test_a_declared_type_checks_a_field_offline_at_its_column() -> None:
    assert offline("rule Low: Indoor while battery.percentage < 20\n") == []
    (error,) = offline("rule Low: Indoor while battery.percent < 20\n")
    assert error.splitlines() == [
        f"robot.layers:{ROW + 1}:24: error: sensor_msgs/msg/BatteryState (the type of topic "
        "'battery') has no field 'percent'",
        "    rule Low: Indoor while battery.percent < 20",
        "                           ^",
    ]


def test_a_comparison_of_the_wrong_kind_is_an_error_offline() -> None:
    (error,) = offline("rule Low: Indoor while battery.location < 20\n")
    assert error.splitlines()[0] == (
        f"robot.layers:{ROW + 1}:24: error: 'battery.location' is a string field of "
        "sensor_msgs/msg/BatteryState: it cannot be compared with the number 20"
    )


def test_an_undeclared_topic_is_a_note_for_run_time() -> None:
    (note,) = offline("rule Dock: Indoor while battery.present and dock.data\n")
    assert note.splitlines()[0] == (
        f"robot.layers:{ROW + 1}:45: note: rule Dock's fields on topic 'dock' are checked at run "
        "time, when the Layer manager sees the topic's type: it has no declaration "
        "('topic dock: PACKAGE/msg/TYPE')"
    )


def test_a_declared_type_not_installed_is_a_note_for_run_time() -> None:
    (note,) = offline(
        "rule Far: Outdoor while odom.pose.pose.position.x > 10\n",
        "topic odom: nav_msgs/msg/Odometry\n",
    )
    assert note.splitlines()[0] == (
        f"robot.layers:{ROW + 1}:25: note: rule Far's fields on topic 'odom' are checked at "
        "run time, when the Layer manager sees the topic's type: its declared type "
        f"nav_msgs/msg/Odometry (robot.layers:{ROW}) is not available here: message package "
        "'nav_msgs' is not installed here"
    )


def test_a_nested_type_not_installed_is_a_note_not_a_crash() -> None:
    def nested_missing(type_name: str) -> FieldLookup:
        def lookup(path: tuple[str, ...]) -> str | None:
            raise ValueError("message package 'robot_msgs' is not installed here")

        return lookup

    source = LAYERS + "topic battery: sensor_msgs/msg/BatteryState\n"
    source += "rule Low: Indoor while battery.cells.low\n"
    (note,) = check_source(source, "robot.layers", message_types=nested_missing)
    assert note.severity.value == "note"
    assert note.message.endswith(
        "a type inside its declared type sensor_msgs/msg/BatteryState is not available here: "
        "message package 'robot_msgs' is not installed here"
    )


def test_without_a_lookup_the_checker_leaves_fields_alone() -> None:
    source = (
        LAYERS + "topic battery: sensor_msgs/msg/BatteryState\n"
        "rule Low: Indoor while battery.percent < 20 and dock.data\n"
    )
    assert check_source(source, "robot.layers") == []
