"""The C++ flavour: golden output that is also compiled and run, Listing 1 verbatim,
`#line` positions in compiler diagnostics, and output independent of the working directory."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from contextros.cli import main
from contextros.language.cpp.generator import compile_cpp
from contextros.language.cpp.parser import parse_with_diagnostics
from tests.language.conftest import GOLDEN

ROOT = Path(__file__).resolve().parents[2]
CPP_FIXTURES = Path(__file__).parent / "fixtures" / "cpp"
RUNTIME = ROOT / "cpp" / "core"
UPDATE = os.environ.get("CONTEXTROS_UPDATE_GOLDEN") == "1"
WARNINGS = ["-Wall", "-Wextra", "-Wpedantic"]


def compiler() -> str:
    found = shutil.which(os.environ.get("CXX", "g++"))
    assert found, "a C++ compiler (g++ or $CXX) is needed for the C++ flavour's tests"
    return found


def generate(name: str, out: Path) -> tuple[Path, Path]:
    """`contextros compile` of fixtures/cpp/<name>.cpp.layers into `out`."""
    source = out / f"{name}.layers.cpp"
    assert main(["compile", str(CPP_FIXTURES / f"{name}.cpp.layers"), "-o", str(source)]) == 0
    return source, out / f"{name}.layers.hpp"


def runtime_objects() -> list[Path]:
    """The C++ runtime (cpp/core/src) compiled once per content of its sources and headers
    and these flags, kept under build/: each test links it instead of compiling it again
    (6 s of g++ each time). A lock makes parallel test workers wait for one compile."""
    import fcntl
    import hashlib

    sources = sorted((RUNTIME / "src").glob("*.cpp"))
    inputs = sorted(RUNTIME.glob("include/**/*.hpp")) + sorted((RUNTIME / "src").glob("*"))
    digest = hashlib.sha256(" ".join([compiler(), *WARNINGS]).encode())
    for path in inputs:
        digest.update(path.read_bytes())
    cache = ROOT / "build" / "test-runtime" / digest.hexdigest()[:16]
    cache.mkdir(parents=True, exist_ok=True)
    objects = [cache / f"{source.stem}.o" for source in sources]
    with open(cache / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        for source, target in zip(sources, objects, strict=True):
            if target.exists():
                continue
            partial = target.with_suffix(".tmp.o")
            build = cxx("-std=c++17", "-Werror", "-pthread", "-c", source, "-o", partial, cwd=cache)
            assert build.returncode == 0, build.stderr
            partial.replace(target)
    return objects


def cxx(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    command = [compiler(), *WARNINGS, f"-I{RUNTIME / 'include'}", f"-I{CPP_FIXTURES}", "-I."]
    return subprocess.run(
        [*command, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300
    )


@pytest.mark.parametrize("name", ["paper_listing1", "robot", "guards"])
def test_generated_code_matches_the_golden_files(name: str) -> None:
    source = (CPP_FIXTURES / f"{name}.cpp.layers").read_text()
    compiled = compile_cpp(source, f"{name}.cpp.layers", output=f"{name}.layers.cpp")
    assert compiled.header is not None
    for suffix, text in (("cpp", compiled.source), ("hpp", compiled.header)):
        golden = GOLDEN / f"{name}.layers.{suffix}.golden"
        if UPDATE:
            golden.write_text(text)
        assert text == golden.read_text()


def test_output_does_not_depend_on_the_working_directory(tmp_path: Path) -> None:
    layers = tmp_path / "src" / "robot.cpp.layers"
    layers.parent.mkdir()
    shutil.copy(CPP_FIXTURES / "robot.cpp.layers", layers)
    outputs = []
    for cwd in (tmp_path, layers.parent, ROOT):
        out = tmp_path / "build" / cwd.name
        out.mkdir(parents=True)
        previous = Path.cwd()
        os.chdir(cwd)
        try:
            relative = os.path.relpath(layers)
            assert main(["compile", relative, "-o", str(out / "robot.layers.cpp")]) == 0
        finally:
            os.chdir(previous)
        outputs.append(
            ((out / "robot.layers.cpp").read_text(), (out / "robot.layers.hpp").read_text())
        )
    assert outputs[0] == outputs[1] == outputs[2]
    assert '#line 1 "../../src/robot.cpp.layers"' in outputs[0][1]
    assert str(tmp_path) not in outputs[0][0] + outputs[0][1]


def test_listing_1_compiles_verbatim_and_warnings_point_into_the_layer_file(
    tmp_path: Path,
) -> None:
    """The paper's Listing 1, with a real `location` type; its methods return nothing, and
    the compiler says so at the layer file's own line and column."""
    source, _ = generate("paper_listing1", tmp_path)
    for standard in ("c++17", "c++20"):
        result = cxx(f"-std={standard}", "-c", source.name, "-o", "listing1.o", cwd=tmp_path)
        assert result.returncode == 0, result.stderr
        lines = [line for line in result.stderr.splitlines() if "warning:" in line]
        assert lines == [
            f"{CPP_FIXTURES / 'paper_listing1.cpp.layers'}"  # named absolutely, as given
            f":{line}:{col}: warning: no return statement in function returning non-void "
            "[-Wreturn-type]"
            for line, col in ((5, 38), (8, 39))
        ]


