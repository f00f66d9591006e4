"""Diagnostics of the C++ flavour: each broken file gives one located error (file:line:col,
the line and a caret), from the same checker as the Python flavour; and fuzzing: mutated C++
layer files only ever raise the language's own errors."""

from __future__ import annotations

import os
import random
from pathlib import Path

import pytest

from contextros.cli import main
from contextros.language import LayerLanguageError, LayerSyntaxError, check_source
from contextros.language.cpp.generator import compile_cpp
from tests.language.test_cpp_compiler import CPP_FIXTURES, cxx

OK = "int f() { return 1; }\n"

BROKEN = {
    "unclosed block": ("Layer A [\n" + OK, 1, 9, "this block is not closed: expected ']'"),
    "unclosed brace": ("Layer A [\nint f() { return 1;\n]\n", 2, 9, "'{' is not closed"),
    "missing bracket": ("Layer A\n" + OK + "]\n", 2, 1, "expected 'excludes', 'requires'"),
    "misspelt relation": ("Layer A with B [\n" + OK + "]\n", 1, 9, "found 'with'"),
    "unknown layer": ("Layer A after C [\n" + OK + "]\n", 1, 15, "unknown layer 'C' in 'after'"),
    "names itself": ("Layer A excludes A [\n" + OK + "]\n", 1, 18, "names itself in 'excludes'"),
    "requires and excludes": (
        "Layer B [\n" + OK + "]\nLayer A excludes B requires B [\nint g() { return 1; }\n]\n",
        4,
        29,
        "both requires and excludes 'B'",
    ),
    "unknown group member": (
        "Layer A [\n" + OK + "]\ngroup g: A, Z;\n",
        4,
        13,
        "unknown layer 'Z' in group 'g'",
    ),
    "group without colon": ("Layer A [\n" + OK + "]\ngroup g A;\n", 4, 9, "expected ':'"),
    "layer twice": (
        "Layer A [\n" + OK + "]\nLayer A [\nint g() { return 1; }\n]\n",
        4,
        7,
        "already declared",
    ),
    "keyword as layer name": ("Layer class [\n" + OK + "]\n", 1, 7, "'class' is a C++ keyword"),
    "signature mismatch": (
        "Layer A [\ndouble f(double x) { return x; }\n]\n"
        "Layer B after A [\ndouble f(int x) { return x; }\n]\n",
        5,
        8,
        "incompatible signature: double f(int) does not match double f(double) in layer A",
    ),
    "method vs base": (
        "struct R { int g() const; };\nbase [\nint R::g() const { return 1; }\n]\n"
        "Layer A [\nint R::g() { return 2; }\n]\n",
        6,
        8,
        "int R::g() does not match int R::g() const in the base block",
    ),
    "method vs its declaration": (
        "struct R {\n  virtual int g(int a = 1) const;\n};\n"
        "Layer A [\nint R::g(long a) const { return 2; }\n]\n",
        5,
        8,
        "int R::g(long) const does not match the declaration int g(int) const in class R (line 2)",
    ),
    "not a function": ("Layer A [\nint x = 3;\n]\n", 2, 1, "expected a C++ function definition"),
    "syntax error": (
        "Layer A [\nint f() { return 1 }\n]\n",
        2,
        19,
        "C++ syntax error: missing ';'",
    ),
    "static": ("Layer A [\nstatic " + OK + "]\n", 2, 1, "'static' is not allowed"),
    "template": (
        "Layer A [\ntemplate <class T> T f(T x) { return x; }\n]\n",
        2,
        1,
        "a template cannot be layered (its dispatch would need one layered function per "
        "instantiation) in layer A: write a plain function per type you need (name_int, "
        "name_double), layer those, and have the template in the header part call them",
    ),
    "method template": (
        "struct R {\n  template <class T> int g(T x);\n};\nLayer A [\n"
        "template <class T> int R::g(T x) { return 1; }\n]\n",
        5,
        1,
        "a template cannot be layered",
    ),
    "code after the declarations": ("Layer A [\n" + OK + "]\nint y;\n", 4, 1, "found 'int'"),
    "empty layer": ("Layer A [\n]\n", 1, 9, "layer A is empty"),
    "method twice": (
        "Layer A [\n" + OK + "int f() { return 2; }\n]\n",
        3,
        5,
        "f is already defined",
    ),
    "variadic": ("Layer A [\nint f(int n, ...) { return n; }\n]\n", 2, 14, "variadic"),
    "destructor": ("struct R { ~R(); };\nLayer A [\nR::~R() {}\n]\n", 3, 1, "cannot layer 'R::~R'"),
    "static method": (
        "#include <string>\nstruct R {\n  static int count();\n};\nLayer A [\n"
        "int R::count() { return 1; }\n]\n",
        6,
        8,
        "cannot layer R::count: class R declares it static",
    ),
    "namespaced free function": (
        "#include <string>\nnamespace nav {\nint speed(int x);\n}\nLayer A [\n"
        "int nav::speed(int x) { return x; }\n]\n",
        6,
        10,
        "cannot layer nav::speed: nav is a namespace",
    ),
    "guard on a base function": (
        "base [\nint f(int x) when (x > 1) { return x; }\n]\n",
        2,
        20,
        "a guard ('when ...') belongs to a layer's partial",
    ),
    "guard with an unnamed parameter": (
        "base [\nint f(int x, int y) { return x + y; }\n]\n"
        "Layer A [\nint f(int x, int) when (x > 1) { return 2; }\n]\n",
        5,
        25,
        "a guarded implementation of f must name every parameter",
    ),
    "guard not closed": (
        "Layer A [\nint f(int x) when (x > 1 { return 1; }\n]\n",
        2,
        19,
        "not closed",
    ),
    "hook in the base block": (
        "base [\n" + OK + "on activate { }\n]\n",
        3,
        1,
        "'on activate' belongs to a layer: the base block has no hooks",
    ),
    "hook misspelt": ("Layer A [\n" + OK + "on activated { }\n]\n", 3, 4, "found 'activated'"),
    "hook without a body": ("Layer A [\n" + OK + "on activate;\n]\n", 3, 12, "expected '{'"),
    "hook twice": (
        "Layer A [\n" + OK + "on activate { }\non activate { }\n]\n",
        4,
        1,
        "already has an 'on activate' hook at line 3",
    ),
    "description not first": (
        "Layer A [\n" + OK + '"late";\n]\n',
        3,
        1,
        "a description is a string literal first in a layer's block",
    ),
    "description not an ordinary literal": (
        'Layer A [\nu8"wide"\n' + OK + "]\n",
        2,
        1,
        "a layer's description is an ordinary string literal",
    ),
    # Overloads, templates and ref-qualified methods: refused, saying what to write instead.
    "overload of a base function": (
        "base [\nint f(int x) { return x; }\n]\nLayer A [\ndouble f(double x) { return x; }\n]\n",
        5,
        8,
        "C++ overloads cannot be layered: give this overload its own name (f_double) and layer "
        "it, and overload f in the header part to call it",
    ),
    "overloads in one layer": (
        "Layer A [\nint f(int x) { return x; }\nint f(const char* s) { return 1; }\n]\n",
        3,
        5,
        "f is already defined in layer 'A' at line 2; C++ overloads cannot be layered: "
        "give this overload its own name (f_const_char)",
    ),
    "overloaded in the header part": (
        "int speed(int);\ndouble speed(double);\nLayer A [\nint speed(int x) { return x; }\n]\n",
        4,
        5,
        "cannot layer speed: the header part declares 2 overloads of it (lines 1, 2), and a "
        "layered function is found by its name; give the one to layer its own name "
        "(speed_layered), layer that, and have the overload call it",
    ),
    "overloaded method": (
        "struct R {\n  int g(int);\n  int g(double);\n};\nLayer A [\n"
        "int R::g(int x) { return x; }\n]\n",
        6,
        8,
        "cannot layer R::g: class R declares 2 overloads of it (lines 2, 3)",
    ),
    "ref-qualified method": (
        "struct R {\n  int g() &&;\n};\nLayer A [\nint R::g() && { return 1; }\n]\n",
        5,
        12,
        "a ref-qualified method ('&&') cannot be layered: its dispatch is a plain method; drop "
        "the qualifier, or layer a plain method (name_layered) and call it from this one",
    ),
    "lvalue ref-qualified method": (
        "struct R {\n  int g() const &;\n};\nLayer A [\nint R::g() const & { return 1; }\n]\n",
        5,
        18,
        "a ref-qualified method ('&') cannot be layered",
    ),
    "unknown class": (
        "Layer A [\nint Robot::f() { return 1; }\n]\n",
        2,
        12,
        "class 'Robot' is not defined in the header: include it",
    ),
}


