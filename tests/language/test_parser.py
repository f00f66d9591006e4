"""The structural parser: what it builds, and where it says a file is malformed."""

from __future__ import annotations

import textwrap

import pytest

from contextros.language import LayerSyntaxError, parse
from contextros.language.parser import parse_with_diagnostics
from tests.language.conftest import FIXTURES


def errors(text: str) -> list[tuple[int, int, str]]:
    """(line, col, message) of every error the parser reports for `text`."""
    _, found = parse_with_diagnostics(textwrap.dedent(text), "t.layers")
    return [(d.line, d.col, d.message) for d in found if d.is_error]


def only_error(text: str) -> tuple[int, int, str]:
    found = errors(text)
    assert len(found) == 1, found
    return found[0]


def test_paper_listing1_is_two_layers_refining_getpos() -> None:
    tree = parse((FIXTURES / "paper_listing1.layers").read_text(), "paper_listing1.layers")
    assert [layer.name for layer in tree.layers] == ["Indoor", "Outdoor"]
    assert tree.header_lines == 11
    assert "class Location(NamedTuple)" in tree.header
    functions = tree.all_functions()
    assert [(f.key, f.layer, f.generated_name) for f in functions] == [
        ("getPos", "Indoor", "getPos_Indoor"),
        ("getPos", "Outdoor", "getPos_Outdoor"),
    ]
    assert (functions[0].at.line, functions[0].at.col) == (13, 9)


def test_relations_groups_hooks_base_and_descriptions() -> None:
    tree = parse((FIXTURES / "cleaner.layers").read_text(), "cleaner.layers")
    layers = {layer.name: layer for layer in tree.layers}
    assert [g.name for g in tree.groups] == ["location"]
    assert [m.name for m in tree.groups[0].members] == ["Indoor", "Outdoor"]
    assert layers["Indoor"].description == "Inside a building: careful and slow."
    assert [h.event for h in layers["Indoor"].hooks] == ["activate", "deactivate"]
    assert [h.generated_name for h in layers["Indoor"].hooks] == [
        "on_activate_Indoor",
        "on_deactivate_Indoor",
    ]
    assert [r.name for r in layers["Night"].after] == ["Indoor", "Outdoor"]
    docked = layers["Docked"]
    assert [r.name for r in docked.excludes] == ["Outdoor", "Night"]
    assert [r.name for r in docked.requires] == ["Indoor"]
    assert [(f.key, f.is_async) for f in docked.functions] == [
        ("status", True),
        ("Cleaner.clean", False),
    ]
    assert docked.functions[1].generated_name == "Cleaner_clean_Docked"
    assert [f.generated_name for f in tree.bases[0].functions] == ["speed"]


def test_python_that_looks_like_a_declaration_stays_in_the_header() -> None:
    tree = parse(
        textwrap.dedent(
            '''\
            layer = 3
            layer is None
            NOTE = """
            layer Fake:
            """
            layer Real:
                def f(): return layer
            '''
        )
    )
    assert [layer.name for layer in tree.layers] == ["Real"]
    assert tree.header_lines == 5


def test_method_bodies_keep_strings_that_reach_column_zero() -> None:
    tree = parse(
        textwrap.dedent(
            '''\
            layer A:
                def text() -> str:
                    return """
            layer B:
            """
                def other(): ...
            '''
        )
    )
    assert [layer.name for layer in tree.layers] == ["A"]
    text, other = tree.layers[0].functions
    assert text.lines[2].text == "layer B:"  # inside the string: not re-indented
    assert other.name == "other"


def test_decorators_belong_to_the_method_below_them() -> None:
    tree = parse("import functools\nlayer A:\n    @functools.cache\n    def f(): return 1\n")
    (function,) = tree.layers[0].functions
    assert function.name == "f"
    assert len(function.node.decorator_list) == 1


