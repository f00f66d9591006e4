"""Rules on the ROS graph's state (`lifecycle NODE`, `param NODE.PARAMETER`), without ROS:
their syntax and errors, the engine fed their values, contradictions, untrusted events."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from contextros.language.diagnostics import LayerSyntaxError
from contextros.language.rules import GraphRef, condition_text
from contextros.rules import Rule, RuleEngine, RuleSet
from contextros.rules.graph import (
    MAX_STRING,
    GraphInput,
    GraphInputs,
    answers_each_event,
    graph_topics,
    resolve_name,
)


def ruleset(*rules: tuple[str, str]) -> RuleSet:
    return RuleSet.from_rules([Rule(name, text) for name, text in rules])


def error(text: str) -> str:
    with pytest.raises(LayerSyntaxError) as raised:
        ruleset(("R", text))
    return str(raised.value)


# -- syntax ---------------------------------------------------------------------------------


def test_a_lifecycle_condition_and_a_parameter_condition_parse_with_their_nodes() -> None:
    rules = ruleset(
        ("Degraded", "SafeMode while lifecycle drivers/propeller != active"),
        ("Slow", "Careful while param controller.gains.kp < 0.5 for 1 s hysteresis 0.1"),
    )
    degraded, slow = rules.rules
    assert degraded.graph == [GraphRef("lifecycle", "drivers/propeller", "", degraded.graph[0].at)]
    assert degraded.fields == [] and rules.topics() == ()
    assert condition_text(degraded.condition) == "lifecycle drivers/propeller != active"
    (ref,) = slow.graph
    assert (ref.node, ref.parameter, ref.text) == (
        "controller",
        "gains.kp",
        "param controller.gains.kp",
    )
    assert (slow.hold, slow.hysteresis) == (1.0, 0.1)
    assert graph_topics(rules.rules) == ("/parameter_events", "drivers/propeller/transition_event")


@pytest.mark.parametrize(
    ("text", "col", "message"),
    [
        (
            "SafeMode while lifecycle drivers/propeller != activ",
            55,
            "unknown lifecycle state 'activ' (did you mean active?): the states are "
            "unconfigured, inactive, active, finalized; during a transition configuring,",
        ),
        ("SafeMode while lifecycle drivers/propeller < active", 52, "compared with == or != only"),
        ("SafeMode while lifecycle drivers/propeller", 24, "compare the lifecycle state with a"),
        ("SafeMode while lifecycle a == 3", 39, "a lifecycle state is compared with a state"),
        ("SafeMode while lifecycle a.b == active", 34, "'a.b' is not a node name"),
        ("SafeMode while lifecycle == active", 34, "expected the node after 'lifecycle'"),
        ("SafeMode while param max_speed < 0.5", 30, "'param max_speed' names no node"),
        ("SafeMode while param ~/x.y < 0.5", 30, "'~/x.y': a node is named by its namespace"),
        ("SafeMode while active == lifecycle a", 24, "'active' is not a field"),
    ],
)
def test_graph_conditions_with_errors_name_file_line_and_column(
    text: str, col: int, message: str
) -> None:
    found = error(text)
    assert found.startswith(f"<rules>:1:{col}: error: "), found
    assert message in found, found
    assert "^" in found  # the line quoted, a caret under the fault


def test_a_lifecycle_state_may_be_quoted_and_compared_with_another_nodes() -> None:
    rules = ruleset(("R", "L while lifecycle a == 'inactive' or lifecycle a != lifecycle b"))
    assert [ref.text for ref in rules.rules[0].graph] == [
        "lifecycle a",
        "lifecycle a",
        "lifecycle b",
    ]


def test_layer_files_take_graph_conditions_in_both_flavours(tmp_path) -> None:
    python = tmp_path / "robot.layers"
    python.write_text("rule Degraded: SafeMode while lifecycle drivers/propeller != active\n")
    cpp = tmp_path / "robot.cpp.layers"
    cpp.write_text("rule Degraded: SafeMode while lifecycle drivers/propeller != active;\n")
    for path in (python, cpp):
        (rule,) = RuleSet.from_files([path]).rules
        assert [ref.text for ref in rule.graph] == ["lifecycle drivers/propeller"]
    bad = tmp_path / "bad.layers"
    bad.write_text("\nrule Degraded: SafeMode while lifecycle drivers/propeller != activ\n")
    with pytest.raises(LayerSyntaxError) as raised:
        RuleSet.from_files([bad])
    assert f"{bad}:2:62: error: unknown lifecycle state 'activ'" in str(raised.value)


# -- the engine -----------------------------------------------------------------------------


def test_a_lifecycle_rule_holds_its_hold_time_like_a_topic_rule() -> None:
    engine = RuleEngine(
        ruleset(("D", "SafeMode while lifecycle drivers/propeller != active for 1 s"))
    )
    source = "lifecycle drivers/propeller"
    assert engine.on_value(source, "active", 0.0) == []
    assert engine.tick(1.0)[0].deactivate == ("SafeMode",)  # the first settled value acts
    assert engine.on_value(source, "inactive", 2.0) == []
    assert engine.on_value(source, "active", 2.5) == [], "a short dip restarts the wait"
    assert engine.tick(4.0) == []
    engine.on_value(source, "inactive", 5.0)
    (firing,) = engine.tick(6.0)
    assert firing.activate == ("SafeMode",)
    assert firing.reason == "lifecycle drivers/propeller != active for 1 s (<rules>:1)"


def test_a_parameter_rule_uses_hysteresis_like_a_topic_rule() -> None:
    engine = RuleEngine(
        ruleset(("S", "Careful while param controller.max_speed < 0.5 hysteresis 0.2"))
    )
    source = "param controller.max_speed"
    values = [1.0, 0.4, 0.6, 0.69, 0.7]
    fired = [(v, f) for v in values for f in engine.on_value(source, v, 0.0)]
    assert [(v, f.activate, f.deactivate) for v, f in fired] == [
        (1.0, (), ("Careful",)),
        (0.4, ("Careful",), ()),
        (0.7, (), ("Careful",)),  # held until 0.5 + 0.2
    ]


def test_no_value_is_an_unknown_condition_that_keeps_the_value_in_force() -> None:
    engine = RuleEngine(ruleset(("D", "SafeMode while lifecycle p != active for 1 s")))
    (report,) = engine.report(0.0)
    assert report.value is None and report.readings == (("lifecycle p", "no value"),)
    engine.on_value("lifecycle p", "active", 0.0)
    engine.tick(1.0)
    engine.on_value("lifecycle p", "inactive", 2.0)
    assert engine.on_value("lifecycle p", None, 2.5) == []  # the node left the graph
    assert engine.tick(10.0) == [], "the change it waited for is dropped"
    (report,) = engine.report(10.0)
    assert (report.value, report.settled, report.holding) == (None, False, False)


def test_a_rule_reading_a_topic_and_a_parameter_waits_for_both() -> None:
    engine = RuleEngine(ruleset(("B", "L while battery.percentage < param c.low")))
    assert engine.on_message("battery", SimpleNamespace(percentage=10.0), 0.0) == []
    (firing,) = engine.on_value("param c.low", 20.0, 0.1)
    assert firing.activate == ("L",)


# -- contradictions -------------------------------------------------------------------------


def test_contradictions_on_lifecycle_states_and_parameters() -> None:
    exclusive = ruleset(
        ("On", "L while lifecycle p == active"),
        ("Off", "deactivate L when lifecycle p == inactive"),
        ("Fast", "activate M when param c.speed > 1"),
        ("Slow", "deactivate M when param c.speed <= 1"),
    )
    assert exclusive.check() == []
    clashing = ruleset(
        ("On", "L while lifecycle p != inactive"),
        ("Off", "deactivate L when lifecycle p != active"),
        ("Fast", "activate M when param c.speed > 1"),
        ("Slow", "deactivate M when param c.speed < 2"),
    )
    found = [d.message for d in clashing.check()]
    assert len(found) == 2, found
    assert found[0].startswith("rules On (<rules>:1) and Off may hold at the same time and one")
    assert found[1].startswith("rules Fast (<rules>:3) and Slow may hold at the same time")


def test_a_parameters_hysteresis_counts_in_contradictions() -> None:
    rules = ruleset(
        ("Low", "Careful while param c.speed < 0.5 hysteresis 0.2"),
        ("Up", "deactivate Careful when param c.speed >= 0.6"),
    )
    (warning,) = rules.check()
    assert "Low's hysteresis 0.2 keeps it holding past its threshold" in warning.message


# -- the values from messages (untrusted) ---------------------------------------------------


def parameter(name: str, kind: int, **value: object) -> SimpleNamespace:
    fields = {"bool_value": False, "integer_value": 0, "double_value": 0.0, "string_value": ""}
    return SimpleNamespace(name=name, value=SimpleNamespace(type=kind, **{**fields, **value}))


def event(node: str, new=(), changed=(), deleted=()) -> SimpleNamespace:
    return SimpleNamespace(
        node=node,
        new_parameters=list(new),
        changed_parameters=list(changed),
        deleted_parameters=list(deleted),
    )


def inputs(*rules: tuple[str, str], namespace: str = "/robot") -> GraphInputs:
    return GraphInputs(ruleset(*rules).rules, lambda name: resolve_name(namespace, name))


def test_parameter_events_give_the_named_parameters_of_the_named_node_only() -> None:
    graph = inputs(("S", "Careful while param controller.max_speed < 0.5"))
    assert graph.channels() == ("/parameter_events", "/robot/controller/get_parameters")
    speed = parameter("max_speed", 3, double_value=0.3)
    assert graph.read("/parameter_events", event("/controller", changed=[speed])) == []
    assert graph.read("/parameter_events", event("/robot/controller", new=[speed])) == [
        GraphInput("param controller.max_speed", 0.3)
    ]
    other = parameter("min_speed", 3, double_value=0.1)
    assert graph.read("/parameter_events", event("/robot/controller", changed=[other])) == []
    assert graph.read("/parameter_events", event("/robot/controller", deleted=[speed])) == [
        GraphInput("param controller.max_speed", None)
    ]
    assert graph.read("/robot/other", event("/robot/controller", new=[speed])) is None


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        (parameter("max_speed", 4, string_value="fast"), "is a string ('fast'), rule S compares"),
        (parameter("max_speed", 8), "is a double array (rules compare plain values)"),
        (parameter("max_speed", 4, string_value="x" * (MAX_STRING + 1)), "a string of 4097"),
        (parameter("max_speed", 3, double_value="0.3"), "malformed (type 3 with a str value)"),
        (parameter("max_speed", 2, integer_value=True), "malformed (type 2 with a bool value)"),
        (parameter("max_speed", 77), "of an unknown parameter type 77"),
        (parameter("max_speed", 0), "is not set (does the node declare it?)"),
    ],
)
def test_a_parameter_value_the_rules_cannot_compare_is_no_value_with_a_problem(
    value: SimpleNamespace, problem: str
) -> None:
    graph = inputs(("S", "Careful while param controller.max_speed < 0.5"))
    found = graph.read("/parameter_events", event("/robot/controller", changed=[value]))
    assert found == [GraphInput("param controller.max_speed", None)]
    (logged,) = graph.problems
    assert problem in logged, logged
    graph.read("/parameter_events", event("/robot/controller", changed=[value]))
    assert len(graph.problems) == 1, "each problem is logged once"


def test_malformed_parameter_events_are_ignored() -> None:
    graph = inputs(("S", "Careful while param controller.max_speed < 0.5"))
    assert graph.read("/parameter_events", SimpleNamespace(node=3)) == []
    assert graph.read("/parameter_events", SimpleNamespace(node="/robot/controller")) == []
    nameless = SimpleNamespace(name=None, value=None)
    assert graph.read("/parameter_events", event("/robot/controller", new=[nameless])) == []


def test_transition_events_give_the_goal_state_and_unknown_is_no_value() -> None:
    graph = inputs(("D", "SafeMode while lifecycle drivers/propeller != active"))
    assert graph.channels() == (
        "/robot/drivers/propeller/transition_event",
        "/robot/drivers/propeller/get_state",
    )

    def transition(state_id: object) -> list[GraphInput] | None:
        goal = SimpleNamespace(goal_state=SimpleNamespace(id=state_id, label="ignored"))
        return graph.read("/robot/drivers/propeller/transition_event", goal)

    assert transition(14) == [GraphInput("lifecycle drivers/propeller", "deactivating")]
    assert transition(2) == [GraphInput("lifecycle drivers/propeller", "inactive")]
    assert transition(0) == [GraphInput("lifecycle drivers/propeller", None)]
    assert graph.problems == []
    assert transition(99) == [GraphInput("lifecycle drivers/propeller", None)]
    assert graph.problems == ["/robot/drivers/propeller reported an unknown lifecycle state id 99"]
    assert graph.absent("/robot/drivers/propeller") == [
        GraphInput("lifecycle drivers/propeller", None)
    ]


# -- the replay -----------------------------------------------------------------------------


def test_the_replay_reads_recorded_answers_and_events_as_the_manager_does() -> None:
    from contextros.rules.replay import RuleReplay

    rules = ruleset(("D", "SafeMode while lifecycle drivers/propeller != active for 0.1 s"))
    replay = RuleReplay(rules, start=0.0, namespace="/robot")

    def goal(state_id: int) -> SimpleNamespace:
        return SimpleNamespace(goal_state=SimpleNamespace(id=state_id))

    # The node's answer when it appeared (unconfigured), then its transitions.
    assert replay.graph_message(0.0, "/robot/drivers/propeller/get_state", goal(1))
    assert replay.graph_message(1.0, "/robot/drivers/propeller/transition_event", goal(3))
    assert replay.graph_message(2.0, "/robot/drivers/propeller/transition_event", goal(14))
    assert not replay.graph_message(2.5, "/drivers/propeller/transition_event", goal(3))
    replay.finish(3.0)
    assert [(round(s.time, 2), s.active, s.requester) for s in replay.result.switches] == [
        (0.1, ("SafeMode",), "rule D"),
        (1.1, (), "rule D"),
        (2.1, ("SafeMode",), "rule D"),
    ]
    assert replay.result.first_inputs == {"lifecycle drivers/propeller": 0.0}


def test_the_replay_plots_a_parameter_and_notes_a_value_it_cannot_compare() -> None:
    from contextros.rules.replay import RuleReplay

    rules = ruleset(("S", "Careful while param controller.max_speed < 0.5"))
    replay = RuleReplay(rules, start=0.0)
    speed = parameter("max_speed", 3, double_value=0.3)
    replay.graph_message(0.0, "/controller/get_parameters", event("/controller", new=[speed]))
    text = parameter("max_speed", 4, string_value="fast")
    replay.graph_message(1.0, "/parameter_events", event("/controller", changed=[text]))
    replay.finish(2.0)
    assert [s.active for s in replay.result.switches] == [("Careful",)]
    assert replay.result.signals == {"param controller.max_speed": [(0.0, 0.3)]}
    assert any("is a string ('fast')" in note for note in replay.result.notes)


GRAPH_LAYERS = """\
layer SafeMode:
    def speed() -> float:
        return 0.1
