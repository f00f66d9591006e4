"""The dashboard (issue 17): how soon a switch shows on the page, and whether a page left open
stays bounded. A manager, four context nodes (one process) and `contextros dashboard`; the page
in Debian's headless Chromium records, with a MutationObserver, the wall-clock time at which
each epoch appears; the latency is that time minus the state's stamp (the manager's wall clock
at publication; one host, one clock). Target: within 100 ms of a switch. Then 2,000 switches
back to back: the page's JS heap (after a garbage collection) and the dashboard process's
resident memory before and after.
"""

from __future__ import annotations

import re
import statistics
import time
from typing import Any

from benchmarks.activation import _wait_for_lines
from benchmarks.storm import _rss_kib

DOMAIN = 97
SWITCHES = 40  # measured one at a time, 150 ms apart
SOAK = 2_000  # then back to back
TARGET_MS = 100.0
URL = re.compile(r"dashboard on (http://\S+/)")
FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--enable-precise-memory-info",
    "--js-flags=--expose-gc",
]
OBSERVE = """() => {
  window.seen = {};
  const record = () => {
    const epoch = document.querySelector('[data-testid=epoch]');
    if (epoch) { const n = epoch.textContent.split(' ')[1]; window.seen[n] ??= Date.now(); }
  };
  new MutationObserver(record).observe(document.body, {childList: true, subtree: true});
}"""


def _heap(page: Any) -> int:
    return int(page.evaluate("() => { gc(); return performance.memory.usedJSHeapSize; }"))


def run() -> list[dict[str, Any]]:
    import rclpy
    from contextros_interfaces.msg import LayerState
    from examples.launch import Launch
    from playwright.sync_api import sync_playwright
    from rclpy.node import Node

    from contextros.ros import STATE_QOS, STATE_TOPIC, LayerClient
    from contextros.ros.messages import stamp_to_seconds

    names = [f"dash_n{index}" for index in range(4)]
    with Launch(DOMAIN, grace=5.0) as launch:
        launch.start_module("manager", "contextros", "manager", "--recovery-window", "0.3")
        launch.start_module("worker", "benchmarks.activation", "worker", *names)
        _wait_for_lines(launch, "ready", 1)
        dashboard = launch.start_module("dashboard", "contextros", "dashboard", "--port", "0")
        url = None
        while url is None:
            line = launch.next_line(30.0)
            assert line is not None, "the dashboard did not start"
            if match := URL.search(line.text):
                url = match.group(1)
        rclpy.init(domain_id=DOMAIN)
        node = Node("bench_dashboard_client")
        client = LayerClient(node, requester="bench")
        stamps: dict[int, float] = {}  # epoch -> the state's stamp (seconds)

        def on_state(msg: Any) -> None:
            stamps.setdefault(msg.epoch, stamp_to_seconds(msg.stamp))

        node.create_subscription(LayerState, STATE_TOPIC, on_state, STATE_QOS)
        try:
            client.wait_for_manager(15.0)
            first = client.query().epoch
            time.sleep(1.0)
            with sync_playwright() as playwright:
                browser = playwright.chromium.launch(
                    executable_path="/usr/bin/chromium", headless=True, args=FLAGS
                )
                page = browser.new_page()
                page.goto(url)
                page.locator('[data-testid="nodes"]', has_text=names[0]).wait_for()
                page.evaluate(OBSERVE)
                for index in range(SWITCHES):
                    result = client.request([("Indoor", "Outdoor")[index % 2]])
                    assert result.success, result.message
                    deadline = time.monotonic() + 0.15
                    while time.monotonic() < deadline or result.epoch not in stamps:
                        rclpy.spin_once(node, timeout_sec=0.02)
                seen = page.evaluate("() => window.seen")
                latencies = [
                    seen[str(epoch)] - published * 1000
                    for epoch, published in stamps.items()
                    if str(epoch) in seen and epoch > first
                ]
                heap_before, rss_before = _heap(page), _rss_kib(dashboard.pid)
                for index in range(SOAK):
                    client.request([("Indoor", "Outdoor")[index % 2]])
                last = client.query().epoch
                page.locator('[data-testid="epoch"]', has_text=f"epoch {last}").wait_for()
                time.sleep(1.0)
                heap_after, rss_after = _heap(page), _rss_kib(dashboard.pid)
                browser.close()
        finally:
            node.destroy_node()
            rclpy.try_shutdown()
    return [
        {
            "switches": len(latencies),
            "median_ms": statistics.median(latencies),
            "p90_ms": statistics.quantiles(latencies, n=10)[-1],
            "max_ms": max(latencies),
            "heap_kib": (heap_before // 1024, heap_after // 1024),
            "rss_kib": (rss_before, rss_after),
        }
    ]


def markdown(rows: list[dict[str, Any]]) -> str:
    (row,) = rows
    verdict = "met" if row["p90_ms"] <= TARGET_MS else "MISSED"
    return "\n".join(
        [
            "| switches | median | p90 | max | target (p90) | page JS heap, after "
            f"{SOAK} more switches | dashboard RSS, same |",
            "|---|---|---|---|---|---|---|",
            f"| {row['switches']} | {row['median_ms']:.1f} ms | {row['p90_ms']:.1f} ms | "
            f"{row['max_ms']:.1f} ms | <= {TARGET_MS:.0f} ms: {verdict} | "
            f"{row['heap_kib'][0]} -> {row['heap_kib'][1]} KiB | "
            f"{row['rss_kib'][0]} -> {row['rss_kib'][1]} KiB |",
        ]
    )
