"""`contextros import-modes`: system_modes model files (written for these tests from
system_modes' documented format, fixtures/system_modes/*.yaml) as layer files."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from contextros.cli import main
from contextros.language.checker import check_source
from contextros.language.system_modes import ModesModelError, import_modes
from tests.language.conftest import FIXTURES

MODELS = FIXTURES / "system_modes"
_LAYER = re.compile(r"layer (\w+)(?: implies ([\w, ]+?))?(?: excludes ([\w, ]+?))?:$")


def imported(name: str) -> tuple[str, list[str]]:
    """The layer file for fixture `name` and its warnings, rendered."""
    result = import_modes((MODELS / name).read_text(encoding="utf-8"), name)
    return result.text, [warning.render() for warning in result.warnings]


def relations(text: str) -> dict[str, tuple[list[str], list[str]]]:
    """Layer -> (what it implies, what it excludes), read from the generated text."""
    found: dict[str, tuple[list[str], list[str]]] = {}
    for line in text.splitlines():
        match = _LAYER.match(line)
        if match:
            implies, excludes = (
                [name.strip() for name in (group or "").split(",") if name.strip()]
                for group in match.group(2, 3)
            )
            found[match.group(1)] = (implies, excludes)
    return found


def implied_closure(text: str, layer: str) -> list[str]:
    """`layer` and everything it implies, transitively, in a depth-first order."""
    implies = {name: pair[0] for name, pair in relations(text).items()}
    found: list[str] = []

    def visit(name: str) -> None:
        if name not in found:
            found.append(name)
            for other in implies[name]:
                visit(other)

    visit(layer)
    return found


def bindings(text: str, layer: str) -> list[str]:
    """The `parameter` and `lifecycle` lines of `layer`, without the layer's name."""
    prefixes = (f"parameter {layer}: ", f"lifecycle {layer}: ")
    return [line.split(": ", 1)[1] for line in text.splitlines() if line.startswith(prefixes)]


def test_each_part_s_modes_are_one_group_of_layers() -> None:
    text, _ = imported("rover.yaml")
    assert "group rover: rover_DEFAULT, rover_CAREFUL, rover_RUSH" in text.splitlines()
    assert "group arm: arm_DEFAULT, arm_GENTLE, arm_FIRM" in text.splitlines()
    assert "group base: base_DEFAULT, base_CRAWL, base_SPRINT" in text.splitlines()


def test_a_node_mode_sets_its_parameters_with_those_of_default_and_requires_the_node_active() -> (
    None
):
    text, _ = imported("rover.yaml")
    # CRAWL only changes max_speed: the rest comes from __DEFAULT__, nested names dotted.
    assert bindings(text, "base_CRAWL") == [
        "base max_speed = 0.1",
        "base planner = 'DWB'",
        "base limits.reverse = false",
        "base active",
    ]
    assert bindings(text, "base_SPRINT") == [
        "base max_speed = 2.5",
        "base planner = 'MPPI'",
        "base limits.reverse = true",
        "base active",
    ]
    assert bindings(text, "arm_DEFAULT") == ["arm max_torque = 0.5", "arm active"]


def test_a_system_mode_implies_its_parts_modes_and_deactivates_the_inactive_ones() -> None:
    text, _ = imported("rover.yaml")
    layers = relations(text)
    assert layers["rover_CAREFUL"] == (["arm_GENTLE", "base_CRAWL"], [])
    # `base: active` is base's __DEFAULT__; `arm: inactive` has no mode: a lifecycle binding,
    # and none of arm's modes may be active meanwhile.
    assert layers["rover_DEFAULT"] == (["base_DEFAULT"], ["arm_DEFAULT", "arm_GENTLE", "arm_FIRM"])
    assert bindings(text, "rover_DEFAULT") == ["arm inactive"]


def test_a_three_level_hierarchy_reaches_every_node() -> None:
    text, warnings = imported("drone.yaml")
    assert warnings == []
    flight = implied_closure(text, "drone_FLIGHT")
    assert flight == [
        "drone_FLIGHT",
        "propulsion_ON",
        "motors_front_RUN",
        "motors_rear_RUN",
        "camera_HIGH_RES",
    ]
    assert bindings(text, "motors_front_RUN") == [
        "motors/front rpm = 4200",
        "motors/front spin = 'clockwise'",
        "motors/front active",
    ]
    # HOVER: propulsion's IDLE, whose parts are `active` alone: their __DEFAULT__ modes.
    assert implied_closure(text, "drone_HOVER")[1:] == [
        "propulsion_IDLE",
        "motors_front_DEFAULT",
        "motors_rear_DEFAULT",
        "camera_DEFAULT",
    ]


