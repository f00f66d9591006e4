"""`make demo`: the paper's cleaning robot, end to end, as separate processes.

Starts the Layer manager with the context rule of examples/cleaner/location.layers (GPS fix
means Outdoor, no fix Indoor), the localization (C++: examples/cleaner/cpp, built by `make
cpp`) and cleaning (Python) context nodes, then the simulated world, and narrates what each
process prints while the robot drives out of the building and back: each Indoor/Outdoor
switch with its latency, how long after the manager's publication each node had applied it,
and each node's changed behaviour. One manager switches both languages in one synchronous
activation, which the rule starts. Exits 0 once the robot is back inside and both nodes
behave as indoors again, 1 if that does not happen in time (every child is stopped either
way).

The domain is $ROS_DOMAIN_ID, else 42; discovery stays on this machine.
"""

from __future__ import annotations

import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from examples.launch import REPOSITORY, Launch, OutputLine

TIME_LIMIT = 45.0
CONTEXT_NODES = ("localization", "cleaning")
LANGUAGE = {"localization": "C++", "cleaning": "Python"}
CPP_LOCALIZATION = REPOSITORY / "build/cpp/examples/cleaner/cleaner_localization"
# The behaviour each part shows in each context (the paper's Table 1).
BEHAVIOUR = {
    "localization": {"Indoor": "gyro", "Outdoor": "GPS"},
    "cleaning": {"Indoor": "wiping", "Outdoor": "vacuuming"},
}
EXPECTED_CONTEXTS = ["Indoor", "Outdoor", "Indoor"]

SWITCHED = re.compile(r"switched to (\w+): (\d+) node\(s\) applied it in ([\d.]+) ms")
JOINED = re.compile(r"participant (/\w+) joined")
RULES = REPOSITORY / "examples/cleaner/location.layers"
POSITION = re.compile(r"position from the (\w+) now")
CLEANING = re.compile(r"cleaning by (\w+) now")
APPLIED = re.compile(r"applied epoch (\d+) \[([\w, ]*)\] ([\d.]+) ms after the manager published")


@dataclass
class Story:
    """What the processes reported so far, in the order they reported it."""

    switches: list[tuple[str, float]] = field(default_factory=list)
    behaviours: dict[str, list[str]] = field(
        default_factory=lambda: {name: [] for name in CONTEXT_NODES}
    )
    # Per context node: (active layers, ms after the manager's publication) of each state.
    applied: dict[str, list[tuple[str, float]]] = field(
        default_factory=lambda: {name: [] for name in CONTEXT_NODES}
    )
    joined: set[str] = field(default_factory=set)
    ready: bool = False
    route_complete: bool = False

    def record(self, line: OutputLine) -> None:
        if line.process in CONTEXT_NODES and (applied := APPLIED.search(line.text)):
            self.applied[line.process].append((applied.group(2), float(applied.group(3))))
        if line.process == "manager":
            if joined := JOINED.search(line.text):
                self.joined.add(joined.group(1))
            self.ready = self.ready or len(self.joined) >= len(CONTEXT_NODES)
            switched = SWITCHED.search(line.text)
            if switched:
                self.switches.append((switched.group(1), float(switched.group(3))))
        elif line.process == "world":
            self.route_complete = self.route_complete or "route complete" in line.text
        elif line.process == "localization" and (match := POSITION.search(line.text)):
            self.behaviours["localization"].append(match.group(1))
        elif line.process == "cleaning" and (match := CLEANING.search(line.text)):
            self.behaviours["cleaning"].append(match.group(1))

    def node_times(self) -> list[dict[str, float]]:
        """For each switch, how long after the manager's publication each node applied it."""
        times: list[dict[str, float]] = []
        seen = dict.fromkeys(CONTEXT_NODES, 0)
        for context, _ in self.switches:
            row: dict[str, float] = {}
            for node in CONTEXT_NODES:
                states = self.applied[node]
                while seen[node] < len(states) and states[seen[node]][0] != context:
                    seen[node] += 1
                if seen[node] < len(states):
                    row[node] = states[seen[node]][1]
                    seen[node] += 1
            times.append(row)
        return times

    def expected_behaviours(self, node: str) -> list[str]:
        return [BEHAVIOUR[node][context] for context in EXPECTED_CONTEXTS]

    def finished(self) -> bool:
        return (
            self.route_complete
            and [context for context, _ in self.switches] == EXPECTED_CONTEXTS
            and all(self.behaviours[n] == self.expected_behaviours(n) for n in CONTEXT_NODES)
        )


# rclpy's log prefix: "[INFO] [1795251002.40] [contextros_manager]: " (the narration has its own).
LOG_PREFIX = re.compile(r"^\[INFO\] \[[\d.]+\] \[[^\]]*\]: ")


def narrate(line: OutputLine) -> None:
    text = LOG_PREFIX.sub("", line.text)
    print(f"{line.at:6.2f} s  {line.process:<17} {text}", flush=True)


def run(time_limit: float = TIME_LIMIT) -> Story:
    story = Story()
    with Launch() as launch:

        def follow(until: float, done: Callable[[], bool]) -> bool:
            """Narrate until `done()` (True), the time `until` or a child's early exit (False)."""
            while launch.elapsed() < until:
                line = launch.next_line(timeout=until - launch.elapsed())
                if line is None:
                    break
                narrate(line)
                story.record(line)
                if done():
                    return True
                for name, process in launch.processes.items():
                    if process.poll() is not None:
                        print(f"{name} exited early with status {process.returncode}")
                        return False
            return False

        print(
            "starting the Layer manager with the rule of location.layers, localization (C++)"
            " and cleaning (Python)"
        )
        launch.start_module(
            "manager", "contextros", "manager", "--recovery-window", "0.3", "--rules", str(RULES)
        )
        launch.start("localization", [str(CPP_LOCALIZATION)])
        launch.start_module("cleaning", "examples.cleaner.cleaning")
        if follow(time_limit, lambda: story.ready):
            # The world starts driving once the localization and the manager's rule listen.
            launch.start_module("world", "examples.cleaner.world")
            follow(time_limit, story.finished)
    return story


def summary(story: Story) -> str:
    lines = ["", "summary (the paper's Table 1):"]
    for node in CONTEXT_NODES:
        behaviours = " -> ".join(story.behaviours[node]) or "nothing"
        lines.append(f"  {node + ' (' + LANGUAGE[node] + ')':<22} {behaviours}")
    for (context, latency), times in zip(story.switches, story.node_times(), strict=False):
        each = ", ".join(
            f"{node} ({LANGUAGE[node]}) {times[node]:.1f} ms"
            for node in CONTEXT_NODES
            if node in times
        )
        lines.append(
            f"  switch to {context:<8} acknowledged by both in {latency:.1f} ms"
            f" (applied after publication: {each or 'not seen'})"
        )
    return "\n".join(lines)


def main() -> int:
    if not CPP_LOCALIZATION.exists():
        print(f"demo: {CPP_LOCALIZATION} is not built: run `make demo` (or `make cpp`)")
        return 1
    started = time.monotonic()
    story = run()
    print(summary(story))
    if story.finished():
        print(f"demo complete in {time.monotonic() - started:.1f} s")
        return 0
    print(
        "demo FAILED: expected the contexts "
        f"{' -> '.join(EXPECTED_CONTEXTS)} and the matching behaviours of every node",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())