@pytest.mark.parametrize("case", sorted(BROKEN))
def test_a_broken_file_gives_one_located_error(case: str) -> None:
    source, line, col, message = BROKEN[case]
    errors = [d for d in check_source(source, "broken.cpp.layers") if d.is_error]
    assert len(errors) == 1, [d.render() for d in errors]
    (error,) = errors
    assert (error.path, error.line, error.col) == ("broken.cpp.layers", line, col)
    assert message in error.message
    with pytest.raises(LayerSyntaxError) as raised:
        compile_cpp(source, "broken.cpp.layers")
    assert (raised.value.line, raised.value.col) == (line, col)
    rendered = raised.value.render().splitlines()
    assert rendered[0].startswith(f"broken.cpp.layers:{line}:{col}: error: ")
    assert rendered[2] == "    " + " " * (col - 1) + "^"


def test_listing_1_warns_of_the_layer_interaction_problem() -> None:
    source = (CPP_FIXTURES / "paper_listing1.cpp.layers").read_text()
    (warning,) = check_source(source, "paper_listing1.cpp.layers")
    assert not warning.is_error
    assert (warning.line, warning.col) == (8, 10)
    assert "getPos is refined by layers 'Indoor' (line 5) and 'Outdoor'" in warning.message
    assert "declare 'Layer Outdoor after Indoor'" in warning.message
    settled = source.replace("/*Layer declaration part */", "group location: Indoor, Outdoor;")
    assert check_source(settled, "paper_listing1.cpp.layers") == []


