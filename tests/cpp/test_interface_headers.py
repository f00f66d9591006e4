"""The generated C++ headers of contextros_interfaces compile as C++17 and as C++20 (a field
named `requires`, a C++20 keyword, once made the C++20 build fail)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

PREFIX = Path(sys.prefix)  # the venv holding the wheels and the built interfaces
HEADERS = [
    "contextros_interfaces/msg/layer_info.hpp",
    "contextros_interfaces/msg/layer_state.hpp",
    "contextros_interfaces/msg/participant_status.hpp",
    "contextros_interfaces/msg/participant_info.hpp",
    "contextros_interfaces/srv/activate.hpp",
    "contextros_interfaces/srv/query_registry.hpp",
]


@pytest.mark.parametrize("standard", ["c++17", "c++20"])
def test_generated_headers_compile(standard: str, tmp_path: Path) -> None:
    compiler = shutil.which("g++") or shutil.which("c++")
    assert compiler, "a C++ compiler is needed (g++)"
    ours = PREFIX / "include" / "contextros_interfaces"
    assert (ours / HEADERS[0]).exists(), f"no generated headers in {ours}: run `make ros`"
    source = tmp_path / "all_headers.cpp"
    source.write_text(
        "".join(f"#include <{header}>\n" for header in HEADERS)
        + 'int main() { contextros_interfaces::msg::LayerInfo info; info.required = {"A"};'
        " return static_cast<int>(info.required.size()) - 1; }\n"
    )
    includes = [f"-I{d}" for d in sorted((PREFIX / "include").iterdir()) if d.is_dir()]
    run = subprocess.run(
        [compiler, f"-std={standard}", "-fsyntax-only", "-Wall", "-Wextra", *includes, str(source)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stderr
    assert run.stderr == "", run.stderr  # no warnings either
