"""The offline replay: the manager's rule handling over recorded messages, without ROS."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from contextros.protocol.relations import LayerDeclaration
from contextros.rules import Rule, RuleSet
from contextros.rules.replay import RuleReplay


def value(x: float) -> SimpleNamespace:
    return SimpleNamespace(data=x)


def switches(replay: RuleReplay) -> list[tuple[float, tuple[str, ...], str]]:
    return [(round(s.time, 3), s.active, s.requester) for s in replay.result.switches]


def test_a_hold_time_ends_at_the_managers_next_tick() -> None:
    rules = RuleSet.from_rules([Rule("Hot", "Hot while temperature.data > 40 for 0.12 s")])
    replay = RuleReplay(rules, start=10.0)
    replay.message(10.0, "temperature", value(50.0))
    replay.finish(11.0)
    # Held from 10.0 s; 0.12 s pass at 10.12 s, the timer ticks every 0.05 s from 10.0 s.
    assert switches(replay) == [(10.15, ("Hot",), "rule Hot")]
    ((rule, begin, end),) = replay.result.holds
    assert (rule, begin, end) == ("Hot", pytest.approx(10.03), pytest.approx(10.15))
    assert replay.result.signals == {"temperature.data": [(10.0, 50.0)]}


def test_a_refused_firing_is_tried_again_after_the_next_state() -> None:
    rules = RuleSet.from_rules(
        [Rule("Load", "Slow while load.data > 10"), Rule("Speed", "Fast while speed.data > 5")]
    )
    declarations = [
        LayerDeclaration("Slow", excludes=frozenset({"Fast"})),
        LayerDeclaration("Fast"),
    ]
    replay = RuleReplay(rules, declarations, start=0.0)
    replay.message(0.0, "load", value(20.0))
    replay.message(0.2, "speed", value(8.0))  # Fast excluded by Slow: refused
    assert [(r.rule, r.asked) for r in replay.result.refusals] == [("Speed", "activate Fast")]
    assert "excludes" in replay.result.refusals[0].message
    replay.message(0.4, "load", value(0.0))  # Slow off: a new state, Fast tried again
    replay.finish(1.0)
    assert switches(replay) == [
        (0.0, ("Slow",), "rule Load"),
        (0.4, (), "rule Load"),
        (0.45, ("Fast",), "rule Speed"),  # at the manager's next tick
    ]


def test_a_manual_command_in_the_recording_stands_and_drops_refused_firings() -> None:
    rules = RuleSet.from_rules(
        [Rule("Load", "Slow while load.data > 10"), Rule("Speed", "Fast while speed.data > 5")]
    )
    declarations = [
        LayerDeclaration("Slow", excludes=frozenset({"Fast"})),
        LayerDeclaration("Fast"),
    ]
    replay = RuleReplay(rules, declarations, start=0.0, active=("Night",))
    replay.message(0.0, "load", value(20.0))
    replay.message(0.1, "speed", value(8.0))  # refused
    replay.manual(0.2, ("Night", "Slow"), "operator", "keep it slow")  # no change: stands
    replay.manual(0.3, ("Slow",), "operator", "day")
    replay.message(0.4, "load", value(0.0))  # Slow off by its rule; the refused Fast is gone
    replay.finish(1.0)
    assert switches(replay) == [
        (0.0, ("Night",), "recording"),
        (0.0, ("Night", "Slow"), "rule Load"),
        (0.3, ("Slow",), "operator"),
        (0.4, (), "rule Load"),
    ]
    assert any("refused firing is dropped" in note for note in replay.result.notes)


def test_an_exclusive_group_choice_replaces_the_other_member() -> None:
    rules = RuleSet.from_rules([Rule("Gps", "Outdoor while gps.data >= 0 else Indoor")])
    declarations = [
        LayerDeclaration("Indoor", group="location"),
        LayerDeclaration("Outdoor", group="location"),
    ]
    replay = RuleReplay(rules, declarations, start=0.0, active=("Indoor",))
    replay.message(0.5, "gps", value(0.0))
    replay.message(1.5, "gps", value(-1.0))
    replay.finish(2.0)
    assert switches(replay)[1:] == [(0.5, ("Outdoor",), "rule Gps"), (1.5, ("Indoor",), "rule Gps")]
