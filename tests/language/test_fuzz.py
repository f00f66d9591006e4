"""Fuzzing: whatever the input, only the language's own errors come out.

Two sources of input: layer files generated from the grammar's pieces (with wrong
indentation, broken bodies, unknown and duplicate names mixed in) and mutations of the
fixtures (characters inserted, deleted, lines duplicated or swapped). For each input,
`check_source` must return diagnostics without raising, each located at a real line and
column and rendered with that line and a caret under the column; `compile_source` may only
raise `LayerSyntaxError`, located likewise; and a file that compiles must yield code Python
accepts.
"""

from __future__ import annotations

import os
import warnings

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from contextros.language import (
    Diagnostic,
    LayerLanguageError,
    LayerSyntaxError,
    check_source,
    compile_source,
)
from contextros.language.diagnostics import printable, source_lines
from tests.language.conftest import FIXTURES

# `make test` runs each fuzzer on 300 inputs; `make fuzz` on 5,000 (CONTEXTROS_FUZZ_EXAMPLES).
FUZZ = settings(
    max_examples=int(os.environ.get("CONTEXTROS_FUZZ_EXAMPLES", "300")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
    database=None,
)

NAMES = ["A", "B", "Indoor", "Outdoor", "Night", "x", "if", "None", "__debug__", "ﬁ", "Zé", "Robot"]
HEADERS = [
    "",
    "import math\n",
    "class Robot:\n    def clean(self):\n        return 1\n",
    "from __future__ import annotations\nRobot = object\n",
    '"""doc"""\nlayer = 3\nNOTE = """\nlayer Fake:\n"""\n',
    "return 1\n",
    "def f(:\n",
    "\tx = 1\n",
]
PARAMS = ["", "x", "x, y=1", "self", "self, x", "*args, **kwargs", "x, *, k=2", "x, /, y", "(", "1"]
BODIES = [
    "return 1",
    "return proceed()",
    "return proceed(x)",
    "pass",
    "...",
    "return (",
    'x = """\nlayer Z:\n"""\n        return x',
    "yield 1",
    "await x",
    "nonlocal q",
    "return x +",
    'return "\\d"',
    "raise ValueError()",
    "\n",
]
INDENTS = ["    ", "  ", "\t", "", "        "]


@st.composite
def relation(draw: st.DrawFn) -> str:
    keyword = draw(st.sampled_from(["excludes", "requires", "after", "with", ""]))
    names = draw(st.lists(st.sampled_from(NAMES), min_size=0, max_size=3))
    return f" {keyword} {', '.join(names)}"


@st.composite
def item(draw: st.DrawFn) -> str:
    indent = draw(st.sampled_from(INDENTS))
    body_indent = indent + draw(st.sampled_from(INDENTS))
    kind = draw(st.sampled_from(["def", "async def", "method", "hook", "doc", "junk", "deco"]))
    name = draw(st.sampled_from(["f", "g", "clean", "__debug__", "proceed", "f_A"]))
    params = draw(st.sampled_from(PARAMS))
    body = draw(st.sampled_from(BODIES))
    if kind in ("def", "async def"):
        head = f"{kind} {name}({params}):"
    elif kind == "method":
        head = f"def {draw(st.sampled_from(NAMES))}.{name}({params}):"
    elif kind == "hook":
        head = f"on {draw(st.sampled_from(['activate', 'deactivate', 'start', '']))}:"
    elif kind == "doc":
        return f'{indent}"""{draw(st.sampled_from(["a layer", "open"]))}"""\n'
    elif kind == "deco":
        decorator = draw(st.sampled_from(["staticmethod", "property", "functools.cache"]))
        head = f"@{decorator}\n{indent}def {name}({params}):"
    else:
        return f"{indent}{draw(st.sampled_from(['x = 1', 'layer', '# c', ')', 'on']))}\n"
    return f"{indent}{head}\n{body_indent}{body}\n"


@st.composite
def declaration(draw: st.DrawFn) -> str:
    kind = draw(st.sampled_from(["layer", "layer", "layer", "base", "group", "junk"]))
    if kind == "group":
        names = draw(st.lists(st.sampled_from(NAMES), max_size=4))
        return f"group {draw(st.sampled_from(NAMES))}: {', '.join(names)}\n"
    if kind == "junk":
        return draw(st.sampled_from(["x = 1\n", "  layer A:\n", "layer\n", "base\n", "\n"]))
    if kind == "base":
        head = "base:"
    else:
        relations = "".join(draw(st.lists(relation(), max_size=3)))
        colon = draw(st.sampled_from([":", ":", ":", "", ": x"]))
        head = f"layer {draw(st.sampled_from(NAMES))}{relations}{colon}"
    items = "".join(draw(st.lists(item(), max_size=4)))
    return f"{head}\n{items}"


@st.composite
def layer_file(draw: st.DrawFn) -> str:
    header = draw(st.sampled_from(HEADERS))
    return header + "".join(draw(st.lists(declaration(), max_size=6)))


CORPUS = [(FIXTURES / name).read_text() for name in ("paper_listing1.layers", "cleaner.layers")]
PIECES = [
    ":",
    " ",
    "\t",
    "\n",
    "(",
    ")",
    '"""',
    "'",
    "#",
    "layer ",
    "def ",
    ".",
    ",",
    "\\",
    "\x00",
    "\r",
    "\x0c",
    "\r\n",
    "\u2028",
    "\x85",
    "\x1c",
    "\ufeff",
    "é",
    "proceed",
    "base:\n",
    "    ",
    "on activate:",
    "@",
]


@st.composite
def mutated(draw: st.DrawFn) -> str:
    text = draw(st.sampled_from(CORPUS))
    for _ in range(draw(st.integers(1, 6))):
        operation = draw(st.sampled_from(["insert", "delete", "duplicate", "swap", "truncate"]))
        position = draw(st.integers(0, len(text)))
        if operation == "insert":
            piece = draw(st.one_of(st.sampled_from(PIECES), st.text(max_size=3)))
            text = text[:position] + piece + text[position:]
        elif operation == "delete":
            text = text[:position] + text[position + draw(st.integers(1, 8)) :]
        elif operation == "truncate":
            text = text[:position]
        else:
            lines = text.split("\n")
            i = draw(st.integers(0, len(lines) - 1))
            j = draw(st.integers(0, len(lines) - 1))
            if operation == "duplicate":
                lines.insert(j, lines[i])
            else:
                lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
    return text


def assert_located(diagnostic: Diagnostic, text: str) -> None:
    """file:line:col of a real line, that line quoted, and a caret under the column."""
    lines = source_lines(text)
    assert 1 <= diagnostic.line <= max(1, len(lines)), diagnostic
    assert diagnostic.col >= 1
    rendered = diagnostic.render().split("\n")
    assert rendered[0].startswith(f"fuzz.layers:{diagnostic.line}:{diagnostic.col}: ")
    if not text:
        return  # nothing to quote (an empty file has no line)
    assert len(rendered) == 3, rendered
    quoted = printable(lines[diagnostic.line - 1])
    assert rendered[1] == f"    {quoted}"
    caret = rendered[2]
    assert caret.endswith("^") and set(caret[:-1]) <= {" "}
    assert len(caret) - 5 == min(diagnostic.col - 1, len(quoted))


def exercise(text: str) -> None:
    diagnostics = check_source(text, "fuzz.layers")
    for diagnostic in diagnostics:
        assert_located(diagnostic, text)
    try:
        compiled = compile_source(text, "fuzz.layers")
    except LayerLanguageError as error:
        assert isinstance(error, LayerSyntaxError)
        assert any(d.is_error for d in diagnostics)
        assert error.diagnostics[0].is_error
        first = error.diagnostics[0]
        assert (error.path, error.line, error.col) == ("fuzz.layers", first.line, first.col)
        assert_located(first, text)
        if text:
            assert str(error).split("\n")[2].endswith("^")
        return
    assert not any(d.is_error for d in diagnostics)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Python's warnings were reported as diagnostics
        compile(compiled.text, "fuzz.py", "exec")  # the written module
        compiled.code()  # and the one the loader runs, positions mapped to the layer file


@FUZZ
@given(layer_file())
def test_generated_layer_files(text: str) -> None:
    exercise(text)


@FUZZ
@given(mutated())
def test_mutated_fixtures(text: str) -> None:
    exercise(text)


@settings(max_examples=300, deadline=None, database=None)
@given(st.text(max_size=200))
def test_arbitrary_text(text: str) -> None:
    exercise(text)


def test_the_generators_reach_both_outcomes() -> None:
    """The fuzzers are only useful if some inputs compile and some do not."""
    compiled = failed = 0
    for text in [*CORPUS, "layer A:\n    def f(): ...\n", "layer A\n"]:
        try:
            compile_source(text, "x.layers")
            compiled += 1
        except LayerLanguageError:
            failed += 1
    assert compiled >= 2 and failed >= 1
