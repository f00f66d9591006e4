"""`make demo-rescue`: the rescue robot of the paper's introduction, end to end.

One robot in the namespace /rescue1: the Layer manager running the rules, parameter and
lifecycle declarations of rescue.layers; the mobility context node; the motion controller
(an ordinary node with a `max_speed` parameter); the propeller driver (an ordinary lifecycle
node, in the sub-namespace /rescue1/drivers); and the simulated world (battery, terrain).
Narrates the mission: the terrain selects wheels or flight, a low battery forbids flight and
slows the robot down; each of these modes implies the modes of the robot's parts (the
propellers on or off, the controller's speed limit), which the manager activates with it.
Exits 0 once every part behaved as expected, 1 otherwise.
"""

from __future__ import annotations

import re
import sys
import time
from dataclasses import dataclass, field

from examples.launch import REPOSITORY, Launch, OutputLine

NAMESPACE = "/rescue1"
TIME_LIMIT = 45.0
LAYERS = REPOSITORY / "examples/rescue/rescue.layers"
# The states the mobility node applies, in order, after the manager's first (empty) one:
# each of the robot's modes with the parts' modes it implies (just before it).
EXPECTED_STATES = [
    "PropellersOff, Wheels",
    "PropellersOn, Flight",
    "PropellersOff, Wheels",
    "PropellersOff, Wheels, SlowDrive, LowBattery",
    "PropellersOff, Wheels",
    "PropellersOn, Flight",
    "PropellersOff, Wheels",
]
EXPECTED_SPEEDS = ["1.5", "0.3", "1.5"]
EXPECTED_PROPELLERS = [
    "propellers configured (resting)",
    "propellers spinning",
    "propellers stopped",
    "propellers spinning",
    "propellers stopped",
]
STATE = re.compile(r"^\[([\w, ]*)\] locomotion: (.*)$")
SPEED = re.compile(r"^max_speed ([\d.]+) m/s$")
LOG_PREFIX = re.compile(r"^\[INFO\] \[[\d.]+\] \[[^\]]*\]: ")


@dataclass
class Mission:
    states: list[str] = field(default_factory=list)
    speeds: list[str] = field(default_factory=list)
    propellers: list[str] = field(default_factory=list)
    switches: list[str] = field(default_factory=list)
    complete: bool = False

    def record(self, line: OutputLine) -> None:
        text = LOG_PREFIX.sub("", line.text)
        if line.process == "mobility" and (state := STATE.match(text)):
            if state.group(1) != "none":
                self.states.append(state.group(1))
        elif line.process == "controller" and (speed := SPEED.match(text)):
            self.speeds.append(speed.group(1))
        elif line.process == "propeller" and text.startswith("propellers"):
            self.propellers.append(text)
        elif line.process == "manager" and " switched to " in text:
            self.switches.append(text)
        elif line.process == "world" and text == "mission complete":
            self.complete = True

    def finished(self) -> bool:
        return (
            self.complete
            and self.states == EXPECTED_STATES
            and self.speeds == EXPECTED_SPEEDS
            and self.propellers == EXPECTED_PROPELLERS
        )


def run(time_limit: float = TIME_LIMIT) -> Mission:
    mission = Mission()
    robot = ("--ros-args", "-r", f"__ns:={NAMESPACE}")
    with Launch() as launch:
        launch.start_module("manager", "contextros", "manager", "--layers", str(LAYERS), *robot)
        launch.start_module("mobility", "examples.rescue.mobility", *robot)
        launch.start_module("controller", "examples.rescue.controller", *robot)
        launch.start_module(
            "propeller",
            "examples.rescue.propeller",
            "--ros-args",
            "-r",
            f"__ns:={NAMESPACE}/drivers",
        )
        launch.start_module("world", "examples.rescue.world", *robot)
        while launch.elapsed() < time_limit and not mission.finished():
            line = launch.next_line(timeout=time_limit - launch.elapsed())
            if line is None:
                break
            text = LOG_PREFIX.sub("", line.text)
            print(f"{line.at:6.2f} s  {line.process:<11} {text}", flush=True)
            mission.record(line)
            if mission.complete and not mission.finished():
                # Let the last acknowledgements and prints arrive.
                end = launch.elapsed() + 2.0
                while launch.elapsed() < end and not mission.finished():
                    late = launch.next_line(timeout=end - launch.elapsed())
                    if late is not None:
                        print(
                            f"{late.at:6.2f} s  {late.process:<11} {LOG_PREFIX.sub('', late.text)}"
                        )
                        mission.record(late)
                break
    return mission


def main() -> int:
    started = time.monotonic()
    mission = run()
    print("\nsummary:")
    print(f"  states      {' -> '.join(f'[{s}]' for s in mission.states) or 'none'}")
    print(f"  max_speed   {' -> '.join(mission.speeds) or 'never set'} m/s")
    print(f"  propellers  {' -> '.join(mission.propellers) or 'never moved'}")
    if mission.finished():
        print(f"rescue demo complete in {time.monotonic() - started:.1f} s")
        return 0
    print(
        f"rescue demo FAILED: expected states {EXPECTED_STATES}, speeds {EXPECTED_SPEEDS}, "
        f"propellers {EXPECTED_PROPELLERS}",
        file=sys.stderr,
    )
    return 1


if __name__ == "__main__":
    sys.exit(main())