def test_comments_and_blank_lines_between_declarations() -> None:
    tree = parse(
        "# start\n\nlayer A:\n    # note\n\n    def f(): ...\n"
        "# between\n\nlayer B:\n    def f(): ...\n"
    )
    assert [layer.name for layer in tree.layers] == ["A", "B"]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "layer A excludes B,:\n    def f(): ...\n",
            (1, 20, "expected a layer name after 'excludes', found ':'"),
        ),
        (
            "layer class:\n    def f(): ...\n",
            (1, 7, "expected a layer name after 'layer', found 'class'"),
        ),
        ("layer A\n    def f(): ...\n", (1, 8, "expected ':' at the end of the layer declaration")),
        (
            "layer A foo:\n    def f(): ...\n",
            (1, 9, "expected 'excludes', 'requires', 'after', 'implies' or ':', found 'foo'"),
        ),
        (
            "layer A excludes:\n    def f(): ...\n",
            (1, 17, "expected a layer name after 'excludes', found ':'"),
        ),
        ("layer A: def f(): ...\n", (1, 10, "a layer's methods start on the next line, indented")),
        ("layer A excludes $:\n    def f(): ...\n", (1, 18, "unexpected character '$'")),
        ("group g A, B\n", (1, 9, "expected ':' after the group name")),
        ("group g: A B\n", (1, 12, "expected ',' between group members, found 'B'")),
        ("group g: A,\n", (1, 12, "expected a layer name in the group")),
        ("base: x\n", (1, 5, "expected 'base:' on a line of its own")),
        ("layer A:\n", (1, 9, "layer A is empty: expected indented methods below it")),
        (
            "layer A:\n    def f(): ...\nx = 1\n",
            (
                3,
                1,
                "expected a declaration ('layer', 'base', 'group', "
                "'rule', 'parameter', 'lifecycle' or 'topic'), "
                "found 'x'; Python code "
                "belongs in the header, above the first declaration",
            ),
        ),
        (
            "layer A:\n    def f(): ...\n  def g(): ...\n",
            (3, 3, "unindent does not match the indentation of the block's other items"),
        ),
        (
            "layer A:\n    x = 1\n",
            (
                2,
                5,
                "expected a method ('def name(...):' or 'def Class.name(...):'), a hook "
                "(on activate:) in layer A",
            ),
        ),
        (
            "layer A:\n    on start:\n        pass\n",
            (2, 5, "expected 'on activate:' or 'on deactivate:'"),
        ),
        ("layer A:\n    on activate\n        pass\n", (2, 16, "expected ':' after 'on activate'")),
        (
            "base:\n    on activate:\n        pass\n",
            (2, 5, "activation hooks belong to a layer, not to the base block"),
        ),
        ("group g: A\n    B\n", (2, 5, "unexpected indentation: a group is declared on one line")),
    ],
)
def test_structural_errors_at_their_exact_position(
    text: str, expected: tuple[int, int, str]
) -> None:
    assert only_error(text) == expected


def test_unexpected_indentation_between_declarations() -> None:
    # an indented line after a column-0 comment still belongs to the block
    assert errors("layer A:\n    def f(): ...\n\n# x\n  \n    def g(): ...\n") == []
    ((line, _, message),) = errors("  x = 1\nlayer A:\n    def f(): ...\n")
    assert (line, message) == (1, "Python syntax error: unexpected indent")
    assert errors("layer A:\n    def f(): ...\n\n  \n\n") == []


def test_python_syntax_errors_in_bodies_point_into_the_layer_file() -> None:
    text = "layer A:\n    def f(x):\n        return (x +)\n"
    assert only_error(text) == (3, 20, "Python syntax error: invalid syntax")
    text = "layer A:\n    def Cls.f(self):\n        return (1,\n"
    line, col, message = only_error(text)
    assert (line, col) == (3, 16)
    assert "was never closed" in message


def test_python_syntax_error_in_the_def_line_after_a_renamed_target() -> None:
    # `Cleaner.clean` becomes `Cleaner_clean_A` in the compiled code: columns after it
    # must still refer to the layer file.
    line, col, message = only_error("layer A:\n    def Cleaner.clean(self, 1): ...\n")
    assert (line, col) == (2, 29)
    assert message.startswith("Python syntax error")


def test_python_syntax_errors_in_the_header() -> None:
    assert only_error("import\nlayer A:\n    def f(): ...\n") == (
        1,
        7,
        "Python syntax error: invalid syntax",
    )


def test_python_syntax_warnings_become_diagnostics() -> None:
    _, found = parse_with_diagnostics('layer A:\n    def f():\n        return "\\d"\n', "t.layers")
    (warning,) = found
    assert not warning.is_error
    assert warning.line == 3
    assert "invalid escape sequence" in warning.message


def test_parse_raises_every_error_as_one_layer_syntax_error() -> None:
    with pytest.raises(LayerSyntaxError) as caught:
        parse("layer def:\n    def f(): ...\nlayer B\n    def f(): ...\n", "bad.layers")
    error = caught.value
    assert isinstance(error, SyntaxError)
    assert (error.path, error.line, error.col) == ("bad.layers", 1, 7)
    assert (error.filename, error.lineno, error.offset) == ("bad.layers", 1, 7)
    assert [d.line for d in error.diagnostics] == [1, 3]
    assert str(error).splitlines() == [
        "bad.layers:1:7: error: expected a layer name after 'layer', found 'def'",
        "    layer def:",
        "          ^",
        "(and 1 more error)",
    ]


def test_only_python_newlines_end_lines() -> None:
    # A form feed and a line separator inside a string are not line breaks for Python.
    text = 'NOTE = "a\u2028b\x0cc"\r\nlayer A:\r\n    def f():\r\n        return (1 +)\r\n'
    _, found = parse_with_diagnostics(text, "t.layers")
    assert [(d.line, d.col) for d in found] == [(4, 20)]
    tree = parse('NOTE = "a\u2028b"\nlayer A:\n    def f(): ...\n')
    assert tree.header == 'NOTE = "a\u2028b"'


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "layer __debug__:\n    def f(): ...\n",
            (1, 7, "'__debug__' cannot be assigned in Python"),
        ),
        (
            "layer A:\n    def __debug__(): ...\n",
            (2, 9, "'__debug__' cannot be assigned in Python"),
        ),
        (
            "layer \ufb01:\n    def f(): ...\n",
            (1, 7, "'\ufb01' is not in the normal form Python uses for identifiers (NFKC)"),
        ),
    ],
)
def test_names_python_would_refuse_or_rename(text: str, expected: tuple[int, int, str]) -> None:
    assert only_error(text) == expected
