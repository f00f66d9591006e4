"""Unix manners of every `contextros` command, as real processes: SIGINT, SIGTERM and a
standard output closed early end it quietly with the status docs/cli.md gives.

The commands come from the CLI's own parser, so a new one is covered without a word here
(with no arguments unless `INVOCATIONS` gives some that keep it busy). The cases of one
kind run at once, in parallel processes; a command that needs a manager runs against none.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from contextros.cli import RUN_UNTIL_STOPPED, build_parser, subcommands
from contextros.cli.exits import CLOSED_OUTPUT
from tests.ros.processes import reserve_domain_id

CONTEXTROS = [sys.executable, "-m", "contextros"]
COMMANDS = sorted(subcommands(build_parser()))
# Exit statuses a command may end with by itself (docs/cli.md, "Exit statuses").
OWN_STATUSES = {0, 1, 2, 3}
MANAGER_DOMAIN = "TEST_MANAGER_DOMAIN"  # (in the environment given to start())
CRASH_SIGNS = ("Traceback", "terminate called", "Exception ignored", "core dumped", "Aborted")
LAYERS = "layer Night:\n    def speed() -> float:\n        return 0.5\n"
BROKEN = "layer Night\n"


# Arguments that keep a command busy for seconds: waiting for a manager that is not there,
# or opening a FIFO no one writes to (the offline commands). The others run as they are:
# those in RUN_UNTIL_STOPPED until stopped, the rest (`daemon stop`) may end first.
BUSY = {
    "compile": ["{fifo}.layers"],
    "check": ["{fifo}.layers"],
    "import-modes": ["{fifo}.yaml"],
    "rules replay": ["{fifo}.mcap", "--rules", "{files}/robot.layers"],
    "repair": ["{fifo}.mcap"],
    "activate": ["Night", "--wait-manager", "20"],
    "deactivate": ["Night", "--wait-manager", "20"],
    "switch": ["--on", "Night", "--wait-manager", "20"],
    "status": ["--wait-manager", "20"],
    "record": ["{files}/run.mcap"],
    "dashboard": ["--port", "0"],
    "daemon start": ["--foreground"],
}


def invocation(command: str, files: Path) -> list[str]:
    fifo = files / command.replace(" ", "_")  # one each: no writer ever opens it
    extra = [word.format(fifo=fifo, files=files) for word in BUSY.get(command, [])]
    for word in extra:
        if word.startswith(str(fifo)) and not os.path.exists(word):
            os.mkfifo(word)
    return [*command.split(), *extra]


# Commands that print on their standard output: with a closed one they must end with 141.
PRINTING = {
    "compile": lambda files: ["compile", str(files / "robot.layers"), "-o", "-"],
    "check": lambda files: ["check", str(files / "broken.layers")],
    "daemon status": lambda files: ["daemon", "status"],
    "dashboard": lambda files: ["dashboard", "--port", "0"],
    "watch": lambda files: ["watch"],  # (nothing to print without a manager: it sees the pipe)
}


@dataclass
class Run:
    argv: list[str]
    popen: subprocess.Popen[str]
    stderr: str = ""
    ran_when_signalled: bool = field(default=False)


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("signals")
    (folder / "robot.layers").write_text(LAYERS, encoding="utf-8")
    (folder / "broken.layers").write_text(BROKEN, encoding="utf-8")
    runtime = folder / "runtime"
    runtime.mkdir(mode=0o700)
    return folder


@pytest.fixture(scope="module")
def environment(files: Path) -> Iterator[dict[str, str]]:
    """A domain with no manager (`contextros manager` runs in one of its own), and a daemon
    directory of the module's own."""
    empty_domain = reserve_domain_id(int(os.environ["ROS_DOMAIN_ID"]) + 1)
    env = dict(os.environ, ROS_DOMAIN_ID=str(empty_domain))
    env[MANAGER_DOMAIN] = str(reserve_domain_id(empty_domain + 1))
    env["CONTEXTROS_RUNTIME_DIR"] = str(files / "runtime")
    yield env
    subprocess.run(
        [*CONTEXTROS, "daemon", "stop", "--all"],
        env=env,
        capture_output=True,
        timeout=30,
    )


