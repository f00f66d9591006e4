"""Checks on everything that arrives from the network, before the protocol believes it.

Any process in a ROS domain can publish a status, a state or call the activation service
(DDS without SROS2 authenticates nobody), so the manager and the participants treat every
field as untrusted: names must look like names, lists and strings are bounded, and epochs
that no honest participant could report are refused. Each check returns the problems it
found as sentences naming the field; an empty list means the value is acceptable.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable

from contextros.protocol.events import ActivationCommand, ParticipantReport
from contextros.protocol.relations import LayerDeclaration
from contextros.protocol.state import MAX_EPOCH, LayerState

MAX_NAME_LENGTH = 128  # a layer or group name
MAX_NODE_NAME_LENGTH = 256  # a fully qualified ROS node name
MAX_LAYERS = 256  # layers a participant implements, or names in one command or state
MAX_RELATIONS = 64  # excludes/requires/after/implies of one layer
MAX_HOSTED = 256  # nodes one participant speaks for
MAX_EXPECTED = 1024  # nodes a command expects to reach
MAX_TOKEN_LENGTH = 64  # incarnation, manager id
MAX_TEXT_LENGTH = 1024  # requester, reason, error
MAX_TIMEOUT = 3600.0  # seconds, for a synchronous or atomic activation

_NODE_NAME = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")


def layer_name_problem(name: object, field: str = "layer name") -> str:
    """Layer and group names are identifiers (the core and the compiled layer files need it)."""
    if not isinstance(name, str):
        return f"{field} is not a string"
    if not name:
        return f"{field} is empty"
    if len(name) > MAX_NAME_LENGTH:
        return f"{field} {_quote(name)} is longer than {MAX_NAME_LENGTH} characters"
    if not name.isidentifier():
        return f"{field} {_quote(name)} is not an identifier"
    return ""


def node_name_problem(name: object, field: str = "node name") -> str:
    if not isinstance(name, str):
        return f"{field} is not a string"
    if not name:
        return f"{field} is empty"
    if len(name) > MAX_NODE_NAME_LENGTH:
        return f"{field} {_quote(name)} is longer than {MAX_NODE_NAME_LENGTH} characters"
    if not _NODE_NAME.fullmatch(name):
        return f"{field} {_quote(name)} is not a fully qualified ROS node name"
    return ""


def text_problem(text: object, field: str, limit: int = MAX_TEXT_LENGTH) -> str:
    """Free text (reasons, errors): bounded and printable, so logs and tables stay readable."""
    if not isinstance(text, str):
        return f"{field} is not a string"
    if len(text) > limit:
        return f"{field} is longer than {limit} characters"
    if not text.isprintable():
        return f"{field} {_quote(text)} has control characters"
    return ""


def epoch_problem(epoch: object, field: str = "epoch") -> str:
    if not isinstance(epoch, int) or isinstance(epoch, bool) or epoch < 0:
        return f"{field} is not a non-negative integer"
    if epoch > MAX_EPOCH:
        return f"{field} {epoch} is beyond any epoch an honest manager issues (2**48)"
    return ""


def _names_problems(
    names: Iterable[object], field: str, limit: int, check: object = layer_name_problem
) -> list[str]:
    listed = list(names)
    if len(listed) > limit:
        return [f"{field} lists {len(listed)} names, more than {limit}"]
    problems = [check(name, f"{field} entry") for name in listed]  # type: ignore[operator]
    return [p for p in problems if p][:3]


def declaration_problems(declaration: LayerDeclaration) -> list[str]:
    problems = [layer_name_problem(declaration.name)]
    where = f"layer {declaration.name!r}" if not problems[0] else "layer"
    problems += _names_problems(declaration.excludes, f"{where} excludes", MAX_RELATIONS)
    problems += _names_problems(declaration.requires, f"{where} requires", MAX_RELATIONS)
    problems += _names_problems(declaration.after, f"{where} after", MAX_RELATIONS)
    problems += _names_problems(declaration.implies, f"{where} implies", MAX_RELATIONS)
    if declaration.group:
        problems.append(layer_name_problem(declaration.group, f"{where} group"))
    return [p for p in problems if p]


def report_problems(
    report: ParticipantReport, previous: ParticipantReport | None = None
) -> list[str]:
    """What is wrong with a participant's status (empty: nothing). `previous`: the same
    participant's last accepted status (same node and incarnation), whose parts this one
    repeats unchanged are not checked again (a participant repeats its declarations, and
    mostly its layers, in every status)."""
    problems = [
        text_problem(report.applied_manager_id, "applied_manager_id", MAX_TOKEN_LENGTH),
        text_problem(report.error, "error"),
        epoch_problem(report.applied_epoch, "applied_epoch"),
        epoch_problem(report.pending_epoch, "pending_epoch"),
        epoch_problem(report.failed_epoch, "failed_epoch"),
        epoch_problem(report.vote_epoch, "vote_epoch"),
        text_problem(report.vote_reason, "vote_reason"),
        text_problem(report.vote_manager_id, "vote_manager_id", MAX_TOKEN_LENGTH),
    ]
    if previous is None:
        problems.append(node_name_problem(report.node))
        problems.append(text_problem(report.incarnation, "incarnation", MAX_TOKEN_LENGTH))
        if not report.incarnation:
            problems.append("incarnation is empty")
    if len(report.layers) > MAX_LAYERS:
        problems.append(f"layers lists {len(report.layers)} layers, more than {MAX_LAYERS}")
    elif previous is None or report.layers != previous.layers:
        for declaration in report.layers:
            problems += declaration_problems(declaration)
    if previous is None or report.active != previous.active:
        problems += _names_problems(report.active, "active_layers", MAX_LAYERS)
        if len(set(report.active)) != len(report.active):
            problems.append("active_layers names a layer twice")
    if previous is None or report.hosted != previous.hosted:
        problems += _names_problems(report.hosted, "hosted_nodes", MAX_HOSTED, node_name_problem)
    return [p for p in problems if p]


def state_problems(state: LayerState) -> list[str]:
    """What is wrong with a state received by a participant (empty: nothing)."""
    problems = [
        epoch_problem(state.epoch),
        text_problem(state.manager_id, "manager_id", MAX_TOKEN_LENGTH),
        text_problem(state.requester, "requester"),
        text_problem(state.reason, "reason"),
    ]
    problems += _names_problems(state.active, "active_layers", MAX_LAYERS)
    if len(set(state.active)) != len(state.active):
        problems.append("active_layers names a layer twice")
    return [p for p in problems if p]


def command_problems(command: ActivationCommand) -> list[str]:
    """What is wrong with an activation command (empty: nothing); checked before anything."""
    problems = _names_problems(command.activate, "activate", MAX_LAYERS)
    problems += _names_problems(command.deactivate, "deactivate", MAX_LAYERS)
    problems += _names_problems(
        command.expect_nodes, "expect_nodes", MAX_EXPECTED, node_name_problem
    )
    problems += [
        text_problem(command.requester, "requester"),
        text_problem(command.reason, "reason"),
    ]
    timeout = command.timeout
    if not isinstance(timeout, float | int) or not math.isfinite(timeout):
        problems.append("timeout is not a finite number of seconds")
    elif not 0 <= timeout <= MAX_TIMEOUT:
        problems.append(f"timeout {timeout:g} s is outside 0..{MAX_TIMEOUT:g} s")
    if not isinstance(command.expect_count, int) or not 0 <= command.expect_count <= 1_000_000:
        problems.append("expect_count is not a count of nodes")
    return [p for p in problems if p]


def listing(names: Iterable[str], limit: int = 10, quote: bool = False) -> str:
    """`a, b, c` for at most `limit` names, then `and N more`: answers stay small."""
    shown: list[str] = []
    rest = 0
    for name in names:
        if len(shown) < limit:
            shown.append(_quote(name) if quote else name)
        else:
            rest += 1
    text = ", ".join(shown)
    return f"{text} and {rest} more" if rest else text


def _quote(text: str, limit: int = 40) -> str:
    """A name as it can be shown: repr (control characters escaped), cut if long."""
    shown = repr(text[:limit])
    return shown + "..." if len(text) > limit else shown
