"""`contextros dashboard` in a real headless Chromium (Debian's, driven by Playwright): a
switch driven from here shows on the page, with the nodes, the rules and the bindings."""

from __future__ import annotations

import os
import re
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from contextros.ros import LayerClient
from tests.ros.processes import HERE, Child, ProcessGroup
from tests.ros.system import LIVENESS, settle, wait_registry
from tests.ros.test_rules import Sensors

CHROMIUM = Path("/usr/bin/chromium")
# As the machine notes say: no GPU, no sandbox (root), and none of Chromium's own network
# traffic (this machine's network is closed).
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
LAYERS = """\
rule Battery: Night while battery.percentage < 20 for 0.2 s hysteresis 5
parameter Night: base max_speed = 0.5
"""
# Where the screenshot for docs/observability.md is written (the test's own temp folder unless
# CONTEXTROS_SCREENSHOTS names one).
SCREENSHOT_DIR = Path(os.environ.get("CONTEXTROS_SCREENSHOTS", tempfile.gettempdir()))
URL = re.compile(r"dashboard on (http://\S+/)")


@pytest.fixture(scope="module")
def system(client: LayerClient, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A manager with a rule and a binding, a participant, and the dashboard: its URL."""
    layers = tmp_path_factory.mktemp("dashboard") / "robot.layers"
    layers.write_text(LAYERS, encoding="utf-8")
    group = ProcessGroup()
    try:
        plain = group.start("plain nodes", [str(HERE / "plain_nodes_process.py")])
        # The default layers, and Survey, which implies CameraHigh (a hierarchy).
        participant = group.participant(
            "dash1", "--layers", "Indoor,Outdoor,Night,Slow,Fast,Gps,Survey,CameraHigh,CameraLow"
        )
        group.manager("--liveness-timeout", LIVENESS, "--layers", str(layers))
        dashboard = group.start("dashboard", ["-m", "contextros", "dashboard", "--port", "0"])
        for child in (plain, participant):
            child.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15)
        client.wait_for_manager(15.0)
        wait_registry(client, lambda r: any(p.node == "/dash1" for p in r.participants))
        yield _url(dashboard)
    finally:
        group.kill_all()


def _url(dashboard: Child) -> str:
    dashboard.wait_for(lambda _: any(URL.search(line) for line in dashboard.lines), 20, "its URL")
    match = next(URL.search(line) for line in dashboard.lines if URL.search(line))
    return match.group(1)


@pytest.fixture(scope="module")
def page(system: str) -> Iterator[Any]:
    assert CHROMIUM.exists(), "Debian's chromium is not installed: `make test` installs it"
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_FLAGS
        )
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 900})
            page.goto(system)
            yield page
        finally:
            browser.close()


def robot(page: Any) -> Any:
    return page.locator('section[data-robot="/"]')


def test_a_switch_shows_on_the_page_with_the_node_that_applied_it(
    page: Any, client: LayerClient
) -> None:
    settle(client)
    page.locator('[data-testid="connection"]', has_text="live").wait_for(timeout=10_000)
    section = robot(page)
    section.locator('[data-testid="nodes"]', has_text="/dash1").wait_for(timeout=10_000)
    result = client.request(["Indoor"], synchronous=True, timeout=5, reason="from the test")
    assert result.success, result.message
    active = section.locator('[data-testid="active"]')
    active.filter(has_text="Indoor").wait_for(timeout=5_000)
    epoch = section.locator('[data-testid="epoch"]')
    assert epoch.inner_text() == f"epoch {result.epoch}"
    assert "pytest: from the test" in section.inner_text()
    switches = section.locator('[data-testid="switches"] tbody tr')
    newest = switches.first
    newest.filter(has_text=re.compile(r"/dash1 \d+\.\d ms")).wait_for(timeout=5_000)
    assert newest.locator("td").first.inner_text() == str(result.epoch)
    shown_at = newest.locator("td").nth(1).inner_text()
    assert re.fullmatch(r"\d\d:\d\d:\d\d\.\d{3}", shown_at), f"to the ms: {shown_at}"
    nodes = section.locator('[data-testid="nodes"] tbody tr', has_text="/dash1")
    cells = nodes.locator("td").all_inner_texts()
    assert cells[:5] == ["/dash1", "Python", "ok", str(result.epoch), ""], cells
    assert section.locator('[data-testid="manager"]').inner_text() == "manager alive"


def test_the_rules_and_bindings_show_their_live_values(page: Any, client: LayerClient) -> None:
    sensors = Sensors(client)
    try:
        section = robot(page)
        rules = section.locator('[data-testid="rules"] tbody tr', has_text="Battery")
        deadline = time.monotonic() + 15
        while "battery.percentage = 50.0" not in rules.inner_text():
            assert time.monotonic() < deadline, rules.inner_text()
            sensors.publish(percentage=50.0)
            time.sleep(0.1)
        assert rules.locator("td").nth(1).inner_text() == "false"
        sensors.keep_publishing(
            lambda: "Night" in section.locator('[data-testid="active"]').inner_text(),
            percentage=10.0,
            what="the rule's switch on the page",
        )
        page.wait_for_function(
            "() => document.querySelector('[data-testid=rules] tbody tr td:nth-child(6)')"
            ".textContent.startsWith('activate Night: epoch')",
            timeout=5_000,
        )
        binding = section.locator('[data-testid="bindings"] tbody tr')
        binding.filter(has_text="ok: set to 0.5 for Night").wait_for(timeout=5_000)
        assert binding.locator("td").all_inner_texts()[:3] == ["Night", "/base", "max_speed = 0.5"]
        page.screenshot(path=str(SCREENSHOT_DIR / "dashboard.png"), full_page=True)
    finally:
        sensors.node.destroy_node()


def test_an_implied_layer_shows_what_implies_it(page: Any, client: LayerClient) -> None:
    settle(client)
    result = client.request(["Survey"], synchronous=True, timeout=5)
    assert result.success and list(result.active) == ["CameraHigh", "Survey"], result.message
    section = robot(page)
    implied = section.locator('[data-testid="active"] .implied')
    implied.filter(has_text="CameraHigh (implied by Survey)").wait_for(timeout=10_000)
    newest = section.locator('[data-testid="switches"] tbody tr').first
    assert "CameraHigh (implied by Survey), Survey" in newest.inner_text()


def test_the_page_stays_bounded_over_many_switches(page: Any, client: LayerClient) -> None:
    settle(client)
    for index in range(120):
        layer = ("Outdoor", "Indoor")[index % 2]
        assert client.request([layer], reason=f"switch {index}").success
    last = client.query().epoch
    section = robot(page)
    section.locator('[data-testid="epoch"]', has_text=f"epoch {last}").wait_for(timeout=10_000)
    rows = section.locator('[data-testid="switches"] tbody tr').count()
    assert rows == 50, "the history keeps the last 50 switches"
    elements = page.evaluate("() => document.getElementsByTagName('*').length")
    assert elements < 2_000, elements


def test_a_drifted_binding_shows_what_the_node_has(page: Any, client: LayerClient) -> None:
    """Another client sets max_speed while Night (which sets it to 0.5) is active: the
    bindings table shows the drift, and the actual bound layers differ from the target."""
    from tests.ros.test_drift import set_by_hand

    settle(client, "Night")
    section = robot(page)
    state = section.locator('[data-testid="actual-state"]')
    state.filter(has_text="as targeted").wait_for(timeout=10_000)
    set_by_hand(client, 0.8)
    drift = section.locator('[data-testid="drift"]')
    drift.filter(has_text="DRIFTED: 0.8 since").wait_for(timeout=10_000)
    assert state.inner_text() == "differs"
    assert "actual [none]" in section.locator('[data-testid="actual"]').inner_text()
    set_by_hand(client, 0.5)
    state.filter(has_text="as targeted").wait_for(timeout=10_000)
    assert drift.count() == 0