def test_an_inactive_subsystem_deactivates_every_node_under_it() -> None:
    text, _ = imported("drone.yaml")
    assert bindings(text, "drone_DEFAULT") == ["motors/front inactive, motors/rear inactive"]
    implies, excludes = relations(text)["drone_DEFAULT"]
    assert implies == ["camera_DEFAULT"]
    assert excludes == [
        "propulsion_DEFAULT",
        "propulsion_ON",
        "propulsion_IDLE",
        "motors_front_DEFAULT",
        "motors_front_RUN",
        "motors_rear_DEFAULT",
        "motors_rear_RUN",
    ]


def test_a_rule_to_inactive_becomes_a_context_rule_on_the_part_s_lifecycle_state() -> None:
    text, _ = imported("rover.yaml")
    assert (
        "rule rover_stop_if_base_fails: deactivate rover_RUSH when lifecycle base == inactive "
        "for 1 s" in text.splitlines()
    )


def test_a_rule_the_language_cannot_say_is_a_warning_and_a_comment_never_dropped() -> None:
    text, warnings = imported("rover.yaml")
    assert len(warnings) == 1
    assert warnings[0].startswith(
        "rover.yaml:28:7: warning: rule 'careful_without_arm' of 'rover' is not converted: "
        "a context rule cannot ask whether rover_RUSH is the active mode"
    )
    assert (
        "# NOT CONVERTED: rule careful_without_arm (rover.yaml:28): if rover's target is "
        "active.RUSH and arm is inactive, go to active.__DEFAULT__" in text.splitlines()
    )
    assert not any(line.startswith("rule rover_careful") for line in text.splitlines())


def test_a_rule_on_a_part_s_mode_reads_the_mode_s_parameters() -> None:
    model = (MODELS / "rover.yaml").read_text(encoding="utf-8")
    model = model.replace("if_part: [base, inactive]", "if_part: [base, active.CRAWL]")
    text = import_modes(model, "rover.yaml").text
    assert (
        "rule rover_stop_if_base_fails: deactivate rover_RUSH when lifecycle base == active "
        "and param base.max_speed == 0.1 and param base.planner == 'DWB' "
        "and param base.limits.reverse == false for 1 s"
    ) in text.splitlines()


def test_unconfigured_is_taken_as_inactive_with_a_warning() -> None:
    model = (MODELS / "rover.yaml").read_text(encoding="utf-8")
    model = model.replace("        arm: inactive\n", "        arm: unconfigured\n", 1)
    result = import_modes(model, "rover.yaml")
    assert "lifecycle rover_DEFAULT: arm inactive" in result.text.splitlines()
    assert (
        result.warnings[0]
        .render()
        .startswith(
            "rover.yaml:15:14: warning: 'arm: unconfigured' in mode __DEFAULT__ of 'rover' is "
            "taken as inactive"
        )
    )


NODE = """\
cam:
  ros__parameters:
    type: node
    modes:
      __DEFAULT__:
        ros__parameters:
          fps: 30
      FAST:
        ros__parameters:
          fps: 60
"""
SYSTEM = """\
sys:
  ros__parameters:
    type: system
    parts:
      cam
    modes:
      __DEFAULT__:
        cam: active
      ON:
        cam: active.FAST
"""


@pytest.mark.parametrize(
    ("model", "expected"),  # the error's place and the start of its message
    [
        (
            NODE.replace("type: node", "type: node: system"),
            "3:15: error: YAML: mapping values are not allowed here",
        ),
        (NODE.replace("    modes:", "    mode:"), "4:5: error: unknown key 'mode' in 'cam' "),
        (NODE.replace("type: node", "type: nodes"), "3:11: error: type 'nodes' of 'cam': "),
        (NODE.replace("          fps: 60", "          fsp: 60"), "10:16: error: parameter 'fsp' "),
        (
            NODE.replace("__DEFAULT__", "DEFAULT"),
            "5:7: error: 'cam' has modes but no '__DEFAULT__'",
        ),
        (NODE.replace("fps: 60", "fps: [60, 30]"), "10:16: error: parameter 'fps' of mode FAST "),
        (
            NODE.replace(
                "ros__parameters:\n          fps: 60", "ros__parameters:\n          fps: .inf"
            ),
            "10:16: error: parameter 'fps' ",
        ),
        (
            NODE + SYSTEM.replace("cam: active.FAST", "cma: active.FAST"),
            "20:9: error: 'cma' in mode ON of 'sys' is not a part of 'sys' (its parts: cam)",
        ),
        (
            NODE + SYSTEM.replace("active.FAST", "active.FASTER"),
            "20:14: error: 'cam' has no mode FASTER (its modes: __DEFAULT__, FAST)",
        ),
        (
            NODE + SYSTEM.replace("active.FAST", "ACTIVE.FAST"),
            "20:14: error: 'ACTIVE.FAST' for part 'cam' in mode ON of 'sys': expected active, ",
        ),
        (
            NODE + SYSTEM.replace("active.FAST", "inactive.FAST"),
            "20:14: error: 'inactive.FAST' for part 'cam' in mode ON of 'sys': only an active part",
        ),
        (NODE + NODE, "11:1: error: duplicate key 'cam' in the model"),
        (
            NODE + NODE.replace("cam:", "/cam:"),
            "11:1: error: '/cam' is 'cam' again (first at line 1)",
        ),
        (
            SYSTEM.replace("parts:\n      cam", "parts:\n      sys")
            .replace("cam: active.FAST", "sys: active.ON")
            .replace("cam: active", "sys: active"),
            "1:1: error: a system is its own part: sys -> sys",
        ),
        (
            "---\na: 1\n---\nb: 2\n",
            "4:1: error: a model is one YAML document; this is a second one",
        ),
        ("# nothing\n", "1:1: error: the model is empty"),
    ],
)
def test_a_bad_model_is_an_error_at_its_line_and_column(model: str, expected: str) -> None:
    with pytest.raises(ModesModelError) as caught:
        import_modes(model, "model.yaml")
    assert caught.value.render().startswith(f"model.yaml:{expected}"), caught.value.render()


