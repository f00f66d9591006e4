"""The pre-compiler: golden modules, the paper's naming scheme, positions in tracebacks."""

from __future__ import annotations

import ast
import os
import traceback
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

import pytest

from contextros import activate, deactivate
from contextros.core import layered_function_of
from contextros.errors import NoImplementationError
from contextros.language import LayerSyntaxError, LayerTargetError, compile_file, compile_source
from tests.language.conftest import FIXTURES, GOLDEN

# The paper's listing has no relation between its layers: the checker says so, rightly.
pytestmark = pytest.mark.filterwarnings("ignore::contextros.language.LayerInteractionWarning")

# CONTEXTROS_UPDATE_GOLDEN=1 rewrites the golden files from the current compiler.
UPDATE = os.environ.get("CONTEXTROS_UPDATE_GOLDEN") == "1"


@pytest.mark.parametrize("name", ["paper_listing1", "cleaner"])
def test_generated_module_matches_the_golden_file(name: str) -> None:
    source = (FIXTURES / f"{name}.layers").read_text()
    text = compile_source(source, f"{name}.layers").text
    golden = GOLDEN / f"{name}.py.golden"  # not .py: linters must not touch it
    if UPDATE:
        golden.write_text(text)
    assert text == golden.read_text()


def test_output_is_deterministic() -> None:
    source = (FIXTURES / "cleaner.layers").read_text()
    assert compile_source(source, "x.layers").text == compile_source(source, "x.layers").text


def test_paper_naming_scheme_and_static_dispatch() -> None:
    """Listing 2: getPos_Indoor, getPos_Outdoor, and a dispatcher under the original name."""
    text = compile_file(FIXTURES / "paper_listing1.layers").text
    tree = ast.parse(text)
    functions = [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    assert functions == ["getPos", "getPos_Indoor", "getPos_Outdoor"]
    # The dispatch function does no look-up by name: its body is only a docstring.
    (dispatch,) = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "getPos"]
    assert len(dispatch.body) == 1 and isinstance(dispatch.body[0], ast.Expr)
    for banned in ("getattr", "globals()", "__dict__", "inspect"):
        assert banned not in text


def test_the_written_module_runs_like_the_layer_file(tmp_path: Path) -> None:
    compiled = compile_file(FIXTURES / "paper_listing1.layers")
    module = ModuleType("paper_listing1_written")
    exec(compile(compiled.text, str(tmp_path / "out.py"), "exec"), module.__dict__)
    with pytest.raises(NoImplementationError):
        module.getPos()
    activate(module.Indoor)
    assert module.getPos() == (1.0, 2.0)
    activate("Outdoor")
    assert module.getPos() == (35.68, 139.69)
    deactivate("Outdoor")
    assert module.getPos() == (1.0, 2.0)


def test_dispatch_function_takes_the_code_of_the_active_layer(
    load_fixture: Callable[[str], ModuleType],
) -> None:
    module = load_fixture("paper_listing1.layers")
    activate("Indoor")
    # Same module, same globals: the stable function runs getPos_Indoor's own code (a
    # copy of it, so that the frame tells `proceed` from a helper which link it is in).
    assert module.getPos.__code__ == module.getPos_Indoor.__code__
    assert not module.getPos.__code__.co_filename.startswith("<contextros dispatch")
    assert layered_function_of(module.getPos) is not None


def test_tracebacks_point_at_the_layer_file(load_fixture: Callable[[str], ModuleType]) -> None:
    module = load_fixture("cleaner.layers")
    activate("Indoor")
    activate("Docked")
    with pytest.raises(RuntimeError) as caught:
        module.Cleaner().clean("kitchen")
    frame = traceback.extract_tb(caught.value.__traceback__)[-1]
    assert Path(frame.filename).name == "cleaner.layers"
    assert frame.lineno == 52
    assert frame.line == 'raise RuntimeError(f"docked, cannot clean {area}")'
    assert (frame.colno, frame.end_colno) == (8, 58)  # 3.11+: the exact columns


def test_syntax_errors_in_a_body_are_raised_with_the_layer_file_position() -> None:
    with pytest.raises(LayerSyntaxError) as caught:
        compile_source("layer A:\n    def f():\n        return 1 +\n", "bad.layers")
    assert (caught.value.path, caught.value.line, caught.value.col) == ("bad.layers", 3, 19)


def test_warnings_travel_with_the_compiled_module() -> None:
    compiled = compile_file(FIXTURES / "paper_listing1.layers")
    assert [(w.line, w.col) for w in compiled.warnings] == [(18, 9)]


