"""Rule evaluation, deterministic: messages and a clock in, firings out (no ROS)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from contextros.language.diagnostics import LayerSyntaxError
from contextros.rules import Firing, Rule, RuleEngine, RuleSet, resolve


def engine(*rules: tuple[str, str]) -> RuleEngine:
    return RuleEngine(RuleSet.from_rules([Rule(name, text) for name, text in rules]))


def battery(percentage: float, present: bool = True) -> SimpleNamespace:
    return SimpleNamespace(percentage=percentage, present=present)


def fix(status: int) -> SimpleNamespace:
    return SimpleNamespace(status=SimpleNamespace(status=status))


def feed(rules: RuleEngine, topic: str, values: list[object], period: float, start: float = 0.0):
    """Each message `period` apart; the firings with the time they came."""
    fired: list[tuple[float, Firing]] = []
    now = start
    for value in values:
        fired += [(now, f) for f in rules.on_message(topic, value, now)]
        now += period
    return fired


def test_a_hold_time_ignores_a_noisy_reading() -> None:
    rules = engine(("Gps", "Outdoor while gps/fix.status.status >= 0 for 0.15 s else Indoor"))
    readings = [fix(s) for s in (-1, -1, -1, -1, 0, -1, -1, 0, 0, 0, 0, 0)]
    fired = feed(rules, "gps/fix", readings, 0.05)
    assert [(round(t, 2), f.activate) for t, f in fired] == [
        (0.15, ("Indoor",)),
        (0.5, ("Outdoor",)),
    ]
    assert fired[1][1].requester == "rule Gps"
    assert fired[1][1].reason == "gps/fix.status.status >= 0 for 0.15 s (<rules>:1)"


def test_the_hold_time_also_passes_without_messages() -> None:
    rules = engine(("Low", "LowBattery while battery.percentage < 20 for 2 s"))
    assert rules.on_message("battery", battery(10), 0.0) == []
    assert rules.tick(1.9) == []
    (firing,) = rules.tick(2.0)
    assert firing.activate == ("LowBattery",)
    assert rules.tick(5.0) == [], "fires once per change"


def test_hysteresis_keeps_a_while_rule_true_until_the_margin_is_passed() -> None:
    rules = engine(("Low", "LowBattery while battery.percentage < 20 hysteresis 5"))
    values = [battery(p) for p in (30, 19, 21, 24.9, 20, 25, 19)]
    fired = feed(rules, "battery", values, 1.0)
    assert [(t, f.activate, f.deactivate) for t, f in fired] == [
        (0.0, (), ("LowBattery",)),
        (1.0, ("LowBattery",), ()),
        (5.0, (), ("LowBattery",)),
        (6.0, ("LowBattery",), ()),
    ]


def test_hysteresis_under_not_moves_the_other_way() -> None:
    rules = engine(("Full", "Charged while not battery.percentage < 90 hysteresis 5"))
    fired = feed(rules, "battery", [battery(p) for p in (95, 87, 84)], 1.0)
    assert [f.activate or f.deactivate for _, f in fired] == [("Charged",), ("Charged",)]
    assert [t for t, _ in fired] == [0.0, 2.0], "stays on at 87, goes off below 85"


def test_edge_rules_act_when_their_condition_starts_to_hold() -> None:
    rules = engine(
        ("Dock", "activate Docked when dock.data == true"),
        ("Undock", "deactivate Docked when dock.data == false"),
    )
    docked, free = SimpleNamespace(data=True), SimpleNamespace(data=False)
    fired = feed(rules, "dock", [free, docked, docked, free], 1.0)
    assert [(f.rule, f.activate, f.deactivate) for _, f in fired] == [
        ("Undock", (), ("Docked",)),
        ("Dock", ("Docked",), ()),
        ("Undock", (), ("Docked",)),
    ]


def test_a_condition_on_two_topics_waits_for_both() -> None:
    rules = engine(("Go", "activate Fast when battery.percentage > 50 and dock.data == false"))
    assert rules.on_message("battery", battery(80), 0.0) == []
    (firing,) = rules.on_message("dock", SimpleNamespace(data=False), 0.1)
    assert firing.activate == ("Fast",)


def test_contradicting_firings_resolve_in_file_order() -> None:
    first = Firing("A", ("Outdoor",), (), "a", 0)
    second = Firing("B", ("Indoor",), (), "b", 1)
    unrelated = Firing("C", ("Night",), (), "c", 2)
    relations = {
        "Indoor": (frozenset({"location"}), frozenset()),
        "Outdoor": (frozenset({"location"}), frozenset()),
    }
    kept, overridden = resolve([second, unrelated, first], relations)
    assert kept == [first, unrelated] and overridden == [second]
    off = Firing("D", (), ("Outdoor",), "d", 3)
    assert resolve([off, first], {})[1] == [off]


def test_python_api_errors_point_into_the_rule_text() -> None:
    with pytest.raises(LayerSyntaxError) as caught:
        RuleSet.from_rules([Rule("Low", "LowBattery while battery.percentage < low")])
    assert "<rules>:1:" in str(caught.value) and "'low' is not a field" in str(caught.value)


def test_a_byte_field_compares_as_its_number() -> None:
    # rclpy hands a ROS byte (IDL octet, std_msgs/Byte.data) over as bytes of length 1.
    rules = engine(("Level", "High while level.data >= 2"))
    (low,) = rules.on_message("level", SimpleNamespace(data=b"\x01"), 0.0)
    assert low.deactivate == ("High",)
    (high,) = rules.on_message("level", SimpleNamespace(data=b"\x05"), 1.0)
    assert high.activate == ("High",)
    assert rules.failures == []


def test_a_rule_whose_evaluation_raises_is_turned_off_and_the_others_run() -> None:
    rules = engine(
        ("Broken", "Night while battery.percentage < 20"),
        ("Fine", "Present while battery.present"),
    )
    # A message unlike its type's promise (a string where a number was checked).
    weird = SimpleNamespace(percentage="low", present=True)
    (firing,) = rules.on_message("battery", weird, 0.0)
    assert firing.rule == "Fine"
    (failure,) = rules.failures
    assert failure.rule.name == "Broken"
    assert str(failure).startswith("rule Broken (<rules>:1) is off: evaluating it failed: ")
    assert "TypeError" in str(failure)
    rules.failures.clear()
    assert rules.on_message("battery", battery(10), 1.0) == [], "the broken rule stays off"
    assert rules.failures == [], "reported once"


def test_a_report_shows_value_hold_timer_readings_and_hysteresis() -> None:
    rules = engine(("Battery", "LowBattery while battery.percentage < 20 for 2 s hysteresis 5"))
    (report,) = rules.report(0.0)
    assert (report.value, report.value_text, report.settled) == (None, "no data", None)
    assert report.readings == (("battery.percentage", "no message yet"),)

    rules.on_message("battery", battery(50.0), 0.0)
    rules.tick(2.5)  # false settles after its hold time
    rules.on_message("battery", battery(18.0), 3.0)
    (report,) = rules.report(3.5)
    assert (report.value, report.settled, report.holding) == (True, False, True)
    assert report.hold_left == pytest.approx(1.5)
    assert not report.relaxed
    assert report.readings == (("battery.percentage", "18.0"),)

    assert [f.activate for f in rules.tick(5.0)] == [("LowBattery",)]
    rules.on_message("battery", battery(22.0), 5.1)  # above 20, below 20 + 5: still true
    (report,) = rules.report(5.2)
    assert (report.value, report.settled, report.holding, report.relaxed) == (
        True,
        True,
        False,
        True,
    )
    assert (report.hold, report.hysteresis, report.error) == (2.0, 5.0, None)


def test_a_report_names_why_a_rule_is_off() -> None:
    rules = engine(("Battery", "LowBattery while battery.percentage < 20"))
    rules.on_message("battery", SimpleNamespace(), 0.0)  # a message without the field
    (report,) = rules.report(0.1)
    assert report.value_text == "off"
    assert report.error is not None and "percentage" in report.error
    assert report.readings[0][1] == "unreadable (AttributeError)"


def test_a_long_condition_is_cut_to_a_reason_the_manager_takes_keeping_its_place() -> None:
    """A command's reason is at most 1024 characters (protocol/validation.py): a rule with
    a longer condition used to fire commands the manager refused, every time."""
    from contextros.protocol import ActivationCommand
    from contextros.protocol.validation import MAX_TEXT_LENGTH, command_problems

    condition = " or ".join(f"battery.percentage < {n}" for n in range(60))
    rules = engine(("Low", f"LowBattery while {condition}"))
    (firing,) = [f for f in rules.on_message("battery", battery(10), 0.0)]
    assert len(firing.reason) <= MAX_TEXT_LENGTH < len(condition)
    assert firing.reason.endswith("... (<rules>:1)"), firing.reason[-40:]
    command = ActivationCommand(-1, firing.activate, reason=firing.reason, synchronous=True)
    assert command_problems(command) == []