def test_proceed_in_the_base_is_a_warning() -> None:
    source = "base [\nint f() { return proceed(); }\n]\nLayer A [\n" + OK + "]\n"
    (warning,) = check_source(source, "x.cpp.layers")
    assert (warning.line, warning.col, warning.is_error) == (2, 5, False)
    assert "proceed() in the base implementation of f" in warning.message


def test_brackets_strings_and_comments_in_bodies_do_not_end_a_block() -> None:
    source = (
        "Layer A [\n"
        "int f(int i) {\n"
        '  int a[2] = {1, 2}; auto g = [&](int k) { return a[k]; }; return g(i) + "]"[0];\n'
        "}\n"
        "// ] in a comment\n"
        "/* ] */ int h() { return ']'; }\n"
        "]\n"
    )
    assert check_source(source, "x.cpp.layers") == []


def _mutations(source: str, rng: random.Random) -> str:
    text = list(source)
    pieces = [
        "[",
        "]",
        "{",
        "}",
        "(",
        ")",
        ";",
        ",",
        ":",
        "Layer ",
        "after ",
        "::",
        '"',
        "'",
        "/*",
        "\n",
        "proceed(",
        "const ",
    ]
    for _ in range(rng.randint(1, 4)):
        where = rng.randrange(len(text) + 1)
        action = rng.random()
        if action < 0.4 and text:
            del text[min(where, len(text) - 1) : min(where + rng.randint(1, 6), len(text))]
        elif action < 0.8:
            text[where:where] = list(rng.choice(pieces))
        else:
            lines = "".join(text).split("\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
            text = list("\n".join(lines))
    return "".join(text)


# `make test` mutates each fixture 100 times; `make fuzz` 5,000 (CONTEXTROS_FUZZ_EXAMPLES).
MUTATIONS = int(os.environ.get("CONTEXTROS_FUZZ_EXAMPLES", "100"))


@pytest.mark.parametrize(
    "fixture", ["robot.cpp.layers", "paper_listing1.cpp.layers", "guards.cpp.layers"]
)
def test_mutated_files_only_raise_the_languages_errors(fixture: str) -> None:
    original = (CPP_FIXTURES / fixture).read_text()
    rng = random.Random(fixture)
    for _ in range(MUTATIONS):
        source = _mutations(original, rng)
        diagnostics = check_source(source, fixture)  # never raises
        try:
            compile_cpp(source, fixture, output="out.layers.cpp")
        except LayerLanguageError as error:
            assert error.line >= 1 and error.col >= 1
            assert any(d.is_error for d in diagnostics)


def test_a_function_of_an_unseen_scope_must_be_a_method_where_cpp_can_tell(tmp_path: Path) -> None:
    """Behind an #include the compiler cannot see whether `nav` is a class or a namespace:
    the generated code asserts it, located in the layer file."""
    (tmp_path / "nav.hpp").write_text("namespace nav {\nint speed(int x);\n}\n")
    layers = tmp_path / "hidden.cpp.layers"
    layers.write_text('#include "nav.hpp"\n\nLayer A [\nint nav::speed(int x) { return x; }\n]\n')
    assert main(["compile", str(layers), "-o", str(tmp_path / "hidden.layers.cpp")]) == 0
    build = cxx("-std=c++17", "-c", "hidden.layers.cpp", "-o", "hidden.o", cwd=tmp_path)
    assert build.returncode != 0
    first = next(line for line in build.stderr.splitlines() if "error" in line)
    assert first.startswith(f"{layers}:4:"), build.stderr
    assert "cannot layer nav::speed: not a non-static member function" in first


def test_line_paths_open_from_where_the_build_runs_the_compiler(tmp_path: Path) -> None:
    """As CMake does: the layer file named absolutely, the output in a subdirectory of the
    build directory, the compiler run in the build directory (ninja). The path in the
    compiler's message opens from there, at the layer file's line and column."""
    layers = tmp_path / "src" / "x.cpp.layers"
    layers.parent.mkdir()
    layers.write_text("Layer A [\nint f() {\n  return undeclared_name;\n}\n]\n")
    build = tmp_path / "build"
    output = build / "sub" / "contextros_layers" / "x.layers.cpp"
    output.parent.mkdir(parents=True)
    assert main(["compile", str(layers), "-o", str(output)]) == 0
    result = cxx("-std=c++17", "-c", output.relative_to(build), "-o", "x.o", cwd=build)
    assert result.returncode != 0
    first = next(line for line in result.stderr.splitlines() if ": error:" in line)
    path, line, col, _ = first.split(":", 3)
    assert (line, col) == ("3", "10"), first
    assert (build / path).resolve() == layers.resolve(), first