layer Cruise:
    def speed() -> float:
        return 1.0
group mode: SafeMode, Cruise
rule Degraded: SafeMode while lifecycle drivers/propeller != active
rule Fine: Cruise while lifecycle drivers/propeller == active
rule Odd: Cruise while lifecycle drivers/propeller == inactive
"""


def test_contextros_check_reports_graph_rule_errors_and_contradictions(tmp_path) -> None:
    import subprocess
    import sys

    good = tmp_path / "robot.layers"
    good.write_text(GRAPH_LAYERS, encoding="utf-8")
    done = subprocess.run(
        [sys.executable, "-m", "contextros", "check", str(good)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    warnings = [line for line in done.stdout.splitlines() if ": warning: " in line]
    # Degraded and Fine are exclusive (!= active, == active); Odd overlaps both.
    assert len(warnings) == 2, done.stdout
    assert warnings[0].startswith(f"{good}:10:6: warning: rules Degraded (robot.layers:8) and Odd")
    assert "both of exclusive group 'mode'" in warnings[0]
    assert warnings[1].startswith(f"{good}:10:6: warning: rules Fine (robot.layers:9) and Odd")
    bad = tmp_path / "bad.layers"
    bad.write_text(
        GRAPH_LAYERS.replace("!= active", "!= activ")
        + "rule Speed: SafeMode while param max_speed < 0.5\n",
        encoding="utf-8",
    )
    done = subprocess.run(
        [sys.executable, "-m", "contextros", "check", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 1
    assert (
        f"{bad}:8:62: error: unknown lifecycle state 'activ' (did you mean active?)" in done.stdout
    )
    assert f"{bad}:11:34: error: 'param max_speed' names no node" in done.stdout


def test_the_live_manager_reads_answers_only_and_knows_stamped_ones() -> None:
    """The manager takes values from the nodes' answers (events are hints it reads the
    node on); a recorded answer stamped with its read's time says the recording has them."""
    graph = GraphInputs(
        ruleset(("S", "Careful while param controller.max_speed < 0.5")).rules,
        lambda name: resolve_name("/robot", name),
        events=False,
    )
    assert graph.channels() == ("/robot/controller/get_parameters",)
    speed = parameter("max_speed", 3, double_value=0.3)
    assert graph.read("/parameter_events", event("/robot/controller", new=[speed])) is None
    answer = event("/robot/controller", new=[speed])
    assert not answers_each_event("/robot/controller/get_parameters", answer)
    answer.stamp = SimpleNamespace(sec=1795759629, nanosec=0)
    assert answers_each_event("/robot/controller/get_parameters", answer)
    state = SimpleNamespace(goal_state=SimpleNamespace(id=3), timestamp=0)
    assert not answers_each_event("/robot/propeller/get_state", state)
    state.timestamp = 1795759629000000000
    assert answers_each_event("/robot/propeller/get_state", state)
    assert not answers_each_event("/robot/propeller/transition_event", state)


