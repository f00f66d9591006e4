"""Using layer files without a compile step: load(), the cache, the import hook."""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from contextros import activate
from contextros.language import (
    CompiledLayers,
    LayerInteractionWarning,
    LayerSyntaxError,
    install_import_hook,
    load,
    loader,
    uninstall_import_hook,
)
from contextros.language.loader import cache_path

TWO_LAYERS = """\
VERSION = {version}

group mode: Fast, Slow

layer Fast:
    def step(x):
        return x + {version}

layer Slow:
    def step(x):
        return x - 1
"""


@pytest.fixture
def compilations(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The paths the loader actually compiled (not taken from the cache)."""
    compiled: list[str] = []
    original = loader.compile_source

    def counting(source: str, path: str = "<layers>") -> CompiledLayers:
        compiled.append(path)
        return original(source, path)

    monkeypatch.setattr(loader, "compile_source", counting)
    return compiled


def test_load_returns_a_module_named_after_the_file(tmp_path: Path) -> None:
    path = tmp_path / "modes.layers"
    path.write_text(TWO_LAYERS.format(version=1))
    module = load(path)
    try:
        assert module.__name__ == "modes"
        assert sys.modules["modes"] is module
        assert module.__file__ == str(path)
        activate("Fast")
        assert module.step(1) == 2
        assert [layer.name for layer in module.__layers__] == ["Fast", "Slow"]
    finally:
        sys.modules.pop("modes", None)


def test_the_cache_is_reused_and_rebuilt_when_the_source_changes(
    tmp_path: Path, compilations: list[str]
) -> None:
    path = tmp_path / "cached.layers"
    path.write_text(TWO_LAYERS.format(version=1))
    load(path, name="cached_a")
    assert cache_path(path).is_file()
    assert len(compilations) == 1

    load(path, name="cached_b")
    assert len(compilations) == 1  # unchanged: from the cache

    os.utime(path, ns=(1, 1))  # touched, same content: the digest says it is current
    load(path, name="cached_c")
    assert len(compilations) == 1

    path.write_text(TWO_LAYERS.format(version=2))
    module = load(path, name="cached_d")
    assert len(compilations) == 2
    assert module.VERSION == 2
    activate("Fast")
    assert module.step(1) == 3


def test_a_corrupt_or_foreign_cache_is_rebuilt(tmp_path: Path, compilations: list[str]) -> None:
    path = tmp_path / "corrupt.layers"
    path.write_text(TWO_LAYERS.format(version=1))
    load(path, name="corrupt_a")
    cache_path(path).write_bytes(b"garbage")
    module = load(path, name="corrupt_b")
    assert len(compilations) == 2
    assert module.VERSION == 1


def test_a_read_only_cache_directory_only_costs_a_compilation(
    tmp_path: Path, compilations: list[str]
) -> None:
    path = tmp_path / "ro.layers"
    path.write_text(TWO_LAYERS.format(version=1))
    (tmp_path / "__pycache__").write_text("a file where the cache directory would go")
    load(path, name="ro_a")
    load(path, name="ro_b")
    assert len(compilations) == 2


def test_errors_are_raised_and_nothing_is_cached(tmp_path: Path) -> None:
    path = tmp_path / "broken.layers"
    path.write_text("layer A:\n    def f(:\n")
    with pytest.raises(LayerSyntaxError) as caught:
        load(path)
    assert (caught.value.line, caught.value.col) == (2, 11)
    assert "broken" not in sys.modules
    assert not cache_path(path).exists()


def test_checker_warnings_are_python_warnings_at_the_layer_line(tmp_path: Path) -> None:
    path = tmp_path / "warns.layers"
    path.write_text("layer A:\n    def f(): ...\nlayer B:\n    def f(): ...\n")
    with pytest.warns(LayerInteractionWarning) as recorded:
        load(path, name="warns_layers")
    (warning,) = recorded
    assert (Path(warning.filename).name, warning.lineno) == ("warns.layers", 4)


@pytest.fixture
def import_hook(tmp_path: Path) -> Iterator[Path]:
    install_import_hook()
    sys.path.insert(0, str(tmp_path))
    yield tmp_path
    sys.path.remove(str(tmp_path))
    uninstall_import_hook()


def test_the_import_hook_finds_layer_files_on_sys_path(import_hook: Path) -> None:
    (import_hook / "hooked_modes.layers").write_text(TWO_LAYERS.format(version=5))
    import hooked_modes  # type: ignore[import-not-found]

    try:
        activate("Fast")
        assert hooked_modes.step(1) == 6
        assert hooked_modes.__spec__.origin == str(import_hook / "hooked_modes.layers")
    finally:
        sys.modules.pop("hooked_modes", None)


def test_the_import_hook_finds_layer_files_in_packages(import_hook: Path) -> None:
    package = import_hook / "hooked_package"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "behaviour.layers").write_text(
        "layer Broken:\n    def explode():\n        return 1 / 0\n"
    )
    from hooked_package import behaviour  # type: ignore[import-not-found]

    try:
        activate("Broken")
        with pytest.raises(ZeroDivisionError) as caught:
            behaviour.explode()
        frame = traceback.extract_tb(caught.value.__traceback__)[-1]
        assert (Path(frame.filename).name, frame.lineno) == ("behaviour.layers", 3)
    finally:
        sys.modules.pop("hooked_package.behaviour", None)
        sys.modules.pop("hooked_package", None)


def test_install_import_hook_is_idempotent() -> None:
    first = install_import_hook()
    try:
        assert install_import_hook() is first
        assert sys.meta_path.count(first) == 1
    finally:
        uninstall_import_hook()
    assert first not in sys.meta_path


def test_load_fixture_helper_works_with_the_paper_listing(
    load_fixture: Callable[[str], object],
) -> None:
    with pytest.warns(LayerInteractionWarning):
        module = load_fixture("paper_listing1.layers")
    activate("Outdoor")
    assert module.getPos().x == 35.68  # type: ignore[attr-defined]


def test_loading_the_same_unchanged_file_again_returns_the_same_module(tmp_path: Path) -> None:
    path = tmp_path / "shared_modes.layers"
    path.write_text(TWO_LAYERS.format(version=1))
    try:
        first = load(path)
        assert load(path) is first  # like import: two users of one layer file share it
        assert load(path, reload=True) is not first
        path.write_text(TWO_LAYERS.format(version=7))
        changed = load(path)
        assert changed.VERSION == 7
        assert load(path, name="shared_modes_elsewhere") is not changed
    finally:
        sys.modules.pop("shared_modes", None)
        sys.modules.pop("shared_modes_elsewhere", None)
