"""The rule grammar of layer files: what it reads, and errors at file:line:col with a caret."""

from __future__ import annotations

import pytest

from contextros.language.flavours import parse_with_diagnostics
from contextros.language.rules import BoolOp, Comparison, FieldRef, Literal, Not, condition_text

HEADER = (
    "group location: Indoor, Outdoor\n\nlayer LowBattery:\n    def f() -> int:\n"
    "        return 1\n\n"
)


def parse(rule_lines: str) -> tuple[list[object], list[str]]:
    layer_file, diagnostics = parse_with_diagnostics(HEADER + rule_lines, "robot.layers")
    return list(layer_file.rules), [d.render() for d in diagnostics]


def test_a_while_rule_with_hold_hysteresis_and_else() -> None:
    (rule,), errors = parse(
        "rule Gps: Outdoor while gps/fix.status.status >= 0 for 500 ms hysteresis 1 else Indoor\n"
    )
    assert errors == []
    assert (rule.name, rule.mode, rule.layer.name) == ("Gps", "while", "Outdoor")
    assert (rule.hold, rule.hysteresis, rule.otherwise.name) == (0.5, 1.0, "Indoor")
    assert rule.condition == Comparison(
        FieldRef("gps/fix", ("status", "status"), rule.condition.left.at),
        ">=",
        Literal(0.0, rule.condition.right.at),
        rule.condition.at,
    )
    assert (rule.condition.left.at.line, rule.condition.left.at.col) == (7, 25)


def test_boolean_structure_and_precedence() -> None:
    (rule,), errors = parse(
        "rule B: activate LowBattery when not battery.present or battery.percentage < 20 "
        "and (battery.voltage < 11.5 or dock.data == false)  # low\n"
    )
    assert errors == []
    assert isinstance(rule.condition, BoolOp) and rule.condition.op == "or"
    assert isinstance(rule.condition.operands[0], Not)
    assert condition_text(rule.condition) == (
        "not battery.present or (battery.percentage < 20 and "
        "(battery.voltage < 11.5 or dock.data == false))"
    )
    assert rule.text.endswith("dock.data == false)"), "the comment is not part of the rule"
    assert [f.topic for f in rule.fields] == ["battery", "battery", "battery", "dock"]


def test_absolute_and_private_topics_and_strings() -> None:
    (rule,), errors = parse("rule M: deactivate LowBattery when /robot/mode.data == 'charging'\n")
    assert errors == []
    assert rule.fields[0].topic == "/robot/mode"
    assert rule.condition.right == Literal("charging", rule.condition.right.at)


@pytest.mark.parametrize(
    ("line", "at", "message"),
    [
        ("rule R: LowBattery when battery.percentage < 20", "when", "expected 'while'"),
        ("rule R: LowBattery while battery < 20", "battery", "'battery' is not a field"),
        ("rule R: LowBattery while battery.percentage <", "", "found the end of the line"),
        ("rule R: LowBattery while battery.percentage < 20 for 2", "", "unit"),
        ("rule R: LowBattery while 3 < 4", "3", "two constants"),
        ("rule R: LowBattery while battery.percentage $ 3", "$", "unexpected character '$'"),
        ("rule R: activate LowBattery when a.b > 1 else Indoor", "else", "'else' applies"),
        ("rule R: LowBattery while a.b > 1 else LowBattery", "LowBattery", "own layer"),
        ("rule R LowBattery while a.b > 1", "LowBattery", "expected ':' after the rule name"),
        ("rule R: LowBattery while (a.b > 1", "", "expected ')'"),
        ("rule R: LowBattery while a.b > 1 for -2 s", "-2", "must be a finite number >= 0"),
    ],
)
def test_errors_name_the_place_with_a_caret(line: str, at: str, message: str) -> None:
    rules, errors = parse(line + "\n")
    assert rules == []
    (error,) = errors
    col = line.rindex(at) + 1 if at else len(line) + 1
    head, quoted, caret = error.splitlines()
    assert head.startswith(f"robot.layers:7:{col}: error:"), head
    assert message in head
    assert quoted.strip() == line
    assert len(caret) - 4 == col, "the caret is under the column"


