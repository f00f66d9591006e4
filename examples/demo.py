"""`make demo`: the paper's cleaning robot, end to end, as separate processes.

Starts the Layer manager, the localization and cleaning context nodes and the context
detector, then the simulated world, and narrates what each process prints while the robot
drives out of the building and back: each Indoor/Outdoor switch with its latency and each
node's changed behaviour. Exits 0 once the robot is back inside and both nodes behave as
indoors again, 1 if that does not happen in time (every child is stopped either way).

The domain is $ROS_DOMAIN_ID, else 42; discovery stays on this machine.
"""

from __future__ import annotations

import re
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from examples.launch import Launch, OutputLine

TIME_LIMIT = 45.0
CONTEXT_NODES = ("localization", "cleaning")
# The behaviour each part shows in each context (the paper's Table 1).
BEHAVIOUR = {
    "localization": {"Indoor": "gyro", "Outdoor": "GPS"},
    "cleaning": {"Indoor": "wiping", "Outdoor": "vacuuming"},
}
EXPECTED_CONTEXTS = ["Indoor", "Outdoor", "Indoor"]

SWITCHED = re.compile(r"switched to (\w+): (\d+) nodes applied it in ([\d.]+) ms")
POSITION = re.compile(r"position from the (\w+) now")
CLEANING = re.compile(r"cleaning by (\w+) now")


@dataclass
class Story:
    """What the processes reported so far, in the order they reported it."""

    switches: list[tuple[str, float]] = field(default_factory=list)
    behaviours: dict[str, list[str]] = field(
        default_factory=lambda: {name: [] for name in CONTEXT_NODES}
    )
    ready: bool = False
    route_complete: bool = False

    def record(self, line: OutputLine) -> None:
        if line.process == "context_detector":
            self.ready = self.ready or line.text.startswith("ready")
            switched = SWITCHED.search(line.text)
            if switched:
                self.switches.append((switched.group(1), float(switched.group(3))))
        elif line.process == "world":
            self.route_complete = self.route_complete or "route complete" in line.text
        elif line.process == "localization" and (match := POSITION.search(line.text)):
            self.behaviours["localization"].append(match.group(1))
        elif line.process == "cleaning" and (match := CLEANING.search(line.text)):
            self.behaviours["cleaning"].append(match.group(1))

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

        print("starting the Layer manager, localization, cleaning and the context detector")
        launch.start_module("manager", "contextros", "manager", "--recovery-window", "0.3")
        for name in CONTEXT_NODES:
            launch.start_module(name, f"examples.cleaner.{name}")
        launch.start_module("context_detector", "examples.cleaner.context_detector", "--nodes", "2")
        if follow(time_limit, lambda: story.ready):
            # Let the first decision (the robot is switched on inside) settle before driving.
            follow(launch.elapsed() + 1.0, lambda: bool(story.switches))
            launch.start_module("world", "examples.cleaner.world")
            follow(time_limit, story.finished)
    return story


def summary(story: Story) -> str:
    lines = ["", "summary (the paper's Table 1):"]
    for node in CONTEXT_NODES:
        lines.append(f"  {node:<13} {' -> '.join(story.behaviours[node]) or 'nothing'}")
    for context, latency in story.switches:
        lines.append(f"  switch to {context:<8} reached both context nodes in {latency:.1f} ms")
    return "\n".join(lines)


def main() -> int:
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
