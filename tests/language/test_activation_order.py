"""`contextros check --activation`: an activation order that contradicts `after` is warned
about where the order is declared (issue 11, part 4: the [Rubble, Flight, Flooded] case)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from contextros.language.checker import check_activation_order
from contextros.language.flavours import parse_with_diagnostics

RESCUE = """\
layer Flooded:
    def speed() -> float:
        return 0.2

layer Rubble after Flooded:
    def speed() -> float:
        return proceed() * 0.5

layer Deep after Rubble:
    def speed() -> float:
        return proceed()
"""


def warnings(order: list[str]) -> list[str]:
    layer_file, found = parse_with_diagnostics(RESCUE, "rescue.layers")
    assert not found
    return [d.render() for d in check_activation_order(layer_file, order)]


def test_a_contradicting_order_is_warned_at_the_after_declaration() -> None:
    (warning,) = warnings(["Rubble", "Flight", "Flooded"])
    assert warning.startswith("rescue.layers:5:20: warning: activation order Rubble, Flight,")
    assert "'layer Rubble after Flooded' is declared here" in warning
    assert warning.splitlines()[-1] == " " * 4 + " " * 19 + "^"


def test_an_agreeing_order_is_quiet() -> None:
    assert warnings(["Flooded", "Flight", "Rubble", "Deep"]) == []


def test_an_order_contradicting_a_chain_points_at_the_layer() -> None:
    (warning,) = warnings(["Deep", "Flooded"])
    assert warning.startswith("rescue.layers:9:7: warning:")
    assert "Deep comes after Flooded through the 'after' declarations" in warning


def test_the_command_line_option(tmp_path: Path) -> None:
    path = tmp_path / "rescue.layers"
    path.write_text(RESCUE, encoding="utf-8")
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "contextros",
            "check",
            str(path),
            "--activation",
            "Rubble",
            "Flooded",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout
    assert "activates Rubble before Flooded" in done.stdout
