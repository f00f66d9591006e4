"""contextros_add_layers() (cpp/cmake/ContextrosLayers.cmake) at configure time: a layer
file that is not there stops the configure with its name, rather than passing and failing
later in the build ("missing and no known rule to make it")."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

LAYERS_CMAKE = Path(__file__).resolve().parents[2] / "cpp" / "cmake" / "ContextrosLayers.cmake"


def configure(project: Path, layer_file: str) -> subprocess.CompletedProcess[str]:
    """A project adding `layer_file` to a target, configured (not built)."""
    cmake = shutil.which("cmake")
    assert cmake is not None, "cmake is needed to build the C++ part"
    (project / "robot.cpp.layers").write_text("Layer Indoor [\n]\n", encoding="utf-8")
    (project / "main.cpp").write_text("int main() {}\n", encoding="utf-8")
    (project / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.21)\n"
        "project(robot LANGUAGES CXX)\n"
        "add_library(contextros::core INTERFACE IMPORTED)\n"
        f'include("{LAYERS_CMAKE}")\n'
        "add_executable(robot_node main.cpp)\n"
        f"contextros_add_layers(robot_node {layer_file})\n",
        encoding="utf-8",
    )
    return subprocess.run(
        [cmake, "-S", str(project), "-B", str(project / "build"), "-DCONTEXTROS_COMPILER=true"],
        capture_output=True,
        text=True,
        timeout=120,
    )


@pytest.mark.parametrize("layer_file", ["robot.cpp.layer", "."])
def test_a_missing_layer_file_stops_the_configure_naming_it(
    layer_file: str, tmp_path: Path
) -> None:
    done = configure(tmp_path, layer_file)
    said = " ".join(done.stderr.split())
    assert done.returncode != 0, done.stdout
    assert f"contextros_add_layers(robot_node): no layer file {layer_file}" in said, said


def test_a_layer_file_beside_the_cmakelists_configures(tmp_path: Path) -> None:
    done = configure(tmp_path, "robot.cpp.layers")
    assert done.returncode == 0, done.stderr
    generated = tmp_path / "build" / "contextros_layers"
    assert generated.is_dir(), done.stdout
