"""Guards in the Python flavour: `def C.m(...) -> T when CONDITION:`, parsed, checked with
located errors, and compiled to a plain function of the partial's parameters."""

from __future__ import annotations

import ast
import textwrap
import traceback
from pathlib import Path

import pytest

from contextros import activate, activate_for, activated
from contextros.language import compile_source, load, parse
from contextros.language.checker import check_source

pytestmark = pytest.mark.filterwarnings("ignore::contextros.language.LayerInteractionWarning")

CLEANER = """\
class Cleaner:
    pass

base:
    def Cleaner.clean(self, area: int) -> str:
        return f"base {area}"

layer Big:
    def Cleaner.clean(self, area: int) -> str when area > 10:
        return "big " + proceed(self, area)

layer Even after Big:
    def Cleaner.clean(self, area: int) when (area %
            2 == 0):  # a condition over two lines
        return "even " + proceed(self, area)

layer Odd:
    def Cleaner.clean(self, area) when area % 2 == 1: return "odd " + proceed(self, area)

layer Failing:
    def Cleaner.clean(self, area) when area / 0:
        return "never"
"""


def errors(text: str) -> list[tuple[int, int, str]]:
    found = check_source(textwrap.dedent(text), "t.layers")
    return [(d.line, d.col, d.message) for d in found if d.is_error]


def load_text(tmp_path: Path, text: str, name: str) -> object:
    path = tmp_path / f"{name}.layers"
    path.write_text(text)
    return load(path, name=name)


def test_the_guard_is_parsed_with_its_position() -> None:
    tree = parse(CLEANER, "cleaner.layers")
    guards = {f.layer: f.guard for f in tree.all_functions()}
    assert guards[None] is None
    big, even = guards["Big"], guards["Even"]
    assert big is not None and (big.text, big.at.line, big.at.col) == ("area > 10", 9, 52)
    assert even is not None and even.text.startswith("(area %") and even.at.line == 13


def test_a_compiled_guard_is_a_plain_function_of_the_partials_parameters() -> None:
    text = compile_source(CLEANER, "cleaner.layers").text
    tree = ast.parse(text)
    guard = next(
        n
        for n in tree.body
        if isinstance(n, ast.FunctionDef) and n.name == "Cleaner_clean_Big__when"
    )
    assert ast.unparse(guard.args) == "self, area"  # annotations are the partial's
    assert "Cleaner_clean.partial(Big, when=Cleaner_clean_Big__when)(Cleaner_clean_Big)" in text
    assert "def Cleaner_clean_Big(self, area: int) -> str:" in text  # the header without it
    for banned in ("getattr", "globals()", "__dict__", "inspect", "eval("):
        assert banned not in text


def test_guards_decide_each_call_in_activation_order(tmp_path: Path) -> None:
    module = load_text(tmp_path, CLEANER, "guards_cleaner")
    cleaner = module.Cleaner()  # type: ignore[attr-defined]
    assert cleaner.clean(20) == "base 20"
    with activated(module.Big):  # type: ignore[attr-defined]
        assert cleaner.clean(20) == "big base 20"
        assert cleaner.clean(4) == "base 4"
    activate(module.Big, module.Even)  # type: ignore[attr-defined]
    assert cleaner.clean(20) == "even big base 20"
    assert cleaner.clean(21) == "big base 21"
    assert cleaner.clean(4) == "even base 4"
    other = module.Cleaner()  # type: ignore[attr-defined]
    activate_for(other, module.Odd)  # type: ignore[attr-defined]
    assert other.clean(3) == "odd base 3" and other.clean(22) == "even big base 22"


def test_an_error_in_a_guard_points_at_the_layer_file(tmp_path: Path) -> None:
    module = load_text(tmp_path, CLEANER, "guards_failing")
    activate(module.Failing)  # type: ignore[attr-defined]
    with pytest.raises(ZeroDivisionError) as raised:
        module.Cleaner().clean(1)  # type: ignore[attr-defined]
    frame = traceback.extract_tb(raised.value.__traceback__)[-1]
    assert (Path(frame.filename).name, frame.lineno) == ("guards_failing.layers", 21)
    assert (
        frame.colno is not None and frame.colno + 1 == CLEANER.splitlines()[20].index("area /") + 1
    )


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "base:\n    def f(x) when x > 1:\n        return x\n",
            (2, 19, "a guard ('when ...') belongs to a layer's partial; the base implementation"),
        ),
        (
            "layer A:\n    def f(x) when:\n        return x\n",
            (2, 14, "expected a condition after 'when'"),
        ),
        ("layer A:\n    def f(x) when x >:\n        return x\n", (2, 22, "Python syntax error")),
        (
            "layer A:\n    def f(x) when lambda: x:\n        return x\n",
            (2, 19, "a lambda in a guard needs parentheses"),
        ),
        (
            "layer A:\n    async def f(x) when await x:\n        return x\n",
            (2, 25, "Python syntax error: 'await' outside"),
        ),
        (
            "layer A:\n    def f(x) when y > 1:\n        return x\n",
            None,  # names are the header's business, as in bodies: checked when called
        ),
    ],
)
def test_guard_errors_are_located(text: str, expected: tuple[int, int, str] | None) -> None:
    found = errors(text)
    if expected is None:
        assert found == []
        return
    assert len(found) == 1, found
    line, col, message = found[0]
    assert (line, col) == expected[:2] and message.startswith(expected[2]), found[0]


def test_a_guard_name_taken_by_the_header_is_an_error() -> None:
    text = "def f_A__when(x):\n    return 1\n\nlayer A:\n    def f(x) when x:\n        return x\n"
    ((line, _, message),) = errors(text)
    assert line == 5 and "'f_A__when'" in message and "guard" in message


def test_when_as_a_name_elsewhere_is_no_guard() -> None:
    text = "layer A:\n    def f(when) -> when:\n        return when\n"
    assert errors(text) == []
    (function,) = parse(text, "t.layers").all_functions()
    assert function.guard is None
