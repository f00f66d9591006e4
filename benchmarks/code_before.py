"""The code before a change, run beside the current code (`CONTEXTROS_BEFORE=<a source tree>`).

The venv's editable install finds `contextros` through an import hook that comes before
`sys.path` (scikit-build-core's in-place finder), so a tree put on PYTHONPATH alone is not
used: until issue 16's second session, every "before" row of the side-by-side benchmarks
ran the current code. A before run's children start with `before_site/sitecustomize.py`,
which removes that hook, and each run checks which code its children import.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SITE = Path(__file__).resolve().parent / "before_site"


def before_environment(tree: Path) -> dict[str, str]:
    """The environment changes that make a child process run `tree`'s code."""
    tree = tree.resolve()
    paths = os.pathsep.join([str(SITE), str(tree / "src"), str(tree)])
    environment = {"PYTHONPATH": paths}
    imported = subprocess.run(
        [sys.executable, "-c", "import contextros; print(contextros.__file__)"],
        env=os.environ | environment,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    if not Path(imported).resolve().is_relative_to(tree):
        raise RuntimeError(
            f"CONTEXTROS_BEFORE={tree}: its children would import {imported}, not the tree's "
            "code; see benchmarks/code_before.py"
        )
    return environment


def trees_to_compare() -> dict[str, Path | None]:
    """The code to measure: "after" (this tree, None) and, with `CONTEXTROS_BEFORE` set,
    "before" (that tree), side by side."""
    trees: dict[str, Path | None] = {"after": None}
    if before := os.environ.get("CONTEXTROS_BEFORE"):
        trees["before"] = Path(before)
    return trees
