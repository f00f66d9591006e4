"""`implies` in both flavours (issue 28, item 1): parsed, compiled into the layer's
declaration, and its cycles and contradictions reported at file:line:col."""

from __future__ import annotations

import subprocess
import textwrap
from pathlib import Path

from contextros.core import Layer
from contextros.language import check_source, load
from contextros.language.compiler import compile_source
from contextros.language.cpp.generator import compile_cpp
from contextros.language.declarations import declarations_from_files

DRONE = """\
group mode: Flight, Landed
group camera: CameraHigh, CameraLow

layer Mission implies Flight:
    def plan() -> str:
        return "mission"

layer Flight implies Propulsion, CameraHigh after Propulsion:
    def speed() -> float:
        return 2.0

layer Landed implies CameraLow:
    def speed() -> float:
        return 0.0

layer Propulsion:
    def thrust() -> float:
        return 1.0

layer CameraHigh:
    def resolution() -> int:
        return 1080

layer CameraLow:
    def resolution() -> int:
        return 480
"""

DRONE_CPP = """\
#include <string>
group mode: Flight, Landed;
group camera: CameraHigh, CameraLow;
Layer Mission implies Flight [
std::string plan() { return "mission"; }
]
Layer Flight implies Propulsion, CameraHigh after Propulsion [
double speed() { return 2.0; }
]
Layer Landed implies CameraLow [
double speed() { return 0.0; }
]
Layer Propulsion [
double thrust() { return 1.0; }
]
Layer CameraHigh [
int resolution() { return 1080; }
]
Layer CameraLow [
int resolution() { return 480; }
]
"""


def found(text: str, name: str = "t.layers") -> list[tuple[str, int, int, str]]:
    return [
        (d.severity.value, d.line, d.col, d.message)
        for d in check_source(textwrap.dedent(text), name)
    ]


def test_a_hierarchy_checks_clean_in_both_flavours() -> None:
    assert found(DRONE) == []
    assert found(DRONE_CPP, "t.cpp.layers") == []


def test_the_compiled_layers_carry_what_they_imply(tmp_path: Path) -> None:
    path = tmp_path / "drone_implies.layers"
    path.write_text(DRONE)
    module = load(path, name="drone_implies")
    flight: Layer = module.Flight
    assert flight.implies == frozenset({"Propulsion", "CameraHigh"})
    assert flight.after == frozenset({"Propulsion"})
    assert module.Mission.implies == frozenset({"Flight"})
    assert 'implies=("Propulsion", "CameraHigh")' in compile_source(DRONE, "drone.layers").text


def test_the_manager_reads_implies_from_layer_files_of_both_flavours(tmp_path: Path) -> None:
    (tmp_path / "a.layers").write_text(DRONE)
    (tmp_path / "b.cpp.layers").write_text(DRONE_CPP.replace("Mission", "Survey"))
    declared = declarations_from_files([tmp_path / "a.layers", tmp_path / "b.cpp.layers"])
    implies = {d.name: d.implies for d in declared if d.implies}
    assert implies["Mission"] == {"Flight"} and implies["Survey"] == {"Flight"}
    assert implies["Flight"] == {"Propulsion", "CameraHigh"}


def test_the_cpp_flavour_defines_what_a_layer_implies() -> None:
    source = compile_cpp(DRONE_CPP, "drone.cpp.layers").source
    assert (
        'define_layer({"Flight", {}, {}, {"Propulsion"}, "mode", {"Propulsion", "CameraHigh"}})'
        in source
    )
    assert 'define_layer({"Propulsion", {}, {}, {}, ""})' in source, "nothing added without implies"


def test_implying_two_layers_of_one_group_is_an_error_at_the_second() -> None:
    text = DRONE.replace(
        "layer Landed implies CameraLow:", "layer Landed implies CameraLow, CameraHigh:"
    )
    assert found(text) == [
        (
            "error",
            12,
            33,
            "layer 'Landed' implies 'CameraHigh' and 'CameraLow', both in group 'camera', of "
            "which at most one is active",
        )
    ]