def start(argv: list[str], env: dict[str, str], stdout: int | None = None) -> Run:
    if argv[0] == "manager":  # the clients started beside it must find none
        env = dict(env, ROS_DOMAIN_ID=env[MANAGER_DOMAIN])
    if argv[:2] == ["daemon", "start"]:  # `daemon stop` beside it would wait for it
        runtime = Path(env["CONTEXTROS_RUNTIME_DIR"]) / "started"
        runtime.mkdir(mode=0o700, exist_ok=True)
        env = dict(env, CONTEXTROS_RUNTIME_DIR=str(runtime))
    popen = subprocess.Popen(
        [*CONTEXTROS, *argv],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL if stdout is None else stdout,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )
    return Run(argv, popen)


def catches(pid: int, signum: int) -> bool:
    """Whether the process has a handler for `signum` (the command's main installed it)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    mask = next(line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:"))
    return bool(int(mask, 16) & (1 << (signum - 1)))


def finish(runs: list[Run], timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    for run in runs:
        try:
            _, run.stderr = run.popen.communicate(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            os.killpg(run.popen.pid, signal.SIGKILL)
            _, run.stderr = run.popen.communicate()
            run.stderr += "\n(test: still running, killed)"


def signalled(
    env: dict[str, str], files: Path, signum: int, after: float, send: Callable[[int], None]
) -> list[Run]:
    """Every command started at once; each gets `signum` `after` s after its main
    installed its handlers."""
    runs = [start(invocation(command, files), env) for command in COMMANDS]
    try:
        pending = list(runs)
        deadline = time.monotonic() + 30
        armed: dict[int, float] = {}
        while pending and time.monotonic() < deadline:
            for run in list(pending):
                pid = run.popen.pid
                if run.popen.poll() is not None:
                    pending.remove(run)
                elif pid not in armed and catches(pid, signal.SIGTERM):
                    armed[pid] = time.monotonic()
                elif pid in armed and time.monotonic() - armed[pid] >= after:
                    run.ran_when_signalled = True
                    send(pid)
                    pending.remove(run)
            time.sleep(0.02)
    finally:
        finish(runs)
    return runs


def problems(runs: list[Run], expected: Callable[[Run], set[int]]) -> list[str]:
    found = []
    for run in runs:
        status = run.popen.returncode
        crashed = [sign for sign in CRASH_SIGNS if sign in run.stderr]
        if crashed or status not in expected(run):
            found.append(f"contextros {' '.join(run.argv)}: status {status}\n{run.stderr}")
    return found


def expected_on_signal(signum: int) -> Callable[[Run], set[int]]:
    def expected(run: Run) -> set[int]:
        command = run.argv[0]
        if run.argv[:2] == ["daemon", "start"] or command in RUN_UNTIL_STOPPED:
            return {0}
        if " ".join(run.argv[:2]) not in BUSY and command not in BUSY:
            return {*OWN_STATUSES, 128 + signum}  # it may have ended before the signal
        return {128 + signum}

    return expected


def test_the_commands_are_found_in_the_parser() -> None:
    assert {"manager", "status", "dashboard", "rules replay", "daemon stop"} <= set(COMMANDS)


def test_ctrl_c_ends_every_command_quietly(environment: dict[str, str], files: Path) -> None:
    """Ctrl-C reaches the terminal's whole foreground job (the command's process group),
    here early in each command's run: during its imports or rclpy's start."""
    runs = signalled(
        environment, files, signal.SIGINT, 0.2, lambda pid: os.killpg(pid, signal.SIGINT)
    )
    ended_first = [run.argv for run in runs if run.argv[0] in BUSY and not run.ran_when_signalled]
    assert ended_first == []
    assert not (found := problems(runs, expected_on_signal(signal.SIGINT))), "\n\n".join(found)


def test_sigterm_ends_every_command_quietly(environment: dict[str, str], files: Path) -> None:
    """`kill PID` reaches the command's process only (not a child asking the manager),
    here once each is at work: waiting, spinning or serving."""
    runs = signalled(
        environment, files, signal.SIGTERM, 1.5, lambda pid: os.kill(pid, signal.SIGTERM)
    )
    ended_first = [run.argv for run in runs if run.argv[0] in BUSY and not run.ran_when_signalled]
    assert ended_first == []
    assert not (found := problems(runs, expected_on_signal(signal.SIGTERM))), "\n\n".join(found)


def test_a_closed_standard_output_ends_every_command_quietly(
    environment: dict[str, str], files: Path
) -> None:
    """As `contextros ... | head -1` once head is gone: the reader closed its end first.
    A command still running after 4 s is stopped with SIGTERM (it printed nothing)."""
    runs = []
    for command, parser in subcommands(build_parser()).items():
        printing = PRINTING.get(command)
        if printing is not None:
            argv = printing(files)
        elif any("--wait-manager" in action.option_strings for action in parser._actions):
            argv = [*command.split(), "--wait-manager", "0.5"]
        else:
            argv = invocation(command, files)
        readable, writable = os.pipe()
        os.close(readable)
        runs.append(start(argv, environment, stdout=writable))
        os.close(writable)
    try:
        time.sleep(4.0)
        for run in runs:
            if run.popen.poll() is None:
                os.kill(run.popen.pid, signal.SIGTERM)
    finally:
        finish(runs)

    def expected(run: Run) -> set[int]:
        printing = " ".join(run.argv[:2]) in PRINTING or run.argv[0] in PRINTING
        if printing:
            return {CLOSED_OUTPUT}
        if run.argv[0] in RUN_UNTIL_STOPPED or run.argv[:2] == ["daemon", "start"]:
            return {0, CLOSED_OUTPUT}
        return {*OWN_STATUSES, CLOSED_OUTPUT, 128 + signal.SIGTERM}

    assert not (found := problems(runs, expected)), "\n\n".join(found)


def test_status_into_a_closed_pipe_with_a_manager(environment: dict[str, str]) -> None:
    """`contextros status | head -1`: the tables meet a closed pipe (141, no traceback)."""
    env = dict(environment, ROS_DOMAIN_ID=environment[MANAGER_DOMAIN])
    manager = subprocess.Popen(
        [*CONTEXTROS, "manager", "--recovery-window", "0.1"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    try:
        readable, writable = os.pipe()
        os.close(readable)
        closed = start(["status", "--wait-manager", "15"], env, stdout=writable)
        os.close(writable)
        shown = subprocess.run(
            [*CONTEXTROS, "status", "--wait-manager", "15"],
            capture_output=True,
            text=True,
            env=env,
            timeout=60,
        )
        finish([closed])
    finally:
        manager.send_signal(signal.SIGINT)
        manager.wait(30)
    assert shown.stdout.startswith("epoch "), shown.stderr
    assert closed.popen.returncode == CLOSED_OUTPUT, closed.stderr
    assert not [sign for sign in CRASH_SIGNS if sign in closed.stderr], closed.stderr


def test_options_go_before_or_after_the_command() -> None:
    """Every option of every command parses the same before the command as after it."""
    from contextros.cli import options_after_command

    parser = build_parser()
    for name, subparser in subcommands(parser).items():
        words = name.split()
        for action in subparser._actions:
            if not action.option_strings or action.option_strings[0] in ("-h", "--help"):
                continue
            option = action.option_strings[-1]
            # (a value may be a command's name: `--reason status activate X`)
            for value in ("/robot1", "status"):
                values = [] if action.nargs == 0 else [value]
                before = options_after_command(parser, [option, *values, *words])
                assert before == [*words, option, *values], (name, option, value)


def test_namespace_before_the_command_reaches_the_manager(environment: dict[str, str]) -> None:
    done = subprocess.run(
        [*CONTEXTROS, "--namespace", "/robot1", "status", "--wait-manager", "0.3", "--no-daemon"],
        capture_output=True,
        text=True,
        env=environment,
        timeout=60,
    )
    assert done.returncode == 3, done.stderr
    assert "/robot1/contextros/" in done.stderr
