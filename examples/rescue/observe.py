"""docs/observability.md's walkthrough, run end to end (`make observe`): the rescue robot's
mission (`make demo-rescue`) watched by `contextros dashboard` and recorded by `contextros
record`; a screenshot of the page once the battery ran low; then the recording replayed
through the robot's rules and through changed ones, each with its timeline.

Writes docs/images/dashboard-rescue.png, docs/images/replay-rescue.png and
docs/images/replay-rescue-changed.png, and build/observe/rescue.mcap; prints each replay.
Needs Debian's chromium (`make test` installs it) for the screenshot.
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from pathlib import Path

from examples.launch import REPOSITORY, Launch, ros_environment

NAMESPACE = "/rescue1"
LAYERS = REPOSITORY / "examples/rescue/rescue.layers"
IMAGES = REPOSITORY / "docs/images"
WORK = REPOSITORY / "build/observe"
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
URL = re.compile(r"dashboard on (http://\S+/)")
# The changed rules of the walkthrough: the battery threshold at 30 %, held 1 s.
CHANGED = ("battery.percentage < 20 for 0.3 s", "battery.percentage < 30 for 1 s")


def main() -> int:
    IMAGES.mkdir(parents=True, exist_ok=True)
    WORK.mkdir(parents=True, exist_ok=True)
    recording = WORK / "rescue.mcap"
    recording.unlink(missing_ok=True)
    with Launch() as launch:
        launch.start_module(
            "dashboard", "contextros", "dashboard", "--namespace", NAMESPACE, "--port", "0"
        )
        url = _wait_for(launch, lambda line: line.process == "dashboard" and URL.search(line.text))
        launch.start_module(
            "record",
            "contextros",
            "record",
            str(recording),
            "--namespace",
            NAMESPACE,
            "--rules",
            str(LAYERS),
        )
        time.sleep(1.0)  # the recorder subscribes before the robot starts
        mission = subprocess.Popen(
            [sys.executable, "-m", "examples.rescue.demo"],
            cwd=REPOSITORY,
            env=ros_environment(),
            stdout=subprocess.PIPE,
            text=True,
        )
        _screenshot(URL.search(url.text).group(1), IMAGES / "dashboard-rescue.png")
        output, _ = mission.communicate(timeout=90)
        print(output[output.index("summary:") :] if "summary:" in output else output)
        launch.stop("record")
        time.sleep(0.5)  # its last lines
        while (line := launch.next_line(0.2)) is not None:
            if line.process == "record" and line.text.startswith("recorded "):
                print(line.text)
    changed = WORK / "rescue-changed.layers"
    changed.write_text(LAYERS.read_text(encoding="utf-8").replace(*CHANGED), encoding="utf-8")
    for rules, image in ((LAYERS, "replay-rescue.png"), (changed, "replay-rescue-changed.png")):
        subprocess.run(
            [
                sys.executable,
                "-m",
                "contextros",
                "rules",
                "replay",
                str(recording),
                "--namespace",
                NAMESPACE,
                "--rules",
                str(rules),
                "--plot",
                str(IMAGES / image),
            ],
            check=True,
        )
    return mission.returncode


def _wait_for(launch: Launch, wanted, timeout: float = 30.0):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = launch.next_line(0.2)
        if line is not None and wanted(line):
            return line
    raise SystemExit("the dashboard did not start")


def _screenshot(url: str, path: Path) -> None:
    """The page once LowBattery is active (the mission's third switch)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path="/usr/bin/chromium", headless=True, args=CHROMIUM_FLAGS
        )
        page = browser.new_page(viewport={"width": 1280, "height": 1000})
        page.goto(url)
        page.locator('[data-testid="active"]', has_text="LowBattery").wait_for(timeout=60_000)
        time.sleep(0.5)
        page.screenshot(path=str(path), full_page=True)
        browser.close()


if __name__ == "__main__":
    sys.exit(main())