def test_a_contradiction_deeper_down_is_said_once_of_the_innermost_layer() -> None:
    text = DRONE.replace(
        "layer Flight implies Propulsion, CameraHigh",
        "layer Flight implies Propulsion, CameraHigh, CameraLow",
    )
    assert found(text) == [
        (
            "error",
            8,
            46,
            "layer 'Flight' implies 'CameraHigh' and 'CameraLow', both in group 'camera', of "
            "which at most one is active",
        )
    ], "Mission, which implies Flight, is not reported again"


def test_implying_a_layer_it_excludes() -> None:
    text = """\
        layer Quiet implies Fans excludes Fans:
            def f(): ...
        layer Fans:
            def g(): ...
        layer Calm implies Fans:
            def h(): ...
        layer Noisy implies Calm excludes Fans:
            def i(): ...
        """
    assert found(text) == [
        ("error", 1, 21, "layer 'Quiet' both implies and excludes 'Fans'"),
        ("error", 7, 21, "layer 'Noisy' implies 'Fans', which it excludes"),
    ]


def test_implying_a_layer_that_excludes_another_it_implies() -> None:
    text = """\
        layer Loud implies Speaker, Mute:
            def f(): ...
        layer Speaker:
            def g(): ...
        layer Mute excludes Speaker:
            def h(): ...
        layer Door implies Mute:
            def i(): ...
        layer Bell excludes Door:
            def j(): ...
        layer Ring implies Bell, Door:
            def k(): ...
        """
    assert found(text) == [
        ("error", 1, 29, "layer 'Loud' implies 'Mute' and 'Speaker', which exclude each other"),
        ("error", 11, 26, "layer 'Ring' implies 'Bell' and 'Door', which exclude each other"),
    ]


def test_a_cycle_of_implies_is_an_error_in_both_flavours() -> None:
    text = """\
        layer A implies B:
            def f(): ...
        layer B implies C:
            def g(): ...
        layer C implies A:
            def h(): ...
        """
    assert found(text) == [
        ("error", 1, 17, "'implies' cycle: A -> B -> C -> A; a layer cannot imply itself")
    ]
    cpp = "Layer A implies B [\nint f() { return 1; }\n]\n"
    cpp += "Layer B implies A [\nint g() { return 1; }\n]\n"
    assert found(cpp, "t.cpp.layers") == [
        ("error", 1, 17, "'implies' cycle: A -> B -> A; a layer cannot imply itself")
    ]


def test_implies_names_a_declared_layer_and_not_itself() -> None:
    text = """\
        layer A implies A, Nope:
            def f(): ...
        """
    assert found(text) == [
        ("error", 1, 17, "layer 'A' names itself in 'implies'"),
        ("error", 1, 20, "unknown layer 'Nope' in 'implies' of layer 'A' (declared layers: A)"),
    ]


def test_a_misspelt_relation_lists_implies() -> None:
    (error,) = found("layer A implie B:\n    def f(): ...\n")
    assert error[3] == "expected 'excludes', 'requires', 'after', 'implies' or ':', found 'implie'"


def test_the_generated_cpp_defines_the_hierarchy_in_the_runtime(tmp_path: Path) -> None:
    """Compiled with -Wall -Wextra -Werror and run: `defined_layers()` (what the C++
    participant announces) carries what each layer implies."""
    from tests.language.test_cpp_compiler import cxx, runtime_objects

    compiled = compile_cpp(DRONE_CPP, "drone.cpp.layers", header=False)
    (tmp_path / "drone.layers.cpp").write_text(compiled.source)
    (tmp_path / "main.cpp").write_text(
        "#include <contextros/layer.hpp>\n#include <iostream>\n"
        "int main() {\n"
        "  for (const auto& layer : contextros::defined_layers()) {\n"
        "    std::cout << layer.name << ':';\n"
        "    for (const auto& implied : layer.implies) std::cout << ' ' << implied;\n"
        "    std::cout << '\\n';\n"
        "  }\n"
        "}\n"
    )
    build = cxx(
        "-std=c++17",
        "-Werror",
        "-pthread",
        "drone.layers.cpp",
        "main.cpp",
        *runtime_objects(),
        "-o",
        "drone",
        cwd=tmp_path,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([tmp_path / "drone"], capture_output=True, text=True, timeout=30)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == [
        "CameraHigh:",
        "CameraLow:",
        "Flight: Propulsion CameraHigh",
        "Landed: CameraLow",
        "Mission: Flight",
        "Propulsion:",
    ]
