"""The dashboard (issue 17): how soon a switch shows on the page, and whether a page left open
stays bounded. A manager, four context nodes (one process) and `contextros dashboard`; the page
in Debian's headless Chromium records, with a MutationObserver, the wall-clock time at which
each epoch appears; the latency is that time minus the state's stamp (the manager's wall clock
at publication; one host, one clock). Target: within 100 ms of a switch. Then 2,000 switches
back to back: the page's JS heap (after a garbage collection) and the dashboard process's
resident memory before and after.
"""

from __future__ import annotations

import argparse
import contextlib
import re
import statistics
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
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


@contextlib.contextmanager
def _system() -> Iterator[_Bench]:
    """A manager, four context nodes, the dashboard, and its page open in Chromium."""
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
        bench = _Bench(LayerClient(node, requester="bench"), node, dashboard.pid)

        def on_state(msg: Any) -> None:
            bench.stamps.setdefault(msg.epoch, stamp_to_seconds(msg.stamp))

        node.create_subscription(LayerState, STATE_TOPIC, on_state, STATE_QOS)
        try:
            bench.client.wait_for_manager(15.0)
            time.sleep(1.0)
            with sync_playwright() as playwright:
                browser = playwright.chromium.launch(
                    executable_path="/usr/bin/chromium", headless=True, args=FLAGS
                )
                bench.page = browser.new_page()
                bench.page.goto(url)
                bench.page.locator('[data-testid="nodes"]', has_text=names[0]).wait_for()
                bench.page.evaluate(OBSERVE)
                yield bench
                browser.close()
        finally:
            node.destroy_node()
            rclpy.try_shutdown()


@dataclass
class _Bench:
    client: Any
    node: Any
    dashboard_pid: int
    page: Any = None
    stamps: dict[int, float] = field(default_factory=dict)  # epoch -> the state's stamp (s)

    def switch(self, index: int, pause: float) -> None:
        """One switch, then `pause` seconds (and until its state was heard here)."""
        import rclpy

        result = self.client.request([("Indoor", "Outdoor")[index % 2]])
        assert result.success, result.message
        deadline = time.monotonic() + pause
        while time.monotonic() < deadline or result.epoch not in self.stamps:
            rclpy.spin_once(self.node, timeout_sec=0.02)

    def latencies(self, since_epoch: int) -> list[float]:
        seen = self.page.evaluate("() => window.seen")
        return [
            seen[str(epoch)] - published * 1000
            for epoch, published in self.stamps.items()
            if str(epoch) in seen and epoch > since_epoch
        ]

    def memory(self) -> tuple[int, int]:
        """The page's JS heap after a garbage collection, the dashboard's RSS (KiB)."""
        heap = self.page.evaluate("() => { gc(); return performance.memory.usedJSHeapSize; }")
        return int(heap) // 1024, _rss_kib(self.dashboard_pid)


def run() -> list[dict[str, Any]]:
    with _system() as bench:
        first = bench.client.query().epoch
        for index in range(SWITCHES):
            bench.switch(index, 0.15)
        latencies = bench.latencies(first)
        before = bench.memory()
        for index in range(SOAK):
            bench.client.request([("Indoor", "Outdoor")[index % 2]])
        last = bench.client.query().epoch
        bench.page.locator('[data-testid="epoch"]', has_text=f"epoch {last}").wait_for()
        time.sleep(1.0)
        after = bench.memory()
    return [
        {
            "switches": len(latencies),
            "median_ms": statistics.median(latencies),
            "p90_ms": statistics.quantiles(latencies, n=10)[-1],
            "max_ms": max(latencies),
            "heap_kib": (before[0], after[0]),
            "rss_kib": (before[1], after[1]),
        }
    ]


def soak(seconds: float) -> None:
    """A page left open: a switch every 2 s for `seconds`; each minute, the memory and the
    latency of that minute's switches (`python -m benchmarks.dashboard --open-for 3600`)."""
    with _system() as bench:
        started = time.monotonic()
        index, minute_start = 0, bench.client.query().epoch
        print("minute  page heap KiB  dashboard RSS KiB  switches  median ms  max ms", flush=True)
        while time.monotonic() - started < seconds:
            bench.switch(index, 2.0)
            index += 1
            if index % 30 == 0:
                latencies = bench.latencies(minute_start)
                minute_start = bench.client.query().epoch
                heap, rss = bench.memory()
                print(
                    f"{index // 30:6d}  {heap:13d}  {rss:17d}  {len(latencies):8d}  "
                    f"{statistics.median(latencies):9.1f}  {max(latencies):6.1f}",
                    flush=True,
                )


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


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=soak.__doc__)
    parser.add_argument("--open-for", type=float, default=600.0, metavar="S")
    soak(parser.parse_args().open_for)
