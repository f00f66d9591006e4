"""The cleaning robot: its layers alone, then the whole demo in real processes."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from examples.launch import REPOSITORY, ros_environment

from contextros import set_active
from contextros.language import load
from tests.examples.conftest import DOMAIN_ID

RULES = Path(REPOSITORY, "examples", "cleaner", "location.layers")
location = load(RULES)


def test_indoors_the_robot_dead_reckons_from_the_gyro_and_wipes() -> None:
    set_active([location.Indoor])
    start = location.Pose(1.0, 2.0, 0.0, "none")
    pose = location.estimate_pose(start, location.Sensors(0.0, 2.0, (50.0, 50.0)), 0.5)
    assert (pose.x, pose.y, pose.source) == (2.0, 2.0, "gyro")  # the GPS is ignored
    assert location.cleaning_method() == "wiping"


def test_outdoors_the_robot_takes_the_gps_fix_and_vacuums() -> None:
    set_active([location.Outdoor])
    start = location.Pose(1.0, 2.0, 0.0, "none")
    pose = location.estimate_pose(start, location.Sensors(0.5, 2.0, (7.0, 8.0)), 0.5)
    assert (pose.x, pose.y, pose.heading, pose.source) == (7.0, 8.0, 0.25, "GPS")
    between_fixes = location.estimate_pose(pose, location.Sensors(0.0, 2.0, None), 0.5)
    assert (between_fixes.x, between_fixes.y) == (7.0, 8.0)
    assert location.cleaning_method() == "vacuuming"


def lines_of(output: str, process: str) -> list[str]:
    """The text of the narrated lines of one process ("  1.05 s  cleaning   text")."""
    found = []
    for line in output.splitlines():
        parts = line.split(maxsplit=3)
        if len(parts) == 4 and parts[1] == "s" and parts[2] == process:
            found.append(parts[3])
    return found


@dataclass(frozen=True)
class RecordedDemo:
    demo: subprocess.CompletedProcess[str]
    recording: Path
    recorder_output: str


@pytest.fixture(scope="module")
def recorded_demo(tmp_path_factory: pytest.TempPathFactory) -> RecordedDemo:
    """`make demo`'s run, recorded by `contextros record` beside it (rules' topics too)."""
    pytest.importorskip("contextros_interfaces", reason="run `make ros` to build the interfaces")
    recording = tmp_path_factory.mktemp("demo") / "demo.mcap"
    env = ros_environment(DOMAIN_ID)
    recorder = subprocess.Popen(
        [sys.executable, "-m", "contextros", "record", str(recording), "--rules", str(RULES)],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        demo = subprocess.run(
            [sys.executable, "-m", "examples.demo"],
            cwd=REPOSITORY,
            env=env,
            capture_output=True,
            text=True,
            timeout=90,
        )
    finally:
        recorder.send_signal(signal.SIGINT)
        try:
            output, _ = recorder.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            recorder.kill()
            output, _ = recorder.communicate()
    return RecordedDemo(demo, recording, output)


@pytest.mark.ros
def test_the_demo_switches_indoor_outdoor_indoor_and_every_node_follows(
    recorded_demo: RecordedDemo,
) -> None:
    """One manager switches the C++ localization node and the Python cleaning node."""
    demo = recorded_demo.demo
    assert demo.returncode == 0, demo.stdout + demo.stderr
    out = demo.stdout
    # The manager's rule (location.layers: `rule GpsFix: ...`) decides, from the GPS.
    switches = [t.split(":")[0] for t in lines_of(out, "manager") if "switched to" in t]
    assert switches == [
        "rule GpsFix switched to Indoor",
        "rule GpsFix switched to Outdoor",
        "rule GpsFix switched to Indoor",
    ]
    positions = [t.split()[3] for t in lines_of(out, "localization") if t.startswith("position")]
    assert positions == ["gyro", "GPS", "gyro"]
    methods = [t.split()[2] for t in lines_of(out, "cleaning") if t.startswith("cleaning by")]
    assert methods == ["wiping", "vacuuming", "wiping"]
    # Cause before effect: the robot is outside before any node behaves as outdoors.
    narration = out.splitlines()
    left = next(i for i, t in enumerate(narration) if "leaves the building" in t)
    first_gps = next(i for i, t in enumerate(narration) if "position from the GPS" in t)
    first_vacuum = next(i for i, t in enumerate(narration) if "cleaning by vacuuming" in t)
    assert left < first_gps and left < first_vacuum
    # The localization node is the C++ one, built from its C++ layer file.
    assert lines_of(out, "localization")[0].startswith("localization node in C++")
    # Each node says how long after the manager's publication it applied each switch.
    for node in ("localization", "cleaning"):
        applied = [t.split("[")[1].split("]")[0] for t in lines_of(out, node) if "applied" in t]
        contexts = [c for c in applied if c in ("Indoor", "Outdoor")]
        assert contexts == ["Indoor", "Outdoor", "Indoor"], f"{node}: {applied}"
    summary = out[out.index("summary") :]
    assert "localization (C++)     gyro -> GPS -> gyro" in summary
    assert "cleaning (Python)      wiping -> vacuuming -> wiping" in summary
    assert summary.count("applied after publication: localization (C++) ") == 3, summary
    assert "demo complete" in out


@pytest.mark.ros
def test_a_replay_of_the_recorded_demo_makes_the_switches_the_manager_made(
    recorded_demo: RecordedDemo, tmp_path: Path
) -> None:
    assert recorded_demo.demo.returncode == 0, recorded_demo.demo.stdout
    assert "recorded " in recorded_demo.recorder_output, recorded_demo.recorder_output
    plot = tmp_path / "timeline.png"
    replay = subprocess.run(
        [
            sys.executable,
            "-m",
            "contextros",
            "rules",
            "replay",
            str(recorded_demo.recording),
            "--rules",
            str(RULES),
            "--json",
            "--plot",
            str(plot),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert replay.returncode == 0, replay.stderr
    result = json.loads(replay.stdout)
    live = [(s["active"], s["requester"], s["time"]) for s in result["recorded"]]
    replayed = [(s["active"], s["requester"], s["time"]) for s in result["switches"]]
    assert [(a, who) for a, who, _ in live] == [
        (["Indoor"], "rule GpsFix"),
        (["Outdoor"], "rule GpsFix"),
        (["Indoor"], "rule GpsFix"),
    ], result
    assert [(a, who) for a, who, _ in replayed] == [(a, who) for a, who, _ in live], result
    # The recorder subscribes once it sees the GPS topic on the graph, and on a loaded
    # machine that can be after the manager's first readings: a switch the manager made on
    # readings the recording lacks comes later in the replay, as soon as the first recorded
    # reading has lasted the hold time. Every later switch comes when it came live.
    recorded_from = result["first_inputs"]["gps/fix"]
    for (_, _, live_at), (_, _, replayed_at) in zip(live, replayed, strict=True):
        if live_at < recorded_from + 0.15:
            assert replayed_at <= recorded_from + 0.15 + 0.1, result
        else:
            # Live, the manager's timer has its own phase and the state travels to the
            # recorder: within 0.15 s.
            assert abs(live_at - replayed_at) < 0.15, result
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