def test_a_rule_is_one_line() -> None:
    _, errors = parse("rule R: LowBattery while a.b > 1\n    for 2 s\n")
    assert any("a rule is declared on one line" in e for e in errors)


# -- string literals and nesting: located errors, never an exception ---------------------


@pytest.mark.parametrize(
    ("line", "at", "message"),
    [
        ('rule R: LowBattery while mode.data == "\\x"', "\\x", "invalid escape '\\x'"),
        ('rule R: LowBattery while mode.data == "ok\\N{foo}"', "\\N", "unknown Unicode character"),
        ("rule R: LowBattery while mode.data == 'a\\u12'", "\\u", "invalid escape '\\u12'"),
        (
            "rule R: LowBattery while " + "not " * 2000 + "mode.data",
            "not " * 1900 + "mode",
            "nests too deeply",
        ),
        (
            "rule R: LowBattery while " + "(" * 2000 + "mode.data" + ")" * 2000,
            "(" * 1900 + "mode",
            "nests too deeply",
        ),
    ],
)
def test_bad_strings_and_deep_nesting_are_located_errors(line: str, at: str, message: str) -> None:
    rules, errors = parse(line + "\n")
    assert rules == []
    (error,) = errors
    col = line.index(at) + 1
    head, _, caret = error.splitlines()
    assert head.startswith(f"robot.layers:7:{col}: error:"), head
    assert message in head
    assert len(caret) - 4 == col


def test_strings_read_as_python_string_literals() -> None:
    (rule,), errors = parse(
        'rule M: deactivate LowBattery when mode.data == "é\\u00e9\\t\\\\\\N{BULLET}"\n'
    )
    assert errors == []
    assert rule.condition.right.value == "éé\t\\\u2022"


def test_nesting_up_to_the_limit_is_read() -> None:
    (rule,), errors = parse(
        "rule R: LowBattery while " + "not (" * 50 + "mode.data" + ")" * 50 + "\n"
    )
    assert errors == []
    assert isinstance(rule.condition, Not)


def test_an_unknown_escape_is_kept_with_a_warning() -> None:
    line = 'rule M: deactivate LowBattery when mode.data == "a\\d"'
    (rule,), found = parse(line + "\n")
    assert rule.condition.right.value == "a\\d"
    (warning,) = found
    col = line.index("\\d") + 1
    assert warning.startswith(f"robot.layers:7:{col}: warning: invalid escape")


@pytest.mark.parametrize(
    ("value", "expected"),
    [('"é"', "é"), ("'a\\tb'", "a\tb"), ('"\\u00e9"', "é"), ("'it''s'", None)],
)
def test_parameter_strings_read_like_rule_strings(value: str, expected: str | None) -> None:
    layer_file, diagnostics = parse_with_diagnostics(
        HEADER + f"parameter LowBattery: /base mode = {value}\n", "robot.layers"
    )
    if expected is None:
        assert layer_file.parameters == [] and diagnostics
        return
    assert [d.render() for d in diagnostics] == []
    assert [p.value for p in layer_file.parameters] == [expected]


@pytest.mark.parametrize(("value", "escape"), [('"\\x"', "\\x"), ('"a\\N{foo}"', "\\N")])
def test_a_bad_parameter_string_is_a_located_error(value: str, escape: str) -> None:
    line = f"parameter LowBattery: /base mode = {value}"
    layer_file, diagnostics = parse_with_diagnostics(HEADER + line + "\n", "robot.layers")
    assert layer_file.parameters == []
    (error,) = [d.render() for d in diagnostics]
    col = line.index(escape) + 1
    assert error.startswith(f"robot.layers:7:{col}: error: invalid escape")