def test_two_modes_that_would_make_one_layer_name_are_an_error() -> None:
    clash = NODE.replace("cam:", "a_b:") + NODE.replace("cam:", "a:").replace("FAST:", "b_FAST:")
    with pytest.raises(ModesModelError) as caught:
        import_modes(clash, "model.yaml")
    assert "would both be layer 'a_b_FAST'" in caught.value.render()


def test_the_command_writes_nothing_and_exits_2_on_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = tmp_path / "bad.yaml"
    model.write_text(NODE.replace("    modes:", "    mode:"), encoding="utf-8")
    output = tmp_path / "out.layers"
    assert main(["import-modes", str(model), "-o", str(output)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"{model}:4:5: error: unknown key 'mode' in 'cam' ros__parameters")
    assert "nothing written" in err and not output.exists()


def test_the_command_writes_the_layers_to_stdout_or_a_file_and_warnings_to_stderr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    model = MODELS / "rover.yaml"
    assert main(["import-modes", str(model)]) == 0
    shown = capsys.readouterr()
    assert shown.out == import_modes(model.read_text(encoding="utf-8"), str(model)).text
    assert f"{model}:28:7: warning: rule 'careful_without_arm'" in shown.err
    output = tmp_path / "rover.layers"
    assert main(["import-modes", str(model), "-o", str(output)]) == 0
    assert output.read_text(encoding="utf-8") == shown.out


def test_the_docs_show_what_the_command_writes_for_their_model() -> None:
    docs = (Path(__file__).parents[2] / "docs" / "ros-integration.md").read_text(encoding="utf-8")
    blocks = {
        name: re.search(rf"<!-- import-modes: {name} -->\n```\w+\n(.*?)```", docs, re.S)
        for name in ("model", "layers")
    }
    assert blocks["model"] and blocks["layers"], "the side-by-side example left the docs"
    text = import_modes(blocks["model"].group(1), "rover.yaml").text
    assert text == blocks["layers"].group(1)


@pytest.mark.parametrize("name", ["drone.yaml", "rover.yaml"])
def test_contextros_check_accepts_the_layers_without_a_warning(name: str) -> None:
    text, _ = imported(name)
    found = [d.render() for d in check_source(text, name.replace(".yaml", ".layers"))]
    assert found == []


def test_the_checker_would_see_a_part_s_mode_beside_an_inactive_part() -> None:
    """What the `excludes` of an inactive part's modes is for: without it, a layer wanting
    the arm inactive and one wanting it active could be active together."""
    text, _ = imported("rover.yaml")
    without = text.replace(" excludes arm_DEFAULT, arm_GENTLE, arm_FIRM", "")
    found = [d.render() for d in check_source(without, "rover.layers")]
    assert any(
        "lifecycle node arm is bound to inactive by layer 'rover_DEFAULT'" in f for f in found
    )


def test_a_part_the_model_does_not_describe_is_a_plain_lifecycle_node() -> None:
    model = (
        """\
lab:
  ros__parameters:
    type: system
    parts: [cam, /lights]
    modes:
      __DEFAULT__:
        cam: active
        lights: inactive
      DARK:
        lights: active
"""
        + NODE
    )
    text = import_modes(model, "lab.yaml").text
    layers = relations(text)
    # cam has modes (its __DEFAULT__ is implied); lights is only a lifecycle node.
    assert layers["lab_DEFAULT"] == (["cam_DEFAULT"], [])
    assert bindings(text, "lab_DEFAULT") == ["lights inactive"]
    assert layers["lab_DARK"] == (["cam_DEFAULT"], [])
    assert bindings(text, "lab_DARK") == ["lights active"]
    with pytest.raises(ModesModelError) as caught:
        import_modes(model.replace("lights: active", "lights: active.ON"), "lab.yaml")
    assert caught.value.render().startswith(
        "lab.yaml:10:17: error: part 'lights' of 'lab' is not in the model, so it has no mode ON"
    )