def test_generated_code_runs_with_the_runtime(tmp_path: Path) -> None:
    """robot.cpp.layers uses every construct: a group, excludes/requires/after, a base block,
    free functions and methods (with and without a base), proceed, scoped activation."""
    source, _ = generate("robot", tmp_path)
    build = cxx(
        "-std=c++17",
        "-Werror",
        "-pthread",
        source.name,
        CPP_FIXTURES / "robot_main.cpp",
        *runtime_objects(),
        "-o",
        "robot",
        cwd=tmp_path,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([tmp_path / "robot"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == [
        "Docked group= excludes=2 required=1 after=1",
        "Indoor group=place excludes=0 required=0 after=0",
        "Night group= excludes=0 required=0 after=2",
        "Outdoor group=place excludes=0 required=0 after=0",
        "none: speed=1 speed(2)=2 pos=none clean=vacuum hall",
        "Indoor: speed=0.5 speed(2)=1 pos=1,2 clean=wipe+vacuum hall",
        "Indoor+Night: speed=0.125 speed(2)=0.25 pos=1,2 clean=quietly wipe+vacuum hall by r1",
        "Night+Outdoor: speed=2 speed(2)=4 pos=35.68,139.69 clean=quietly vacuum hall by r1",
        "Docked with Night: layers Docked and Night cannot be active together "
        "(Docked excludes Night)",
        "Indoor+Docked: speed=0.5 speed(2)=1 pos=1,2 clean!docked, cannot clean hall",
        "scoped Outdoor: speed=2 speed(2)=4 pos=35.68,139.69 clean=vacuum hall",
        "after scope: speed=1 speed(2)=2 pos=none clean=vacuum hall",
    ]


def test_generated_code_compiles_as_cpp20(tmp_path: Path) -> None:
    source, _ = generate("robot", tmp_path)
    result = cxx("-std=c++20", "-Werror", "-c", source.name, "-o", "robot.o", cwd=tmp_path)
    assert result.returncode == 0, result.stderr


def test_a_compiler_error_in_a_layer_points_at_the_layer_file(tmp_path: Path) -> None:
    layers = tmp_path / "broken.cpp.layers"
    layers.write_text(
        "#include <string>\n"
        "Layer Indoor [\n"
        "int count(int n) {\n"
        "  std::string s = n;  // not convertible\n"
        "  return proceed(n) + 1;\n"
        "}\n"
        "]\n"
    )
    assert main(["compile", str(layers), "-o", str(tmp_path / "broken.layers.cpp")]) == 0
    result = cxx("-std=c++17", "-c", "broken.layers.cpp", "-o", "broken.o", cwd=tmp_path)
    assert result.returncode != 0
    assert "broken.cpp.layers:4:19: error: conversion from 'int'" in result.stderr.replace(
        "\u2018", "'"
    ).replace("\u2019", "'"), result.stderr


CLASSES = """\
#include <string>
#include "elsewhere.hpp"

class Greeter {
  std::string name_ = "Ken";  // private: the layers' methods are members
 public:
  std::string hello() const;
};

Layer Tokyo [
std::string Greeter::hello() const { return "konnichiwa " + name_; }
std::string Greeter::bye() { return "sayonara " + name_; }  // declared by the compiler
int Counter::next() { return ++count_ * 10; }
]
"""

ELSEWHERE = """\
#pragma once
#include <contextros/layered.hpp>

class Counter {
  CONTEXTROS_LAYERED_CLASS;  // a class defined outside the layer file opts in
  int count_ = 0;

 public:
  int next();
};
"""

CLASSES_MAIN = """\
#include <iostream>
#include "classes.layers.hpp"

int main() {
  Greeter greeter;
  Counter counter;
  contextros::activate("Tokyo");
  std::cout << greeter.hello() << "/" << greeter.bye() << "/" << counter.next() << "/"
            << counter.next() << "\\n";
  contextros::deactivate("Tokyo");
  try {
    greeter.hello();
  } catch (const contextros::NoImplementationError& error) {
    std::cout << error.what() << "\\n";
  }
}
"""


def test_methods_of_header_classes_and_of_classes_declared_elsewhere(tmp_path: Path) -> None:
    (tmp_path / "classes.cpp.layers").write_text(CLASSES)
    (tmp_path / "elsewhere.hpp").write_text(ELSEWHERE)
    (tmp_path / "main.cpp").write_text(CLASSES_MAIN)
    layers = str(tmp_path / "classes.cpp.layers")
    assert main(["compile", layers, "-o", str(tmp_path / "classes.layers.cpp")]) == 0
    build = cxx(
        "-std=c++17",
        "-Werror",
        "-pthread",
        "classes.layers.cpp",
        "main.cpp",
        *runtime_objects(),
        "-o",
        "classes",
        cwd=tmp_path,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([tmp_path / "classes"], capture_output=True, text=True, timeout=60)
    assert run.stdout.splitlines() == [
        "konnichiwa Ken/sayonara Ken/10/20",
        "Greeter::hello has no base implementation and no active layer refines it "
        "(active layers: none)",
    ], run.stderr


def test_check_accepts_cpp_layer_files(capsys: pytest.CaptureFixture[str]) -> None:
    """`contextros check DIR` reads both flavours; a C++ file's warning is located as usual."""
    assert main(["check", str(CPP_FIXTURES)]) == 0
    out = capsys.readouterr().out
    listing = CPP_FIXTURES / "paper_listing1.cpp.layers"
    assert f"{listing}:8:10: warning: getPos is refined by layers 'Indoor' (line 5)" in out
    assert "robot.cpp.layers" not in out  # no findings there


def test_language_option_overrides_the_file_name(tmp_path: Path) -> None:
    layers = tmp_path / "listing.layers"  # a Python name, C++ content
    shutil.copy(CPP_FIXTURES / "paper_listing1.cpp.layers", layers)
    assert main(["check", str(layers)]) == 1  # read as Python: errors
    assert main(["check", "--language", "cpp", str(layers)]) == 0
    out = tmp_path / "listing.layers.cpp"
    assert main(["compile", "--language", "cpp", str(layers), "-o", str(out)]) == 0
    assert (tmp_path / "listing.layers.hpp").exists()
    assert "location getPos_Indoor" in out.read_text()


FORMS = """\
#include <string>
#include <vector>

class Robot {
 public:
  const std::string& label() const;
  std::vector<int> path(int n, const std::vector<int>& seed = {}) noexcept;
 private:
  std::string label_ = "r";
};

auto twice(int x) -> int;

namespace nav {
struct Map {
  int size() const;
};
}  // namespace nav

base [
auto twice(int x) -> int { return 2 * x; }
const std::string& Robot::label() const { return label_; }
]

Layer Fast [
auto twice(int x) -> int { return proceed(x) + 1; }
std::vector<int> Robot::path(int n, const std::vector<int>& seed) noexcept {
  std::vector<int> out(seed);
  for (int i = 0; i < n; ++i) out.push_back(i);
  return out;
}
[[nodiscard]] int extra(int a) { return a + 1; }
int nav::Map::size() const { return 5; }
]

Layer Slow after Fast [
std::vector<int> Robot::path(int n, const std::vector<int>& seed) noexcept {
  auto out = proceed(n, seed);
  out.push_back(-1);
  return out;
}
int extra(int a) { return proceed(a) * 10; }
]
"""

FORMS_MAIN = """\
#include <iostream>
#include "var.layers.hpp"
int main() {
  Robot r;
  contextros::set_active({"Fast", "Slow"});
  std::cout << twice(3) << " " << r.label() << " " << r.path(2).size() << " " << extra(1)
            << " " << nav::Map{}.size() << "\\n";
}
"""


def test_trailing_returns_references_noexcept_attributes_and_braced_defaults(
    tmp_path: Path,
) -> None:
    """Forms of real code: `auto f() -> int`, a method returning a reference, a `noexcept`
    method with a `= {}` default in its class, an attribute on one implementation only, a
    class in a namespace."""
    (tmp_path / "forms.cpp.layers").write_text(FORMS)
    (tmp_path / "main.cpp").write_text(FORMS_MAIN.replace("var.layers.hpp", "forms.layers.hpp"))
    layers = str(tmp_path / "forms.cpp.layers")
    assert main(["compile", layers, "-o", str(tmp_path / "forms.layers.cpp")]) == 0
    build = cxx(
        "-std=c++17",
        "-Werror",
        "-pthread",
        "forms.layers.cpp",
        "main.cpp",
        *runtime_objects(),
        "-o",
        "forms",
        cwd=tmp_path,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([tmp_path / "forms"], capture_output=True, text=True, timeout=60)
    assert run.stdout == "7 r 3 20 5\n", run.stderr


PREFIXED_NAMES = """\
class Robot {
 public:
  int pos_ = 3;
};

Layer Indoor [
int Robot::getPos() { return pos_; }
int Robot::get() { return pos_ * 2; }  // a prefix of getPos: declared too
]
"""


def test_a_method_named_like_a_prefix_of_another_is_declared(tmp_path: Path) -> None:
    (tmp_path / "prefixed.cpp.layers").write_text(PREFIXED_NAMES)
    layers = str(tmp_path / "prefixed.cpp.layers")
    assert main(["compile", layers, "-o", str(tmp_path / "prefixed.layers.cpp")]) == 0
    header = (tmp_path / "prefixed.layers.hpp").read_text()
    assert "int get()" in header and "int getPos()" in header
    build = cxx("-std=c++17", "-Werror", "-c", "prefixed.layers.cpp", "-o", "p.o", cwd=tmp_path)
    assert build.returncode == 0, build.stderr


EDGES = """#include <string>
struct R {
  int n = 3;
  int g(int x) const noexcept;
  auto h(int x) -> int;
};
base [
int R::g(int x) const noexcept { return x; }
auto R::h(int x) -> int { return x; }
]
Layer A [
"two " "parts"  // a description in pieces, as C++ joins them
int R::g(int x) const noexcept when (x > n) { return proceed(x) * 10; }
auto R::h(int x) -> int when (x < 0) { return -proceed(-x); }
on activate {}
]
"""


def test_guards_after_qualifiers_and_trailing_return_types_compile(tmp_path: Path) -> None:
    """`when` after `const noexcept` and after `-> int`; a description of two literals."""
    parsed, diagnostics = parse_with_diagnostics(EDGES, "edges.cpp.layers")
    assert [d.render() for d in diagnostics if d.is_error] == []
    (layer,) = parsed.layers
    assert layer.description == "two parts"
    assert [(f.key, f.guard.text if f.guard else None) for f in layer.functions] == [
        ("R::g", "x > n"),
        ("R::h", "x < 0"),
    ]
    assert [hook.event for hook in layer.hooks] == ["activate"]
    (tmp_path / "edges.cpp.layers").write_text(EDGES)
    source = tmp_path / "edges.layers.cpp"
    assert main(["compile", str(tmp_path / "edges.cpp.layers"), "-o", str(source)]) == 0
    result = cxx("-std=c++17", "-Werror", "-fsyntax-only", source.name, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
