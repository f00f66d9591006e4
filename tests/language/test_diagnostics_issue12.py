"""The newcomer's diagnostics (issue 12): the first error is the real one, one mistake
gives one error, and the caret stands where the indentation goes wrong."""

from __future__ import annotations

import pytest

from contextros.language import LayerSyntaxError, check_source, compile_source
from tests.language.conftest import FIXTURES

CLEANER = (FIXTURES / "cleaner.layers").read_text(encoding="utf-8")


def errors_of(text: str) -> list[tuple[int, int, str]]:
    return [(d.line, d.col, d.message) for d in check_source(text, "c.layers") if d.is_error]


def line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_a_missing_colon_is_the_only_error_and_the_first_one() -> None:
    text = CLEANER.replace("layer Outdoor:", "layer Outdoor")
    row = line_of(text, "layer Outdoor")
    assert errors_of(text) == [(row, 14, "expected ':' at the end of the layer declaration")]
    with pytest.raises(LayerSyntaxError) as caught:
        compile_source(text, "c.layers")
    assert (caught.value.line, caught.value.col) == (row, 14)


def test_a_bad_relation_list_does_not_make_the_layer_unknown_elsewhere() -> None:
    text = CLEANER.replace("layer Outdoor:", "layer Outdoor excludes:")
    ((row, _, message),) = errors_of(text)
    assert row == line_of(text, "layer Outdoor") and "a layer name after 'excludes'" in message


def test_a_declaration_indented_by_one_space_is_one_error_at_the_indentation() -> None:
    text = CLEANER.replace("\nlayer Outdoor:", "\n layer Outdoor:")
    row = line_of(text, " layer Outdoor:")
    ((line, col, message),) = errors_of(text)
    assert (line, col) == (row, 1)
    assert "'layer' must start at the beginning of the line" in message


def test_an_indented_group_or_base_is_one_error_too() -> None:
    text = CLEANER.replace("\nbase:", "\n  base:")
    assert [(r, c) for r, c, _ in errors_of(text)] == [(line_of(text, "  base:"), 1)]
    text = CLEANER.replace("\ngroup location", "\n\tgroup location")
    assert [(r, c) for r, c, _ in errors_of(text)] == [(line_of(text, "\tgroup"), 1)]


def test_inconsistent_indentation_puts_the_caret_at_the_indentation() -> None:
    text = "layer A:\n    def f():\n        x = 1\n      return x\n"
    ((line, col, message),) = errors_of(text)
    assert (line, col) == (4, 7)  # where `return` starts: the unindent that matches nothing
    assert "indent" in message
    text = "layer A:\n    def f():\n        if x:\n                y = 1\n             z = 2\n"
    ((line, col, _),) = errors_of(text)
    assert (line, col) == (5, 14)


def test_an_unexpected_indent_in_a_body_points_at_the_indented_code() -> None:
    text = "layer A:\n    def f():\n        x = 1\n            y = 2\n"
    ((line, col, message),) = errors_of(text)
    assert (line, col, message) == (4, 13, "Python syntax error: unexpected indent")


def test_every_error_of_a_broken_file_is_rendered_with_its_line_and_a_caret() -> None:
    for text in ["layer A", "layer A:\n", "layer A:\n    def f(:\n", "base:"]:
        for diagnostic in check_source(text, "c.layers"):
            rendered = diagnostic.render().splitlines()
            assert len(rendered) == 3 and rendered[2].strip() == "^", rendered
