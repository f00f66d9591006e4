"""The public surface (CMake functions, CLI commands and options, Python exports) changes
only on purpose: a removed name keeps a stub for one release that says what replaces it.

`public_surface.txt` lists every public name; a name that disappears from the code while
still listed fails here (issue 25: `contextros_use_ros_wheels()` was removed and a project
using it failed with `Unknown CMake command` and no word of what replaced it). A stub is
listed with `stub:` and when it goes; it must say what replaces it. A new name must be
added to the list (so that removing it later is a decision too).
"""

from __future__ import annotations

import argparse
import importlib
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from contextros.cli import build_parser, subcommands

ROOT = Path(__file__).resolve().parents[2]
LISTED = Path(__file__).with_name("public_surface.txt")
CMAKE_FILES = sorted((ROOT / "cpp" / "cmake").glob("*.cmake*"))
PYTHON_PACKAGES = (
    "contextros",
    "contextros.core",
    "contextros.ros",
    "contextros.language",
    "contextros.rules",
    "contextros.recording",
)
DEFINITION = re.compile(r"^\s*(?:function|macro)\(\s*([A-Za-z]\w*)", re.MULTILINE)


def cmake_names() -> set[str]:
    return {
        f"cmake {name}"
        for path in CMAKE_FILES
        for name in DEFINITION.findall(path.read_text(encoding="utf-8"))
    }


def cli_names() -> set[str]:
    parser = build_parser()
    names = {f"option {option}" for option in _options(parser)}
    for command, subparser in subcommands(parser).items():
        names.add(f"command {command}")
        names |= {f"option {command} {option}" for option in _options(subparser)}
    return names


def _options(parser: argparse.ArgumentParser) -> list[str]:
    return [
        option
        for action in parser._actions
        if action.help != argparse.SUPPRESS and not isinstance(action, argparse._HelpAction)
        for option in action.option_strings
    ]


def python_names() -> set[str]:
    names = set()
    for package in PYTHON_PACKAGES:
        module = importlib.import_module(package)
        names |= {f"python {package}.{name}" for name in module.__all__}
    return names


def listed() -> dict[str, str]:
    """The committed list: name -> its note ('' or 'stub: ...')."""
    entries = {}
    for line in LISTED.read_text(encoding="utf-8").splitlines():
        line = line.split("#", 1)[0].rstrip()
        if line:
            name, _, note = line.partition("  ")
            entries[name.strip()] = note.strip()
    return entries


def test_no_listed_name_disappeared() -> None:
    pytest.importorskip("rclpy")
    current = cmake_names() | cli_names() | python_names()
    gone = sorted(set(listed()) - current)
    assert gone == [], (
        f"{gone} left the public surface without a word: keep a stub for one release that "
        "says what replaces it (list it with `stub:` in tests/cli/public_surface.txt)"
    )


def test_every_public_name_is_listed() -> None:
    pytest.importorskip("rclpy")
    current = cmake_names() | cli_names() | python_names()
    new = sorted(current - set(listed()))
    assert new == [], f"add the new public names {new} to tests/cli/public_surface.txt"


@pytest.mark.parametrize(
    "name", [n for n, note in listed().items() if note.startswith("stub:")] or ["(none)"]
)
def test_a_stub_says_what_replaces_it(name: str, tmp_path: Path) -> None:
    if name == "(none)":
        return
    kind, _, what = name.partition(" ")
    assert kind == "cmake", f"{name}: only CMake stubs are checked yet; add a check for {kind}"
    cmake = shutil.which("cmake")
    assert cmake is not None, "cmake is needed to build the C++ part"
    script = tmp_path / "use.cmake"
    (defining,) = [p for p in CMAKE_FILES if what in DEFINITION.findall(p.read_text())]
    script.write_text(f'include("{defining}")\n{what}(a_target)\n', encoding="utf-8")
    done = subprocess.run([cmake, "-P", str(script)], capture_output=True, text=True, timeout=60)
    said = " ".join((done.stdout + done.stderr).split())
    assert f"{what}() was removed" in said and "goes in" in said, said
    assert "contextros_ros_wheels_link_interface" in said or "contextros::" in said, said
