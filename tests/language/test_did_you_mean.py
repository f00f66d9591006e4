"""A binding or a rule naming a layer the file does not declare, close to one it does: a
warning (a node may implement that layer) that names the close one."""

from __future__ import annotations

from pathlib import Path

import pytest

from contextros.cli import main
from contextros.language.checker import check_source

MISSPELT = """\
layer Slow:
    \"\"\"Drive slowly.\"\"\"
parameter Slw: base max_speed = 0.3
lifecycle Slow: propeller active
rule Careful: Slw while battery.percentage < 20
rule Other: Unrelated while battery.percentage < 10
"""


def test_a_misspelt_layer_of_a_binding_or_a_rule_gets_did_you_mean() -> None:
    found = [(d.severity.value, d.line, d.message) for d in check_source(MISSPELT, "t.layers")]
    warnings = [(line, message) for severity, line, message in found if severity == "warning"]
    assert [line for line, _ in warnings] == [3, 5, 6], found
    assert "'Slw', which this file does not declare (did you mean 'Slow'?)" in warnings[0][1]
    assert "'Slw', which this file does not declare (did you mean 'Slow'?)" in warnings[1][1]
    assert "did you mean" not in warnings[2][1]  # nothing close to 'Unrelated'


def test_contextros_check_keeps_it_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(MISSPELT, encoding="utf-8")
    assert main(["check", str(path)]) == 0
    assert "(did you mean 'Slow'?)" in capsys.readouterr().out
