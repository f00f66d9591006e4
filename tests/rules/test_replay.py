"""The offline replay: the manager's rule handling over recorded messages, without ROS."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from contextros.protocol.relations import LayerDeclaration
from contextros.rules import Rule, RuleSet
from contextros.rules.replay import RecordedState, RuleReplay, compare


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


def test_the_replay_composes_as_the_manager_given_the_same_layer_files() -> None:
    """Issue 25: the layer file says `layer LowBattery after Road, Grass`, the nodes declare
    LowBattery without `after`. The manager given the file and the replay given the same
    file compose [Road, LowBattery] from [LowBattery] + Road."""
    from contextros.protocol import ActivationCommand, ManagerProtocol, ManagerSettings
    from contextros.protocol.events import ParticipantReport, PublishState

    layer_files = [LayerDeclaration("LowBattery", after=frozenset({"Road", "Grass"}))]
    nodes = (LayerDeclaration("LowBattery"), LayerDeclaration("Road"), LayerDeclaration("Grass"))
    settings = ManagerSettings(recovery_window=0.0, layer_files=tuple(layer_files))
    manager = ManagerProtocol(0.0, settings)
    manager.receive_status(ParticipantReport(node="/nodes", incarnation="1", layers=nodes), 0.0)
    manager.tick(1.0)
    live = []
    for request, layer in enumerate(["LowBattery", "Road"], start=1):
        actions = manager.receive_command(ActivationCommand(request, (layer,), ()), 1.0)
        live += [a.state.active for a in actions if isinstance(a, PublishState)]
    assert live == [("LowBattery",), ("Road", "LowBattery")]

    replay = RuleReplay(RuleSet.from_rules([]), nodes, layer_files=layer_files, start=0.0)
    replay.manual(1.0, ("LowBattery",), "operator", "")
    replay.manual(2.0, ("LowBattery", "Road"), "operator", "")  # as recorded before the fix
    assert [s.active for s in replay.result.switches] == live


def state(time: float, *active: str, requester: str = "rule Hot") -> RecordedState:
    return RecordedState(time, 0, active, requester)


def test_every_difference_from_the_recorded_states_is_reported() -> None:
    rules = RuleSet.from_rules(
        [Rule("Hot", "Hot while temperature.data > 40"), Rule("Wet", "Wet while rain.data > 0")]
    )
    replay = RuleReplay(rules, start=0.0)
    replay.message(1.0, "temperature", value(50.0))  # [Hot] at 1.0
    replay.message(2.0, "rain", value(1.0))  # [Hot, Wet] at 2.0
    replay.message(3.0, "temperature", value(0.0))  # [Wet] at 3.0
    replay.message(4.0, "rain", value(0.0))  # [] at 4.0
    result = replay.finish(5.0)
    agreeing = [
        state(1.1, "Hot"),
        state(2.0, "Hot", "Wet", requester="rule Wet"),
        state(3.0, "Wet"),
        state(4.0, requester="rule Wet"),
    ]
    assert compare(result, agreeing, rules, start=0.0) == []
    recorded = [
        state(1.5, "Hot"),  # 0.5 s later than the replay
        state(2.0, "Wet", "Hot", requester="rule Wet"),  # another order
        state(3.0, "Night", requester="operator"),  # other layers
        state(4.0, requester="rule Wet"),
        state(4.5, "Hot"),  # not in the replay
    ]
    found = compare(result, recorded, rules, start=0.0)
    assert [(d.kind, round(d.time, 3)) for d in found] == [
        ("time", 1.5),
        ("order", 2.0),
        ("layers", 3.0),
        ("missing", 4.5),
    ]
    assert (
        found[0].text
        == "[Hot] live at 1.500 s (rule Hot), in the replay 0.500 s earlier (tolerance 0.25 s)"
    )
    assert found[1].text == "live composed [Wet, Hot] at 2.000 s (rule Wet), the replay [Hot, Wet]"
    wider = compare(result, recorded, rules, start=0.0, tolerance=0.6)
    assert [d.kind for d in wider] == ["order", "layers", "missing"]
    extra = compare(result, agreeing[:3], rules, start=0.0)
    assert [(d.kind, d.text) for d in extra] == [
        ("extra", "replay [none] at 4.000 s (rule Wet): not in the recording")
    ]


def test_a_switch_made_on_readings_the_recording_lacks_is_late_but_no_difference() -> None:
    rules = RuleSet.from_rules([Rule("Hot", "Hot while temperature.data > 40 for 1 s")])
    replay = RuleReplay(rules, start=0.0)
    replay.message(0.5, "temperature", value(50.0))  # the first recorded reading
    result = replay.finish(3.0)
    # Live, the manager had readings from before the recording: it switched at 0.8 s.
    assert compare(result, [state(0.8, "Hot")], rules, start=0.0) == []
    assert any("no reading of temperature from before 0.500 s" in n for n in result.notes)
    # Once the recorded readings could have caused it, a time apart is a difference again.
    assert [d.kind for d in compare(result, [state(1.9, "Hot")], rules, start=0.0)] == ["time"]


def test_the_command_line_default_tolerance_is_the_replays() -> None:
    from contextros.cli import observe_commands
    from contextros.rules import replay

    assert observe_commands.TIME_TOLERANCE == replay.TIME_TOLERANCE
