"""Every numeric option of every `contextros` subcommand refuses nan, inf, a negative and a
too large value at once: status 2, argparse naming the option (docs/cli.md, "Numeric
options"). The options come from the parser, so a new one is covered without a word here."""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
from contextlib import redirect_stderr

import pytest

from contextros.cli import build_parser, option_types, subcommands
from contextros.protocol.validation import MAX_TIMEOUT

PARSER = build_parser()
NUMBER_TYPES = (option_types.Seconds, option_types.Count)


def numeric_options() -> list[tuple[str, argparse.Action]]:
    found = []
    for command, parser in sorted(subcommands(PARSER).items()):
        for action in parser._actions:
            if action.option_strings and (
                action.type in (int, float) or isinstance(action.type, NUMBER_TYPES)
            ):
                found.append((command, action))
    return found


def argv_around(command: str, option: str, value: str) -> list[str]:
    """`command` with its required arguments filled in and `option value`."""
    argv = command.split()
    for action in subcommands(PARSER)[command]._actions:
        if not action.option_strings and action.dest != "help":
            argv.append("x")  # a positional
        elif action.required:
            argv += [action.option_strings[0], "x"]
    return [*argv, option, value]


NUMERIC = numeric_options()
BAD = ("nan", "inf", "-inf", "-1", "1e400", "99999999", "ten")


def test_the_parser_has_the_numeric_options_the_docs_list() -> None:
    named = {f"{command} {action.option_strings[0]}" for command, action in NUMERIC}
    assert {
        "activate --timeout",
        "activate --expect-count",
        "status --wait-manager",
        "watch --count",
        "watch --duration",
        "manager --liveness-timeout",
        "record --duration",
        "dashboard --port",
        "daemon start --idle-timeout",
        "rules replay --tolerance",
    } <= named


@pytest.mark.parametrize(
    ("command", "action"), NUMERIC, ids=[f"{c} {a.option_strings[0]}" for c, a in NUMERIC]
)
def test_a_bad_number_is_a_usage_error_naming_the_option(
    command: str, action: argparse.Action
) -> None:
    option = action.option_strings[0]
    for value in BAD:
        stderr = io.StringIO()
        with redirect_stderr(stderr), pytest.raises(SystemExit) as exit:
            PARSER.parse_args(argv_around(command, option, value))
        assert exit.value.code == 2, (command, option, value)
        assert f"argument {option}" in stderr.getvalue(), stderr.getvalue()
    assert action.type not in (int, float), f"{command} {option}: a bare {action.type}"
    # A sensible value still parses.
    parsed = PARSER.parse_args(argv_around(command, option, "1"))
    assert getattr(parsed, action.dest) == 1


def test_the_cli_bound_on_a_timeout_is_the_managers() -> None:
    assert option_types.MAX_TIMEOUT == MAX_TIMEOUT


# (the option, the command line)
CASES = [
    ("--timeout", ["activate", "Indoor", "--timeout", "nan"]),  # the daemon's client crashed
    ("--timeout", ["activate", "Indoor", "--timeout", "99999"]),  # refused after rclpy started
    ("--expect-count", ["switch", "--on", "Indoor", "--sync", "--expect-count", "-1"]),
    ("--duration", ["watch", "--duration", "nan"]),  # hung
    ("--count", ["watch", "--count", "-1"]),  # exited 0, saying nothing
    ("--liveness-timeout", ["manager", "--liveness-timeout", "nan"]),  # was accepted
]


def test_real_commands_exit_2_with_the_option_named() -> None:
    """As real processes, in parallel (the daemon is not disabled: nothing reaches it)."""
    env = os.environ | {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    running = [
        subprocess.Popen(
            [sys.executable, "-m", "contextros", *case],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _, case in CASES
    ]
    try:
        outcomes = [process.communicate(timeout=20) for process in running]
    finally:
        for process in running:
            process.kill()
    for (option, case), process, (out, err) in zip(CASES, running, outcomes, strict=True):
        assert process.returncode == 2, (case, out, err)
        assert f"argument {option}: " in err, err
        assert "Traceback" not in err and not out, (case, out, err)
