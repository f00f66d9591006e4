"""The checker: each error and each layer-interaction warning, at its exact position."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from contextros.language import LayerSyntaxError, check_file, check_source
from contextros.language.checker import check_files, checked
from tests.language.conftest import FIXTURES

Found = tuple[str, int, int, str]


def diagnostics(text: str) -> list[Found]:
    return [
        (d.severity.value, d.line, d.col, d.message)
        for d in check_source(textwrap.dedent(text), "t.layers")
    ]


def only(text: str) -> Found:
    found = diagnostics(text)
    assert len(found) == 1, found
    return found[0]


def test_the_fixtures() -> None:
    assert [d.render() for d in check_file(FIXTURES / "cleaner.layers")] == []
    (warning,) = check_file(FIXTURES / "paper_listing1.layers")
    assert (warning.severity.value, warning.line, warning.col) == ("warning", 18, 9)


def test_duplicate_layer() -> None:
    assert only(
        """\
        layer A:
            def f(): ...
        layer A:
            def g(): ...
        """
    ) == ("error", 3, 7, "layer 'A' is already declared at line 1")


def test_method_defined_twice_in_one_layer() -> None:
    assert only(
        """\
        layer A:
            def f(): ...

            def f(): ...
        """
    ) == ("error", 4, 9, "f is already defined in layer 'A' at line 2")


def test_method_defined_twice_in_the_base() -> None:
    assert only(
        """\
        class C: ...
        base:
            def C.f(self): ...
            def C .f(self): ...
        """
    ) == ("error", 4, 9, "C.f is already defined in the base block at line 3")


@pytest.mark.parametrize(
    ("declaration", "col", "context"),
    [
        ("layer A excludes Nope:", 18, "'excludes' of layer 'A'"),
        ("layer A requires Nope:", 18, "'requires' of layer 'A'"),
        ("layer A after Nope:", 15, "'after' of layer 'A'"),
    ],
)
def test_relation_naming_an_unknown_layer(declaration: str, col: int, context: str) -> None:
    assert only(f"{declaration}\n    def f(): ...\n") == (
        "error",
        1,
        col,
        f"unknown layer 'Nope' in {context} (declared layers: A)",
    )


def test_group_naming_an_unknown_layer_or_a_layer_twice() -> None:
    assert diagnostics(
        """\
        group g: A, Nope, A
        group h: A
        group g: A
        layer A:
            def f(): ...
        """
    ) == [
        ("error", 1, 13, "unknown layer 'Nope' in group 'g' (declared layers: A)"),
        ("error", 1, 19, "layer 'A' is listed twice in group 'g'"),
        ("error", 2, 10, "layer 'A' is already in group 'g'; a layer belongs to at most one group"),
        ("error", 3, 7, "group 'g' is already declared at line 1"),
    ]


def test_a_layer_relating_to_itself_or_requiring_what_it_excludes() -> None:
    assert diagnostics(
        """\
        layer B:
            def g(): ...
        layer A excludes A, B requires B:
            def f(): ...
        """
    ) == [
        ("error", 3, 18, "layer 'A' names itself in 'excludes'"),
        ("error", 3, 32, "layer 'A' both requires and excludes 'B'"),
    ]


def test_incompatible_signatures_in_different_layers() -> None:
    assert only(
        """\
        layer A:
            def f(x, y=1): ...
        layer B excludes A:
            def f(x, y): ...
        """
    ) == (
        "error",
        4,
        9,
        "incompatible signature: f(x, y) does not match f(x, y=1) in layer A (line 2)",
    )


def test_incompatible_signature_against_the_base() -> None:
    found = only(
        """\
        base:
            def f(x, *, scale=1.0): ...
        layer A:
            def f(x, scale=1.0): ...
        """
    )
    assert found[:3] == ("error", 4, 9)
    assert "in the base block (line 2)" in found[3]


def test_async_and_plain_implementations_do_not_mix() -> None:
    assert only(
        """\
        layer A:
            async def f(): ...
        layer B excludes A:
            def f(): ...
        """
    ) == ("error", 4, 9, "f() is not async, but f in layer A (line 2) is async")


def test_annotations_and_default_values_may_differ() -> None:
    assert (
        diagnostics(
            """\
        layer A:
            def f(x: int, y: int = 1) -> int: ...
        layer B excludes A:
            def f(x, y=2): ...
        """
        )
        == []
    )


def test_methods_of_classes_the_header_does_not_define() -> None:
    assert only("layer A:\n    def Robot.f(self): ...\n") == (
        "error",
        2,
        9,
        "class 'Robot' is not defined in the header: import it or define it above the first "
        "declaration",
    )
    assert diagnostics("from robots import Robot\nlayer A:\n    def Robot.f(self): ...\n") == []
    assert diagnostics("from robots import *\nlayer A:\n    def Robot.f(self): ...\n") == []


def test_a_method_needs_a_parameter_for_the_instance() -> None:
    assert only("class Robot: ...\nlayer A:\n    def Robot.f(): ...\n") == (
        "error",
        3,
        9,
        "method Robot.f takes no parameters: it needs one for the instance (self)",
    )


@pytest.mark.parametrize(
    ("block", "decorator"),
    [
        ("layer A", "functools.cache"),  # cached object, not a function: failed on import
        ("layer A", "functools.lru_cache(maxsize=2)"),
        ("layer A", "wraps_nothing"),
        ("base", "functools.cache"),
    ],
)
def test_other_decorators_are_rejected_at_the_decorator(block: str, decorator: str) -> None:
    source = f"import functools\n{block}:\n    @{decorator}\n    def f():\n        return 1\n"
    assert only(source) == (
        "error",
        3,
        6,
        f"decorators are not supported on implementations: @{decorator} would replace f by "
        "what it returns, and the core layers only the plain function; decorate a helper in "
        "the header and call it from the body",
    )


@pytest.mark.parametrize(
    ("name", "what"),
    [
        ("__new__", "a static method"),
        ("__init_subclass__", "a class method"),
        ("__class__", "a 'getset_descriptor' attribute"),
    ],
)
def test_what_object_gives_as_no_instance_method_cannot_be_layered(name: str, what: str) -> None:
    assert only(f"class C: ...\nlayer A:\n    def C.{name}(cls): ...\n") == (
        "error",
        3,
        9,
        f"C.{name} cannot be layered: every class has {name} from object, as {what}, and a "
        "layer refines only instance methods (plain functions such as __init__ or __repr__)",
    )


def test_descriptor_decorators_are_rejected() -> None:
    assert only("layer A:\n    @staticmethod\n    def f(): ...\n") == (
        "error",
        3,
        9,
        "@staticmethod makes f a staticmethod object; layered implementations must stay plain "
        "functions",
    )


def test_generated_names_must_not_collide() -> None:
    assert diagnostics(
        """\
        def f_A(): ...
        Night = 1
        layer A:
            def f(): ...
        layer Night excludes A:
            def f(): ...
        """
    ) == [
        (
            "error",
            4,
            9,
            "the compiled name 'f_A' of f is already a name defined in the header; rename the "
            "method or the layer",
        ),
        ("error", 5, 7, "layer 'Night' would shadow 'Night', a name defined in the header"),
    ]


def test_generated_names_of_two_methods_colliding() -> None:
    # f in layer A_B and f_A in layer B both compile to f_A_B
    found = diagnostics("layer A_B:\n    def f(): ...\nlayer B:\n    def f_A(): ...\n")
    assert found == [
        (
            "error",
            4,
            9,
            "the compiled name 'f_A_B' of f_A is already f in layer A_B; rename the method or "
            "the layer",
        )
    ]


def test_dispatch_name_colliding_with_the_header() -> None:
    assert only("def f(): ...\nlayer A:\n    def f(): ...\n") == (
        "error",
        3,
        9,
        "the dispatch function 'f' of f is already a name defined in the header; rename the "
        "method or the layer",
    )


def test_proceed_in_a_base_implementation() -> None:
    assert only("base:\n    def f():\n        return proceed()\n") == (
        "warning",
        2,
        9,
        "proceed() in the base implementation of f has no next implementation to run: it "
        "raises at run time",
    )


# -- the layer interaction problem -------------------------------------------------------


def test_layers_that_may_be_active_together_with_no_order() -> None:
    assert only(
        """\
        layer A:
            def f(): ...
        layer B:
            def f(): ...
        """
    ) == (
        "warning",
        4,
        9,
        "f is refined by layers 'A' (line 2) and 'B', which may be active together with no "
        "declared order, so the result depends on which was activated last; declare "
        "'layer B after A' (or the reverse), or make them exclusive ('excludes', 'group')",
    )


@pytest.mark.parametrize(
    "relation",
    [
        "group g: A, B\n",
        "layer B excludes A:\n    def g(): ...\n",
        "layer B after A:\n    def g(): ...\n",
    ],
)
def test_declared_relations_silence_the_interaction_warning(relation: str) -> None:
    name_b = "layer B:" if relation.startswith("group") else ""
    text = f"layer A:\n    def f(): ...\n{relation}"
    if name_b:
        text += "layer B:\n    def f(): ...\n"
    else:
        text += "    def f(): ...\n"
    assert diagnostics(text) == []


def test_order_is_transitive_and_requires_closure_counts() -> None:
    assert diagnostics(
        """\
        group where: Indoor, Outdoor
        layer Indoor:
            def f(): ...
        layer Outdoor:
            def f(): ...
        layer Mid after Indoor:
            def g(): ...
        layer Top after Mid:
            def f(): ...
        layer Lamp requires Outdoor:
            def h(): ...
        layer Dim requires Indoor:
            def h(): ...
        """
    ) == [
        (
            "warning",
            9,
            9,
            "f is refined by layers 'Outdoor' (line 5) and 'Top', which may be active together "
            "with no declared order, so the result depends on which was activated last; "
            "declare 'layer Top after Outdoor' (or the reverse), or make them exclusive "
            "('excludes', 'group')",
        ),
    ]


def test_requires_cycle() -> None:
    assert diagnostics(
        """\
        layer A requires B:
            def f(): ...
        layer B requires C:
            def g(): ...
        layer C requires A:
            def h(): ...
        """
    ) == [
        (
            "warning",
            1,
            18,
            "'requires' cycle: A -> B -> C -> A; these layers can only be activated together, "
            "in one switch",
        )
    ]


def test_after_cycle_is_an_error() -> None:
    assert only(
        """\
        layer A after B:
            def f(): ...
        layer B after A:
            def f(): ...
        """
    ) == ("error", 1, 15, "'after' cycle: A -> B -> A; an order cannot go both ways")


def test_layer_that_can_never_be_activated() -> None:
    assert diagnostics(
        """\
        group where: Indoor, Outdoor
        layer Indoor:
            def f(): ...
        layer Outdoor:
            def g(): ...
        layer Confused requires Indoor, Outdoor:
            def h(): ...
        layer Worse requires Confused:
            def k(): ...
        """
    ) == [
        (
            "warning",
            6,
            7,
            "layer 'Confused' can never be activated: it requires Indoor, Outdoor; 'Indoor' and "
            "'Outdoor' exclude each other",
        ),
        (
            "warning",
            8,
            7,
            "layer 'Worse' can never be activated: it requires Confused, Indoor, Outdoor; "
            "'Indoor' and 'Outdoor' exclude each other",
        ),
    ]


def test_checked_raises_on_errors_and_returns_warnings() -> None:
    _, warnings = checked("layer A:\n    def f(): ...\nlayer B:\n    def f(): ...\n")
    assert [w.line for w in warnings] == [4]
    with pytest.raises(LayerSyntaxError) as caught:
        checked("layer A after Z:\n    def f(): ...\n", "z.layers")
    assert (caught.value.line, caught.value.col) == (1, 15)


def test_an_unreadable_file_is_an_error_not_a_crash(tmp_path: object) -> None:
    (found,) = check_file("/nonexistent/x.layers")
    assert (found.is_error, found.line, found.col) == (True, 1, 1)
    assert "cannot read the layer file" in found.message


def test_proceed_in_a_method_without_the_instance() -> None:
    assert only(
        """\
        class Robot:
            def go(self, speed): ...
        layer A:
            def Robot.go(self, speed):
                return 1 + proceed(speed)
        """
    ) == (
        "warning",
        5,
        20,
        "proceed() in Robot.go does not pass the instance first: the next implementation is "
        "called with the method's arguments, as proceed(self, ...)",
    )
    assert (
        diagnostics(
            """\
            class Robot: ...
            layer A:
                def Robot.go(this, *args):
                    return proceed(this, *args) or proceed(*args)
            """
        )
        == []
    )


@pytest.mark.parametrize(
    "name", ["_Layer", "_layered", "_layered_method", "proceed", "__layers__", "__layer_order__"]
)
def test_names_the_compiled_module_defines_are_reserved(name: str) -> None:
    # A layer of that name, and a method whose dispatch function has it: both replace what
    # the compiled module needs (the import then fails); located errors instead.
    found = diagnostics(f"layer {name}:\n    def f(): ...\nbase:\n    def {name}(): ...\n")
    assert [(sev, line, col) for sev, line, col, _ in found] == [
        ("error", 1, 7),
        ("error", 4, 9),
    ], found
    assert f"layer {name!r} would shadow {name!r}" in found[0][3]
    assert f"the dispatch function {name!r} of {name} is already" in found[1][3]


def test_a_layer_named_like_a_module_attribute_is_refused() -> None:
    assert only("layer __name__:\n    def f(): ...\n") == (
        "error",
        1,
        7,
        "layer '__name__' would shadow '__name__', a name Python sets on every module",
    )


def test_hook_functions_are_claimed_names() -> None:
    assert only("layer L:\n    on activate:\n        pass\n    def on_activate(): ...\n") == (
        "error",
        4,
        9,
        "the compiled name 'on_activate_L' of on_activate is already the 'on activate' hook "
        "of layer 'L'; rename the method or the layer",
    )
    assert only("def on_deactivate_L(): ...\nlayer L:\n    on deactivate:\n        pass\n") == (
        "error",
        3,
        5,
        "the compiled name 'on_deactivate_L' of the 'on deactivate' hook of layer 'L' is "
        "already a name defined in the header; rename the layer",
    )


def test_reserved_names_checked_clean_compile_and_run() -> None:
    from contextros.language.compiler import compile_source

    # Names near the reserved ones stay free, and what checks clean imports.
    source = "layer Layer:\n    def layered(): return 1\nbase:\n    def layers(): return 2\n"
    assert diagnostics(source) == []
    namespace: dict[str, object] = {"__name__": "reserved_names_probe"}
    exec(compile_source(source, "t.layers").code(), namespace)
    assert namespace["__layers__"] == (namespace["Layer"],)


def test_a_hook_declared_twice_in_a_layer() -> None:
    # Found by tests/language/test_fuzz.py: the compiled module repeated `on_activate=`.
    assert only("layer A:\n    on activate:\n        pass\n    on activate:\n        pass\n") == (
        "error",
        4,
        5,
        "layer 'A' already has an 'on activate' hook at line 2",
    )


BOM = "\ufeff"


def test_a_file_saved_with_a_byte_order_mark_checks_like_one_without(tmp_path: object) -> None:
    from pathlib import Path

    assert isinstance(tmp_path, Path)
    path = tmp_path / "bom.layers"
    text = "layer A:\n    def f():\n        return 1 +\n"
    path.write_text(BOM + text, encoding="utf-8")
    assert [(d.line, d.col) for d in check_file(path)] == [(3, 19)]
    path.write_text(BOM + text.replace(" +", ""), encoding="utf-8")
    assert check_file(path) == []


@pytest.mark.parametrize(
    ("text", "at"),
    [
        # A parser error after a renamed name with non-ASCII letters (columns in characters).
        ("layer Ü:\n    def fé(x y):\n        return 1\n", "y"),
        ("layer A:\n    def fé(x) -> str: return 'é' + x y\n", "y"),
        # Errors only Python's compiler finds count bytes: still the character column.
        ("layer A:\n    def f():\n        x = 'éé'; nonlocal q\n", "nonlocal"),
        ("layer Ü:\n    def fé(): x = 'éé'; yield 1; await y\n", "await"),
        ("layer Ü:\n    on activate: x = 'éé'; await y\n", "await"),
        ("x = 'éé'; return 1\nlayer A:\n    def f():\n        return 1\n", "return"),
        # AST positions (bytes) of proceed calls.
        ("class C: ...\nlayer Ü:\n    def C.fé(self): s = 'éé'; return proceed()\n", "proceed"),
    ],
)
def test_columns_count_characters_on_lines_with_non_ascii_text(text: str, at: str) -> None:
    (found,) = diagnostics(text)
    line = text.splitlines()[found[1] - 1]
    assert found[2] == line.rindex(at) + 1, (found, line)


TWO_LAYERS = "layer A:\n    def f(): ...\nlayer B{relation}:\n    def g(): ...\n"


def test_a_binding_naming_an_undeclared_layer() -> None:
    found = diagnostics(
        TWO_LAYERS.format(relation="")
        + "parameter Typo: /base max_speed = 0.1\nlifecycle Typo: a active, b inactive\n"
    )
    assert found == [
        (
            "warning",
            5,
            11,
            "parameter of layer 'Typo', which this file does not declare: the Layer manager "
            "given this file knows it as a layer of its own that only binds ROS nodes",
        ),
        (
            "warning",
            6,
            11,
            "lifecycle of layer 'Typo', which this file does not declare: the Layer manager "
            "given this file knows it as a layer of its own that only binds ROS nodes",
        ),
    ]


BINDINGS = (
    "parameter A: /base max_speed = 0.3\nparameter B: /base max_speed = 1.0\n"
    "lifecycle A: drv active\nlifecycle B: drv inactive\n"
)


def test_unordered_layers_binding_one_thing_to_different_values() -> None:
    found = diagnostics(TWO_LAYERS.format(relation="") + BINDINGS)
    assert found == [
        (
            "warning",
            6,
            14,
            "parameter /base max_speed is bound to 0.3 by layer 'A' (line 5) and to 1.0 by "
            "layer 'B', which may be active together with no declared order, so it depends on "
            "which was activated last; declare 'layer B after A' (or the reverse), or make "
            "them exclusive ('excludes', 'group')",
        ),
        (
            "warning",
            8,
            14,
            "lifecycle node drv is bound to active by layer 'A' (line 7) and to inactive by "
            "layer 'B', which may be active together with no declared order, so it depends on "
            "which was activated last; declare 'layer B after A' (or the reverse), or make "
            "them exclusive ('excludes', 'group')",
        ),
    ]


@pytest.mark.parametrize("relation", [" after A", " excludes A"])
def test_ordered_or_exclusive_layers_may_bind_one_thing_differently(relation: str) -> None:
    assert diagnostics(TWO_LAYERS.format(relation=relation) + BINDINGS) == []


def test_equal_values_and_other_parameters_are_no_conflict() -> None:
    assert (
        diagnostics(
            TWO_LAYERS.format(relation="")
            + "parameter A: /base max_speed = 0.3\nparameter B: /base max_speed = 0.3\n"
            "parameter B: /base min_speed = 1\nparameter A: /arm max_speed = 1\n"
            "lifecycle A: drv active\nlifecycle B: drv active, other inactive\n"
        )
        == []
    )


def test_one_layer_binding_one_parameter_twice() -> None:
    assert only(
        TWO_LAYERS.format(relation="")
        + "parameter A: /base mode = 'fast'\nparameter A: /base mode = 'slow'\n"
    ) == (
        "warning",
        6,
        14,
        "parameter /base mode is already bound to 'fast' by layer 'A' at line 5: the later "
        "line wins",
    )


def test_binding_checks_in_the_cpp_flavour() -> None:
    source = "Layer A [\nint f() { return 1; }\n]\nLayer B [\nint g() { return 1; }\n]\n" + BINDINGS
    found = [(d.line, d.col, d.message[:40]) for d in check_source(source, "t.cpp.layers")]
    assert found == [
        (8, 14, "parameter /base max_speed is bound to 0."),
        (10, 14, "lifecycle node drv is bound to active by"),
    ]
    assert "declare 'Layer B after A'" in check_source(source, "t.cpp.layers")[0].message


def test_a_misspelt_message_type_of_an_installed_package_is_an_error() -> None:
    """What `contextros check` and the manager run (the installed interfaces' lookup raises
    NoSuchMessageType for a type its package lacks): an error at the type, not a note."""
    from contextros.rules.ruleset import FieldLookup, NoSuchMessageType

    def installed(name: str) -> FieldLookup:
        package, _, message = name.split("/")
        if package != "sensor_msgs":
            raise ValueError(f"message package {package!r} is not installed here")
        raise NoSuchMessageType(f"sensor_msgs.msg has no message type {message!r}")

    source = (
        "topic battery: sensor_msgs/msg/BateryState\n"
        "rule Low: Night while battery.percentage < 20\n"
    )
    found = check_source(source, "t.layers", message_types=installed)
    assert [(d.severity.value, d.line, d.col) for d in found] == [("error", 1, 16)]
    assert found[0].message == (
        "the declared type of topic 'battery' does not exist: sensor_msgs.msg has no message "
        "type 'BateryState'"
    )
    # A package not installed where `check` runs (a laptop): its fields wait for run time.
    laptop = check_source(source.replace("sensor_msgs", "robot_msgs"), "t.layers", None, installed)
    assert [(d.severity.value, d.line) for d in laptop] == [("note", 2)]


def test_check_files_finds_what_check_finds_in_each_file_and_what_only_the_files_together_have(
    tmp_path: Path,
) -> None:
    """What the manager runs on its --layers files: each file's diagnostics as `contextros
    check` gives them (a layer error outside the rules too), then the errors of the files
    together (a rule name declared in two), file by file in the order given."""
    first = tmp_path / "z_first.layers"
    first.write_text(
        "layer A requires Nope:\n    def f(): ...\nrule Low: A while battery.percentage < 20\n",
        encoding="utf-8",
    )
    second = tmp_path / "a_second.layers"
    second.write_text(
        "rule B: Night wile x.y > 1\nrule Low: Night while x.y < 1\n", encoding="utf-8"
    )
    found = check_files([first, second])
    assert found[: len(check_file(first))] == check_file(first)
    assert [(Path(d.path).name, d.line, d.severity.value) for d in found if d.is_error] == [
        ("z_first.layers", 1, "error"),
        ("a_second.layers", 1, "error"),
        ("a_second.layers", 2, "error"),
    ]
    assert "unknown layer 'Nope'" in found[0].message
    assert f"rule 'Low' is already declared at {first.name}:3" in found[-1].message
    assert check_files([second]) == check_file(second), "alone, the same as `check`"
