"""Context rules in a real manager process: topics from a publisher, ordinary activations
with the rule as their reason, manual commands beside them, field errors before messages."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from rclpy.node import Node
from sensor_msgs.msg import BatteryState, NavSatFix

from contextros.ros import LayerClient
from tests.ros.processes import Child, ProcessGroup
from tests.ros.system import LIVENESS, wait_registry
from tests.ros.test_cli import contextros
from tests.ros.test_topic_declarations import heads, manager_line

RULES = """\
# The robot's rules
rule Battery: Night while battery.percentage < 20 for 0.2 s hysteresis 5
rule Place: Outdoor while gps.status.status >= 0 else Indoor
"""


class Sensors:
    """Publishers of the topics the rules read, in the test process (namespace `ns`)."""

    def __init__(self, client: LayerClient, namespace: str = "/") -> None:
        self.node = Node("fake_sensors", namespace=namespace)
        self.client = client
        self.battery = self.node.create_publisher(BatteryState, "battery", 10)
        self.gps = self.node.create_publisher(NavSatFix, "gps", 10)

    def publish(self, percentage: float | None = None, fix: int | None = None) -> None:
        if percentage is not None:
            self.battery.publish(BatteryState(percentage=percentage))
        if fix is not None:
            message = NavSatFix()
            message.status.status = fix
            self.gps.publish(message)

    def keep_publishing(
        self, until: Callable[[], bool], timeout: float = 10.0, what: str = "", **values: float
    ) -> None:
        """Publish every 50 ms until `until()` (the rules need their topics discovered)."""
        deadline = time.monotonic() + timeout
        while not until():
            assert time.monotonic() < deadline, f"timed out: {what}"
            self.publish(**values)  # type: ignore[arg-type]
            time.sleep(0.05)


@pytest.fixture(scope="module")
def rules(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The rules' file; the manager is given its full path, and its log names it so."""
    path = tmp_path_factory.mktemp("rules") / "robot.layers"
    path.write_text(RULES, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def system(client: LayerClient, rules: Path) -> Iterator[Child]:
    group = ProcessGroup()
    try:
        participant = group.participant("r1")
        manager = group.manager("--liveness-timeout", LIVENESS, "--rules", str(rules))
        participant.wait_for(lambda events: any(e["event"] == "ready" for e in events), 15)
        client.wait_for_manager(15.0)
        wait_registry(client, lambda r: any(p.node == "/r1" for p in r.participants))
        yield manager
    finally:
        group.kill_all()


@pytest.fixture(scope="module")
def sensors(client: LayerClient, system: Child) -> Iterator[Sensors]:
    sensors = Sensors(client)
    try:
        yield sensors
    finally:
        sensors.node.destroy_node()


def active(client: LayerClient) -> list[str]:
    return list(client.query().active_layers)


def test_a_rule_activates_its_layer_with_itself_as_the_reason(
    client: LayerClient, sensors: Sensors, system: Child, rules: Path
) -> None:
    sensors.keep_publishing(
        lambda: "Indoor" in active(client), fix=-1, percentage=50.0, what="Indoor from no GPS fix"
    )
    sensors.keep_publishing(
        lambda: "Night" in active(client), percentage=10.0, what="Night from a low battery"
    )
    registry = client.query()
    assert registry.requester == "rule Battery"
    assert registry.reason == "battery.percentage < 20 for 0.2 s (robot.layers:2)"
    shown = contextros("status")
    assert "(rule Battery: battery.percentage < 20 for 0.2 s (robot.layers:2))" in shown.stdout
    system.wait_for(
        lambda _: any(f"rule Battery ({rules}:2): Night while" in line for line in system.lines),
        5,
        "the manager's log of the rule, naming its file as given",
    )
    system.wait_for(
        lambda _: any(
            "rule Battery switched to Night: 1 node(s) applied it" in line for line in system.lines
        ),
        5,
        "the manager's log of the rule's activation",
    )


def test_status_shows_each_rule_s_value_hold_timer_hysteresis_and_last_firing(
    client: LayerClient, sensors: Sensors
) -> None:
    sensors.keep_publishing(lambda: "Night" in active(client), percentage=10.0, fix=-1)
    sensors.publish(percentage=23.0)  # above 20, within the hysteresis: still low

    def battery_rule() -> dict[str, object]:
        shown = contextros("status", "--json")
        assert shown.returncode == 0, shown.stderr
        shown_rules = {rule["name"]: rule for rule in json.loads(shown.stdout)["rules"]}
        assert set(shown_rules) == {"Battery", "Place"}
        return shown_rules["Battery"]

    deadline = time.monotonic() + 10
    while (rule := battery_rule())["readings"] != ["battery.percentage = 23.0"]:
        assert time.monotonic() < deadline, rule
        sensors.publish(percentage=23.0)
    assert rule["where"] == "robot.layers:2"
    assert (rule["value"], rule["settled"], rule["relaxed"], rule["hysteresis"]) == (
        "true",
        "true",
        True,
        5.0,
    )
    assert rule["last_firing"] == "activate Night"
    assert rule["last_outcome"].startswith("epoch "), rule
    text = contextros("status").stdout
    assert "Battery: Night while battery.percentage < 20 for 0.2 s hysteresis 5" in text
    assert "hysteresis 5 engaged" in text
    assert "Place: Outdoor while gps.status.status >= 0 else Indoor" in text


def test_hysteresis_and_a_group_choice(client: LayerClient, sensors: Sensors) -> None:
    sensors.keep_publishing(lambda: "Night" in active(client), percentage=10.0)
    for _ in range(10):  # above 20 but below 20 + 5: still low
        sensors.publish(percentage=23.0)
        time.sleep(0.05)
    assert "Night" in active(client)
    sensors.keep_publishing(lambda: "Night" not in active(client), percentage=26.0)
    sensors.keep_publishing(lambda: active(client)[-1:] == ["Outdoor"], fix=0)
    assert "Indoor" not in active(client), "the else branch's group member was replaced"


def test_a_manual_command_stands_until_the_rule_s_condition_changes(
    client: LayerClient, sensors: Sensors
) -> None:
    sensors.keep_publishing(lambda: "Night" in active(client), percentage=10.0)
    result = client.request((), ("Night",), synchronous=True, timeout=5, reason="operator")
    assert result.success, result.message
    for _ in range(10):  # the battery is still low: the rule does not fight the operator
        sensors.publish(percentage=10.0)
        time.sleep(0.05)
    assert "Night" not in active(client)
    assert client.query().reason == "operator"
    for _ in range(8):  # the condition changes (no change: Night is off already)...
        sensors.publish(percentage=30.0)
        time.sleep(0.05)
    # ... and when the battery runs low again, the rule acts again.
    sensors.keep_publishing(lambda: "Night" in active(client), percentage=10.0)
    assert client.query().requester == "rule Battery"


def test_a_field_the_message_lacks_is_reported_before_any_message(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    rules = tmp_path / "bad.layers"
    rules.write_text("rule Bad: Night while battery.percent < 20\n", encoding="utf-8")
    manager = processes.manager(
        "--rules", str(rules), "--ros-args", "-r", "__ns:=/bad", name="bad manager"
    )
    sensors = Sensors(client, namespace="/bad")
    try:
        manager.wait_for(
            lambda _: any("has no field 'percent'" in line for line in manager.lines),
            15,
            "the field error",
        )
        sensors.publish(percentage=1.0)
        output = manager.output()
        assert f"{rules}:1:23: error: sensor_msgs/msg/BatteryState (the type of topic " in output
        assert "rule Bad: Night while battery.percent < 20" in output
        assert "rules on /bad/battery stay off" in output
    finally:
        sensors.node.destroy_node()


def test_a_rule_with_a_syntax_error_stops_the_manager_at_once(tmp_path: Path) -> None:
    rules = tmp_path / "broken.layers"
    rules.write_text("rule Low: Night while battery.percentage <\n", encoding="utf-8")
    done = contextros("manager", "--rules", str(rules))
    assert done.returncode == 2
    assert f"{rules}:1:43: error: expected a field (TOPIC.FIELD) or a constant" in done.stderr


# Files `contextros check` refuses, with how many errors each has.
BROKEN = {
    "fields.layers": (
        "topic battery: sensor_msgs/msg/BatteryState\n"
        "rule Low: Night while battery.percent < 20\n"
        "rule Odd: Flight while battery.voltage == 'high'\n",
        2,
    ),
    "syntax.layers": (
        "rule A: Night while battery.percentage <\n"
        "rule B: Night wile battery.percentage < 3\n"
        "rule C: Night while battery.percentage < 20 for 3 h\n"
        "rule D: Night while 3 < 4\n",
        4,
    ),
    "misspelt.layers": (
        "topic battery: sensor_msgs/msg/BateryState\n"
        "rule Low: Night while battery.percentage < 20\n",
        1,
    ),
    "layers.layers": (
        "layer A requires Nope:\n    def f(): ...\nrule Low: A while battery.percentage < 20\n",
        1,
    ),
}


def refused_manager(*paths: Path) -> subprocess.CompletedProcess[str]:
    """`contextros manager --layers PATHS...`, which must refuse them (exit 2) at once."""
    try:  # (a manager that accepts the files runs until stopped)
        manager = subprocess.run(
            [sys.executable, "-m", "contextros", "manager", "--layers", *map(str, paths)],
            capture_output=True,
            text=True,
            timeout=20,
        )
    except subprocess.TimeoutExpired as running:
        pytest.fail(f"the manager ran with files `check` refuses: {running.stdout!r}")
    assert manager.returncode == 2, manager.stderr
    return manager


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_the_manager_refuses_every_file_check_refuses_and_lists_every_error(
    name: str, tmp_path: Path
) -> None:
    text, count = BROKEN[name]
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    checked = contextros("check", str(path))
    errors = [line for line in heads(checked.stdout) if ": error: " in line]
    assert (checked.returncode, len(errors)) == (1, count), checked.stdout
    manager = refused_manager(path)
    assert [line for line in heads(manager.stderr) if ": error: " in line] == errors
    assert "more error" not in manager.stderr, "every error listed, not a count"


def test_the_manager_refuses_a_file_that_is_no_layer_file_as_check_does(tmp_path: Path) -> None:
    module = tmp_path / "robot.py"
    module.write_text("print('a node, not its layers')\n", encoding="utf-8")
    assert contextros("check", str(module)).returncode == 1
    manager = refused_manager(module)
    assert f"{module}: error: a Python module, not a layer file" in manager.stderr


def test_check_together_refuses_what_the_manager_refuses_in_several_files(tmp_path: Path) -> None:
    sensors = tmp_path / "sensors.layers"
    sensors.write_text("topic battery: sensor_msgs/msg/BatteryState\n", encoding="utf-8")
    robot = tmp_path / "robot.layers"
    robot.write_text("rule Low: Night while battery.percent < 20\n", encoding="utf-8")
    files = (str(sensors), str(robot))
    assert contextros("check", *files).returncode == 0, "each alone: a note (no declaration)"
    together = contextros("check", "--together", *files)
    assert together.returncode == 1
    assert heads(together.stdout) == [
        f"{robot}:1:23: error: sensor_msgs/msg/BatteryState (the type of topic 'battery') has "
        "no field 'percent'"
    ]
    manager = refused_manager(sensors, robot)
    assert heads(manager.stderr)[1:] == heads(together.stdout)


def test_a_misspelt_message_type_names_the_installed_one(tmp_path: Path) -> None:
    path = tmp_path / "robot.layers"
    path.write_text(BROKEN["misspelt.layers"][0], encoding="utf-8")
    checked = contextros("check", str(path))
    assert heads(checked.stdout) == [
        f"{path}:1:16: error: the declared type of topic 'battery' does not exist: "
        "sensor_msgs.msg has no message type 'BateryState' (did you mean BatteryState?)"
    ]


def _stamp(line: str) -> float:
    """The time of a ROS log line: `[WARN] [1795746213.671906953] [node]: ...`."""
    return float(line.split("] [", 2)[1])


def test_a_topic_no_node_publishes_is_logged_once_after_the_grace_period(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    from contextros.ros.rules import UNPUBLISHED_GRACE

    rules = tmp_path / "typo.layers"
    rules.write_text(
        "rule Low: Night while batery.percentage < 20\n"
        "rule Place: Outdoor while gps.status.status >= 0\n",
        encoding="utf-8",
    )
    sensors = Sensors(client, namespace="/typo")  # publishes /typo/battery and /typo/gps
    manager = processes.manager("--rules", str(rules), "--ros-args", "-r", "__ns:=/typo")
    try:
        manager.wait_for(
            lambda _: any("rules on /typo/batery wait" in line for line in manager.lines),
            UNPUBLISHED_GRACE + 15,
            "the log of the topic nobody publishes",
        )
        (line,) = [line for line in manager.lines if "rules on /typo/batery wait" in line]
        assert line.startswith("[WARN]"), line
        assert (
            "rules on /typo/batery wait: no node has published it in the 5 s since the manager "
            "started (rule Low reads it). Is its name misspelt, or its publisher not started? "
            "Published topics with a close name: /typo/battery" in line
        ), line
        started = next(_stamp(line) for line in manager.lines if "recovering from" in line)
        assert _stamp(line) - started >= UNPUBLISHED_GRACE - 0.1, "not before the grace period"
        time.sleep(1.0)  # five more discovery rounds: logged once, not every round
        output = manager.output()
        assert output.count("rules on /typo/batery wait") == 1, output
        assert "rules on /typo/gps wait" not in output, "a published topic is not logged"
        assert "rules read /typo/gps (sensor_msgs/msg/NavSatFix)" in output
    finally:
        sensors.node.destroy_node()


def test_a_type_only_subscribers_give_is_not_said_to_be_published(
    client: LayerClient, processes: ProcessGroup, tmp_path: Path
) -> None:
    rules = tmp_path / "robot.layers"
    rules.write_text(
        "topic battery: robot_power_msgs/msg/Battery\n"
        "rule Low: Night while battery.percentage < 20\n",
        encoding="utf-8",
    )
    node = Node("battery_reader", namespace="/unpublished")
    node.create_subscription(BatteryState, "battery", lambda _: None, 10)
    manager = processes.manager("--rules", str(rules), "--ros-args", "-r", "__ns:=/unpublished")
    try:
        line = manager_line(manager, "/unpublished/battery has type", "the type mismatch")
        assert line.endswith(
            f"{rules}:1:16: error: topic /unpublished/battery has type "
            "sensor_msgs/msg/BatteryState on the ROS graph, from its subscribers (no node "
            "publishes it), but topic 'battery' is declared as robot_power_msgs/msg/Battery: "
            "the rules reading it (Low) stay off"
        ), line
        assert "is published as" not in manager.output()
    finally:
        node.destroy_node()


def test_a_byte_field_is_a_number_and_a_raising_rule_does_not_stop_the_manager(
    client: LayerClient,
) -> None:
    from std_msgs.msg import Byte, UInt8

    from contextros.ros.rules import RuleRunner, field_kind
    from contextros.rules import Firing, Rule, RuleSet

    assert field_kind(Byte, ("data",)) == "number"
    assert field_kind(UInt8, ("data",)) == "number"
    rules = RuleSet.from_rules(
        [Rule("Level", "High while level.data >= 2"), Rule("Odd", "Odd while odd.data > 1")]
    )
    fired: list[Firing] = []
    node = Node("rule_runner_test")
    try:
        runner = RuleRunner(node, rules, fired.append, dict)
        # What rclpy delivers for std_msgs/Byte: bytes of length 1 (this raised TypeError
        # out of the subscription callback, and spin_nodes ended the manager).
        runner._on_message("level", Byte(data=b"\x05"))
        assert [f.activate for f in fired] == [("High",)]
        # A message the static checks could not foresee: the rule goes off, nothing escapes.
        runner._on_message("odd", UInt8Like("x"))
        runner._on_message("odd", UInt8Like(5))
        assert [f.rule for f in fired] == ["Level"], "the failed rule stays off"
        runner._on_message("level", Byte(data=b"\x00"))
        assert [f.deactivate for f in fired][-1] == ("High",), "the other rules still run"
    finally:
        node.destroy_node()


class UInt8Like:
    def __init__(self, data: object) -> None:
        self.data = data


def test_a_manual_command_drops_the_refused_firings_older_than_it(client: LayerClient) -> None:
    """Night refused, the operator switches to Day: the retry after the operator's state
    activated Night and dropped Day. In a manager in this process, its own namespace."""
    from contextros.protocol import LayerState, PublishState
    from contextros.ros import LayerManagerNode
    from contextros.rules import Firing, Rule, RuleSet

    rules = RuleSet.from_rules([Rule("Dark", "Night while light.lux < 10")])
    manager = LayerManagerNode(rules=rules, node_name="m", namespace="/refused_firings")
    try:
        runner = manager.rules
        assert runner is not None
        sent: list[Firing] = []
        runner.firings._send_command = sent.append
        night = Firing("Dark", ("Night",), (), "light.lux < 10", 0)

        def state(epoch: int, requester: str) -> None:
            manager._run([PublishState(LayerState(epoch, ("Day",), requester=requester))])

        # Refused, then the operator's state: the refusal is dropped, not retried.
        runner.firings.fire([night])
        runner.refused(night)
        state(1, "operator")
        runner.retry()
        assert sent == [night], "no retry over the operator's state"
        # Refused only after the operator's state came (its command was under way): dropped.
        runner.firings.fire([night])
        state(2, "operator")
        runner.refused(night)
        runner.retry()
        assert sent == [night, night]
        # A state another rule (or the manager's recovery) caused: retried as before.
        runner.firings.fire([night])
        runner.refused(night)
        state(3, "manager")
        runner.retry()
        assert sent == [night, night, night, night]
    finally:
        manager.destroy_node()


def test_a_layer_file_that_cannot_be_read_is_named_with_no_empty_quote_nor_caret(
    tmp_path: Path,
) -> None:
    missing, directory, binary = (
        tmp_path / "gone.layers",
        tmp_path / "dir.layers",
        tmp_path / "bin.layers",
    )
    directory.mkdir()
    binary.write_bytes(b"\xff\xfe")
    manager = refused_manager(missing, directory, binary)
    for path in (missing, binary):
        assert f"{path}:1:1: error: cannot read the layer file: " in manager.stderr
    assert f"{directory}: error: a directory, not a layer file" in manager.stderr
    lines = manager.stderr.splitlines()
    assert not [line for line in lines if not line.strip() or line.strip() == "^"], lines
