"""The greeting application: plain rclpy and ContextROS print the same thing in both cities."""

from __future__ import annotations

import re
import subprocess
import sys
import time
from collections.abc import Iterator
from datetime import datetime, timezone
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from examples.launch import Launch, ros_environment

if TYPE_CHECKING:
    from examples.greeting import context_node, plain_node

    BothNodes = tuple[plain_node.GreetingNode, context_node.GreetingNode]

# The same instants seen from both cities: morning, afternoon and evening in one or the other.
INSTANTS = [datetime(2026, 11, 21, hour, 30, tzinfo=timezone.utc) for hour in (0, 6, 10, 15, 21)]
EXPECTED = {
    ("Tokyo", 0): "09:30 JST おはようございます",
    ("Tokyo", 6): "15:30 JST こんにちは",
    ("Tokyo", 10): "19:30 JST こんばんは",
    ("Tokyo", 15): "00:30 JST こんばんは",
    ("Tokyo", 21): "06:30 JST おはようございます",
    ("London", 0): "00:30 GMT Good evening",
    ("London", 6): "06:30 GMT Good morning",
    ("London", 10): "10:30 GMT Good morning",
    ("London", 15): "15:30 GMT Good afternoon",
    ("London", 21): "21:30 GMT Good evening",
}
GREETING = re.compile(r"^(\d\d):(\d\d) (JST|GMT) (.+)$")


@pytest.fixture
def both_nodes(domain_id: int) -> Iterator[BothNodes]:
    import rclpy
    from examples.greeting import context_node, plain_node

    rclpy.init(domain_id=domain_id)
    plain, context = plain_node.GreetingNode(), context_node.GreetingNode()
    try:
        yield plain, context
    finally:
        plain.destroy_node()
        context.destroy_node()
        rclpy.try_shutdown()


@pytest.mark.ros
@pytest.mark.parametrize("city", ["Tokyo", "London"])
def test_both_implementations_greet_alike_at_every_time_of_day(
    both_nodes: BothNodes, city: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from examples.greeting.context_node import greeting
    from rclpy.parameter import Parameter

    from contextros import set_active

    plain, context = both_nodes
    plain.set_parameters([Parameter("city", value=city)])
    set_active([getattr(greeting, city)])  # what the manager's state does in the node
    for instant in INSTANTS:
        plain.greet(instant)
        context.greet(instant)
        plain_line, context_line = capsys.readouterr().out.splitlines()
        assert plain_line == context_line == EXPECTED[city, instant.hour]


@pytest.mark.ros
def test_the_plain_node_refuses_an_unknown_city(domain_id: int) -> None:
    run = subprocess.run(
        [sys.executable, "-m", "examples.greeting.plain_node", "--ros-args", "-p", "city:=Paris"],
        env=ros_environment(domain_id),
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert run.returncode != 0
    assert "unknown city 'Paris'" in run.stderr


def next_greeting(launch: Launch, process: str, zone: str, timeout: float = 15.0) -> str:
    deadline = time.monotonic() + timeout
    while (line := launch.next_line(deadline - time.monotonic())) is not None:
        match = GREETING.match(line.text)
        if line.process == process and match and match.group(3) == zone:
            return line.text
    raise AssertionError(f"{process} printed no {zone} greeting within {timeout:g} s")


def contextros(domain_id: int, *args: str) -> None:
    """A `contextros` command, retried while the manager does not know the city layers yet."""
    deadline = time.monotonic() + 15.0
    while True:
        run = subprocess.run(
            [sys.executable, "-m", "contextros", *args],
            env=ros_environment(domain_id),
            capture_output=True,
            text=True,
            timeout=30,
        )
        if run.returncode == 0 or time.monotonic() > deadline:
            assert run.returncode == 0, run.stdout + run.stderr
            return
        time.sleep(0.2)


def same_greeting(plain: str, context: str) -> bool:
    """Equal, but for the minute turning between the two lines."""
    a, b = GREETING.match(plain), GREETING.match(context)
    assert a and b
    minutes = [int(m.group(1)) * 60 + int(m.group(2)) for m in (a, b)]
    return a.group(3, 4) == b.group(3, 4) and abs(minutes[0] - minutes[1]) in (0, 1, 1439)


@pytest.mark.ros
def test_in_real_processes_the_layer_manager_switches_the_city(domain_id: int) -> None:
    with Launch(domain_id) as launch:
        launch.start_module("manager", "contextros", "manager", "--recovery-window", "0.3")
        launch.start_module("contextros_greeting", "examples.greeting.context_node")
        for city in ("Tokyo", "London"):
            launch.start_module(
                f"plain_{city}",
                "examples.greeting.plain_node",
                "--ros-args",
                "-r",
                f"__node:=greeting_{city.lower()}",
                "-p",
                f"city:={city}",
            )
        contextros(domain_id, "activate", "Tokyo", "--sync")
        tokyo = next_greeting(launch, "contextros_greeting", "JST")
        assert same_greeting(next_greeting(launch, "plain_Tokyo", "JST"), tokyo)
        contextros(domain_id, "switch", "--on", "London", "--off", "Tokyo", "--sync")
        london = next_greeting(launch, "contextros_greeting", "GMT")
        assert same_greeting(next_greeting(launch, "plain_London", "GMT"), london)


def test_the_line_counter_counts_code_not_docstrings_comments_or_blank_lines(
    tmp_path: Path,
) -> None:
    from benchmarks.greeting import counted_lines

    source = tmp_path / "sample.layers"
    source.write_text(
        '"""A module docstring\n\nover three lines."""\n'
        "# a comment\n"
        "import math  # a trailing comment does not hide code\n"
        "\n"
        "layer Tokyo:\n"
        '    """A layer docstring."""\n'
        "    def zone() -> float:\n"
        "        return (math.pi +\n"
        "                1.0)\n"
    )
    assert counted_lines(source) == 5  # import, layer, def, and the two lines of the return
