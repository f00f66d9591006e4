"""Rules, parameters and lifecycle lines read the same in a C++ layer file (one front end):
a `//` comment and a `;` may end them, errors point at the same columns."""

from __future__ import annotations

import pytest

from contextros.language.flavours import parse_with_diagnostics

LINES = [
    "rule Battery: LowBattery while battery.percentage < 20 for 0.3 s hysteresis 5",
    "rule Terrain: Flight while terrain.data == 'flooded' and battery.percentage >= 25 else Wheels",
    "parameter LowBattery: controller max_speed = 0.3",
    "lifecycle Flight: drivers/propeller active, /wheels inactive",
]
PYTHON = (
    "group locomotion: Wheels, Flight\n\nlayer Wheels:\n    def f() -> int:\n        return 1\n\n"
    + "\n".join(LINES)
    + "\n"
)
CPP = (
    "#include <string>\n\ngroup locomotion: Wheels, Flight;\n\n"
    "Layer Wheels [\nint f() { return 1; }\n]\n\n"
    + "\n".join(f"{line};  // same in C++" for line in LINES)
    + "\n"
)


def summary(source: str, path: str) -> tuple[object, ...]:
    layer_file, diagnostics = parse_with_diagnostics(source, path)
    assert [d for d in diagnostics if d.is_error] == []
    return (
        [
            (r.name, r.mode, r.layer.name, r.text, r.hold, r.hysteresis, r.at.col)
            for r in layer_file.rules
        ],
        [(p.layer.name, p.node, p.name, p.value, p.at.col) for p in layer_file.parameters],
        [(c.layer.name, c.node, c.state, c.at.col) for c in layer_file.lifecycles],
    )


def test_both_flavours_give_the_same_declarations() -> None:
    python, cpp = summary(PYTHON, "robot.layers"), summary(CPP, "robot.cpp.layers")
    assert python == cpp
    assert len(python[0]) == 2 and len(python[1]) == 1 and len(python[2]) == 2


def test_a_cpp_rule_error_has_its_column_and_caret() -> None:
    source = CPP + "rule Bad: Flight while terrain < 3;\n"
    _, diagnostics = parse_with_diagnostics(source, "robot.cpp.layers")
    (error,) = [d.render() for d in diagnostics if d.is_error]
    assert error.startswith("robot.cpp.layers:13:24: error: 'terrain' is not a field")
    assert error.splitlines()[-1] == " " * (4 + 23) + "^"


def test_a_long_layer_name_reads_the_same_in_both_flavours() -> None:
    # The whole line is read: a declaration whose ':' comes late is one in C++ too.
    line = "parameter LowBatteryConservativeNavigation: controller max_speed = 0.3"
    python, cpp = (
        summary(PYTHON + line + "\n", "robot.layers"),
        summary(CPP + line + ";\n", "robot.cpp.layers"),
    )
    assert python == cpp
    assert ("LowBatteryConservativeNavigation", "controller", "max_speed", 0.3, 45) in python[1]


def _errors(source: str, path: str) -> list[tuple[int, int, str]]:
    _, diagnostics = parse_with_diagnostics(source, path)
    return [(d.line, d.col, d.message) for d in diagnostics if d.is_error]


def _both(
    line: str, *, in_header: bool
) -> tuple[list[tuple[int, int, str]], list[tuple[int, int, str]]]:
    python_layers = "layer Wheels:\n    def f() -> int:\n        return 1\n"
    cpp_layers = "Layer Wheels [\nint f() { return 1; }\n]\n"
    if in_header:
        python = f"x = 1\n{line}\n{python_layers}"
        cpp = f"int x = 1;\n{line}\n{cpp_layers}"
    else:
        python = f"x = 1\n{python_layers}{line}\n"
        cpp = f"int x = 1;\n{cpp_layers}{line}\n"
    return _errors(python, "robot.layers"), _errors(cpp, "robot.cpp.layers")


@pytest.mark.parametrize("in_header", [True, False])
@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("rule R Wheels while a.b > 1", "expected ':' after the rule name"),
        ("parameter Wheels /base speed = 1", "expected ':' after the layer name"),
        ("lifecycle Wheels", "expected ':' after the layer name"),
        ("rule R: Wheels while a.b >", "expected a field"),
    ],
)
def test_both_flavours_detect_declaration_lines_alike(
    line: str, message: str, in_header: bool
) -> None:
    python, cpp = _both(line, in_header=in_header)
    assert [(col, text) for _, col, text in python] == [(col, text) for _, col, text in cpp]
    assert python and message in python[0][2], python
