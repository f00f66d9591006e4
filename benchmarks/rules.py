"""Context rules: the manager-side cost of evaluating rules per message (issue 11, target:
at most 50 µs per message).

Measured in one process, on real rosidl message objects (sensor_msgs NavSatFix and
BatteryState), with the rules parsed from layer-file text: `RuleEngine.on_message` as the
manager's subscription callback calls it (after rclpy has deserialized the message, which
every subscriber pays whatever it does). Cases: the cleaning robot's one rule with no
change (the steady state: nearly every message); a message that makes it fire, including
the manager protocol turning the firing into a published state (validation, next
configuration, declared order); and ten rules on one topic, each with a compound condition
(and/or/not) and hysteresis.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

ROUNDS = 5
CALLS = 20_000
TARGET_US = 50.0


def _best(run: Callable[[int], None], calls: int) -> float:
    """Fastest of ROUNDS rounds, in µs per call."""
    best = float("inf")
    for _ in range(ROUNDS):
        started = time.perf_counter_ns()
        run(calls)
        best = min(best, (time.perf_counter_ns() - started) / calls / 1000)
    return best


def run() -> list[dict[str, Any]]:
    from sensor_msgs.msg import BatteryState, NavSatFix

    from contextros.protocol import (
        ActivationCommand,
        LayerDeclaration,
        ManagerProtocol,
        ManagerSettings,
        ParticipantReport,
    )
    from contextros.rules import Rule, RuleEngine, RuleSet

    gps = RuleEngine(
        RuleSet.from_rules(
            [Rule("GpsFix", "Outdoor while gps/fix.status.status >= 0 for 0.15 s else Indoor")]
        )
    )
    fix = NavSatFix()
    fix.status.status = 0

    def steady(calls: int) -> None:
        on_message = gps.on_message
        for i in range(calls):
            on_message("gps/fix", fix, float(i))

    steady(10)  # settle the rule: later messages change nothing

    # Firing: alternate fix / no fix with no hold time, every message fires, and the firing
    # goes through the manager protocol as the manager node does it.
    flip = RuleEngine(
        RuleSet.from_rules([Rule("GpsFix", "Outdoor while gps/fix.status.status >= 0 else Indoor")])
    )
    protocol = ManagerProtocol(0.0, ManagerSettings(recovery_window=0.0))
    layers = (
        LayerDeclaration("Indoor", group="location"),
        LayerDeclaration("Outdoor", group="location"),
    )
    protocol.receive_status(ParticipantReport(node="/n", incarnation="1", layers=layers), 0.0)
    protocol.tick(1.0)
    no_fix = NavSatFix()
    no_fix.status.status = -1
    messages = (fix, no_fix)

    def firing(calls: int) -> None:
        on_message, receive = flip.on_message, protocol.receive_command
        for i in range(calls):
            for f in on_message("gps/fix", messages[i & 1], 2.0 + i):
                receive(
                    ActivationCommand(
                        -i,
                        activate=f.activate,
                        deactivate=f.deactivate,
                        requester=f.requester,
                        reason=f.reason,
                    ),
                    2.0 + i,
                )

    ten = RuleEngine(
        RuleSet.from_rules(
            [
                Rule(
                    f"Rule{i}",
                    f"Layer{i} while battery.percentage < {10 + i} and not battery.present == "
                    f"false or battery.voltage > {30 + i} for 1 s hysteresis 2",
                )
                for i in range(10)
            ]
        )
    )
    battery = BatteryState(percentage=50.0, voltage=12.0, present=True)

    def ten_rules(calls: int) -> None:
        on_message = ten.on_message
        for i in range(calls):
            on_message("battery", battery, float(i))

    ten_rules(10)
    rows = [
        {"case": "cleaner rule, no change (steady state)", "us": _best(steady, CALLS)},
        {
            "case": "cleaner rule fires + manager protocol publishes",
            "us": _best(firing, CALLS // 4),
        },
        {
            "case": "ten compound rules with hysteresis, one topic",
            "us": _best(ten_rules, CALLS // 4),
        },
    ]
    return rows


def markdown(rows: list[dict[str, Any]]) -> str:
    lines = ["| case | µs per message | target |", "|---|---:|---|"]
    for row in rows:
        verdict = "met" if row["us"] <= TARGET_US else "MISSED"
        lines.append(f"| {row['case']} | {row['us']:.2f} | <= {TARGET_US:g} µs: {verdict} |")
    import datetime

    from benchmarks.__main__ import machine

    when = f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC"
    lines += [
        "",
        f"Command: `python -m benchmarks rules` (rewrites this section only), {when}, on "
        f"{machine()}, other sessions' builds and tests running on the same 2 cores.",
    ]
    return "\n".join(lines)