def graph_recording(path: Path, stamped: bool) -> Path:
    """An answer of /controller (max_speed 1.0) at 100 s, an event saying 0.3 at 101 s and
    an answer saying 0.3 at 102 s, by a recorder that stamps its answers or not."""
    from mcap_ros2.writer import Writer

    from contextros.recording.definitions import message_definition

    kind = "rcl_interfaces/msg/ParameterEvent"
    with path.open("wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef(kind, message_definition(kind))
        for second, topic, value in [
            (100, "/controller/get_parameters", 1.0),
            (101, "/parameter_events", 0.3),
            (102, "/controller/get_parameters", 0.3),
        ]:
            answer = topic.endswith("get_parameters")
            message = {
                "stamp": {"sec": second if stamped and answer else 0, "nanosec": 0},
                "node": "/controller",
                "new_parameters" if answer else "changed_parameters": [
                    {"name": "max_speed", "value": {"type": 3, "double_value": value}}
                ],
            }
            writer.write_message(topic, schema, message, log_time=second * 10**9)
        writer.finish()
    return path


@pytest.mark.parametrize(("stamped", "switched_at"), [(False, 1.0), (True, 2.0)])
def test_the_replay_takes_events_as_values_only_in_recordings_without_stamped_answers(
    tmp_path: Path, stamped: bool, switched_at: float
) -> None:
    """A recording made before the manager read nodes after each event (or by another
    tool) replays as then: its events are values. One with stamped answers replays as the
    manager runs now: the event is a hint, the answer after it the value."""
    import json

    pytest.importorskip("mcap_ros2")
    from tests.recording.test_reader import replay

    recording = graph_recording(tmp_path / "graph.mcap", stamped)
    rules = tmp_path / "robot.layers"
    rules.write_text("rule S: Careful while param controller.max_speed < 0.5\n", encoding="utf-8")
    done = replay(recording, rules, "--json")
    assert done.returncode == 0, done.stderr
    switches = json.loads(done.stdout)["switches"]
    assert [(s["time"], s["active"]) for s in switches] == [(switched_at, ["Careful"])]