def test_a_class_method_refines_the_existing_method_as_its_base(
    load_fixture: Callable[[str], ModuleType],
) -> None:
    module = load_fixture("cleaner.layers")
    robot = module.Cleaner()
    assert robot.clean("hall") == "vacuum hall"
    activate("Indoor")
    assert robot.clean("hall") == "wipe+vacuum hall"
    activate("Night")
    assert robot.clean("hall") == "quietly wipe+vacuum hall"


def test_a_non_function_attribute_is_never_overwritten(tmp_path: Path) -> None:
    from contextros.language import load

    path = tmp_path / "prop.layers"
    path.write_text(
        "class Robot:\n    clean = 'not a method'\n\nlayer A:\n    def Robot.clean(self): ...\n"
    )
    with pytest.raises(LayerTargetError) as caught:
        load(path, name="prop_layers")
    assert (caught.value.line, caught.value.col) == (5, 9)
    assert "'str', not a plain function" in caught.value.message
    assert caught.value.source_line.strip() == "def Robot.clean(self): ..."


def test_a_method_inherited_from_object_is_the_base_through_super(tmp_path: Path) -> None:
    from contextros.language import check_file, load

    path = tmp_path / "dunder.layers"
    path.write_text(
        "class Robot:\n    pass\n\nclass Vacuum(Robot):\n    pass\n\n"
        "layer A:\n    def Robot.__init__(self, speed=1):\n        proceed(self)\n"
        "        self.speed = speed * 10\n\n"
        "    def Robot.__repr__(self):\n        return 'A:' + proceed(self)[:1]\n"
    )
    assert check_file(path) == []
    module = load(path, name="dunder_layers")
    assert not hasattr(module.Vacuum(), "speed")
    assert repr(module.Robot()).startswith("<dunder_layers.Robot object")
    activate("A")
    assert (module.Robot(2).speed, module.Vacuum().speed) == (20, 10)
    assert repr(module.Vacuum()) == "A:<"
    with pytest.raises(TypeError):
        module.Robot(1, 2)
    deactivate("A")
    assert not hasattr(module.Robot(), "speed")


def test_a_class_without_the_method_gets_one_without_base(tmp_path: Path) -> None:
    from contextros.language import load

    path = tmp_path / "new_method.layers"
    path.write_text(
        "class Robot:\n    pass\n\nlayer A:\n    def Robot.beep(self, times=1):\n"
        "        return 'beep' * times\n"
    )
    module = load(path, name="new_method_layers")
    with pytest.raises(NoImplementationError):
        module.Robot().beep()
    activate("A")
    assert module.Robot().beep(2) == "beepbeep"


def test_a_base_block_replaces_the_class_method_explicitly(tmp_path: Path) -> None:
    from contextros.language import load

    path = tmp_path / "rebased.layers"
    path.write_text(
        "class Robot:\n    def beep(self): return 'old'\n\nbase:\n    def Robot.beep(self):\n"
        "        return 'base'\n\nlayer A:\n    def Robot.beep(self):\n"
        "        return 'A+' + proceed(self)\n"
    )
    module = load(path, name="rebased_layers")
    assert module.Robot().beep() == "base"
    activate("A")
    assert module.Robot().beep() == "A+base"
    assert module.Robot.beep is module.Robot_beep


def test_an_already_layered_method_is_refined_further(tmp_path: Path) -> None:
    from contextros.language import load

    path = tmp_path / "again.layers"
    path.write_text(
        "from contextros import layered\n\n"
        "class Robot:\n    @layered\n    def beep(self):\n        return 'base'\n\n"
        "layer A:\n    def Robot.beep(self):\n        return 'A+' + proceed(self)\n"
    )
    module = load(path, name="again_layers")
    activate("A")
    assert module.Robot().beep() == "A+base"

    path.write_text(
        "from contextros import layered\n\nclass Robot:\n    @layered\n    def beep(self): ...\n\n"
        "base:\n    def Robot.beep(self):\n        return 'mine'\n\n"
        "layer A:\n    def Robot.beep(self):\n        return 'A'\n"
    )
    with pytest.raises(LayerTargetError) as caught:
        load(path, name="again_layers_2")
    assert "already layered" in caught.value.message


def test_scoped_activation_works_on_compiled_dispatch(
    load_fixture: Callable[[str], ModuleType],
) -> None:
    from contextros import activated

    module = load_fixture("paper_listing1.layers")
    with activated("Outdoor"):
        assert module.getPos() == (35.68, 139.69)
        with activated("Indoor"):
            assert module.getPos() == (1.0, 2.0)
    with pytest.raises(NoImplementationError):
        module.getPos()
