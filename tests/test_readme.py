"""The README's usage example is code users will paste: it must run and print what it says."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_usage_example_runs_and_prints_its_comments() -> None:
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S)
    assert code is not None
    expected = re.findall(r"print\(.*?\)\s+# (.+)", code.group(1))
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code.group(1), str(README), "exec"), {})
    assert out.getvalue().splitlines() == expected


def test_readme_layer_file_checks_clean_and_compiles() -> None:
    from contextros.language import check_source, compile_source

    code = re.search(r"```python\n(# location\.layers.*?)```", README.read_text(), re.S)
    assert code is not None
    assert list(check_source(code.group(1), "location.layers")) == []
    compiled = compile_source(code.group(1), "location.layers")
    for name in ("def get_pos_Indoor", "def get_pos_Outdoor", "def Cleaner_clean_Indoor"):
        assert name in compiled.text
