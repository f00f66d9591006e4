"""The timeline's thresholds are the engine's: where hysteresis holds a rule on is drawn from
the same relaxed condition the engine evaluates (no ROS, no plotting)."""

from __future__ import annotations

from contextros.recording.timeline import thresholds
from contextros.rules import Rule, RuleSet


def test_each_threshold_is_drawn_where_the_engine_holds_the_rule() -> None:
    rules = RuleSet.from_rules(
        [
            Rule("Low", "LowBattery while battery.percentage < 20 hysteresis 5"),
            Rule("Full", "Charged while not battery.percentage < 90 hysteresis 5"),
            Rule("Hot", "Hot while 40 < temperature.data hysteresis 2"),
            Rule("Dock", "activate Docked when dock.level > 3"),
        ]
    )
    assert thresholds(rules) == {
        "battery.percentage": [("Low", 20.0, 25.0), ("Full", 90.0, 85.0)],
        "temperature.data": [("Hot", 40.0, 38.0)],
        "dock.level": [("Dock", 3.0, 3.0)],
    }
