"""`topic` declarations: the message type of a topic the rules read, stated in the file.

    topic battery: sensor_msgs/msg/BatteryState
    topic /robot1/gps/fix: sensor_msgs/msg/NavSatFix

With the type known, `contextros check` checks the rules' fields without a running system,
and the Layer manager refuses a topic published with another type. A declaration names the
topic exactly as the rules do (`battery` and `/battery` are different names here). Like
rules, the line holds no code of the host language: both flavours hand it here.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from contextros.language.diagnostics import DiagnosticSink
from contextros.language.positions import Position

# A ROS topic name, as a rule may name it: relative, absolute or private (`~/`).
_TOPIC = re.compile(r"(?:~/|/)?[A-Za-z_][A-Za-z0-9_]*(?:/[A-Za-z_][A-Za-z0-9_]*)*")
# PACKAGE/msg/NAME: a ROS package name (REP 144) and a message name (a capital first).
_TYPE = re.compile(r"[a-z][a-z0-9_]*/msg/[A-Z][A-Za-z0-9]*")
_WORD = re.compile(r"[^\s:#]+")
_TYPE_WORD = re.compile(r"[^\s#]+")
EXAMPLE_TYPE = "sensor_msgs/msg/BatteryState"


@dataclass(frozen=True)
class TopicDecl:
    """`topic NAME: PACKAGE/msg/TYPE`; `at` is the topic name, `type_at` the type."""

    topic: str
    type_name: str
    at: Position
    type_at: Position
    path: str = "<layers>"


def _blanks(text: str, pos: int) -> int:
    while pos < len(text) and text[pos] in " \t":
        pos += 1
    return pos


def parse_topic(text: str, line: int, sink: DiagnosticSink) -> TopicDecl | None:
    """The declaration on `text` (line `line`, from column 1, starting with `topic`);
    errors go to `sink` at their column, and give None."""
    pos = _blanks(text, len("topic"))
    word = _WORD.match(text, pos)
    if word is None:
        found = repr(text[pos]) if pos < len(text) and text[pos] != "#" else "the end of the line"
        sink.error(f"expected a topic name after 'topic', found {found}", line, pos + 1)
        return None
    name, at = word.group(), Position(line, pos + 1)
    if _TOPIC.fullmatch(name) is None:
        if "." in name:
            why = "a topic name has no '.' (the first dot of 'TOPIC.FIELD' ends the topic)"
        else:
            why = (
                "a topic name is parts of letters, digits and '_' joined by '/', "
                "e.g. battery, gps/fix, /robot1/battery, ~/state"
            )
        sink.error(f"{name!r} is not a topic name: {why}", at.line, at.col)
        return None
    pos = _blanks(text, word.end())
    if pos >= len(text) or text[pos] != ":":
        sink.error(
            f"expected ':' after the topic name, then its type ({EXAMPLE_TYPE})", line, pos + 1
        )
        return None
    pos = _blanks(text, pos + 1)
    type_word = _TYPE_WORD.match(text, pos)
    if type_word is None:
        sink.error(
            f"expected the message type of topic '{name}' after ':' (e.g. {EXAMPLE_TYPE})",
            line,
            pos + 1,
        )
        return None
    type_name, type_at = type_word.group(), Position(line, pos + 1)
    problem = type_name_problem(type_name)
    if problem:
        sink.error(problem, type_at.line, type_at.col)
        return None
    pos = _blanks(text, type_word.end())
    if pos < len(text) and text[pos] != "#":
        sink.error(
            f"expected the end of the declaration after the type, found {text[pos:].split()[0]!r}",
            line,
            pos + 1,
        )
        return None
    return TopicDecl(name, type_name, at, type_at, sink.path)


def type_name_problem(type_name: str) -> str:
    """Why `type_name` is not a message type name as a topic declaration takes it ('' if
    it is): PACKAGE/msg/NAME, the form the ROS graph reports."""
    if _TYPE.fullmatch(type_name):
        return ""
    parts = type_name.split("/")
    if len(parts) == 2 and all(parts):
        return f"write the message type as PACKAGE/msg/NAME: {parts[0]}/msg/{parts[1]}"
    if len(parts) == 3 and parts[1] in ("srv", "action"):
        return (
            f"{type_name!r} is a {parts[1]} type: a topic carries a message type (PACKAGE/msg/NAME)"
        )
    return (
        f"{type_name!r} is not a message type name: PACKAGE/msg/NAME (e.g. {EXAMPLE_TYPE}; "
        "a package name is lowercase letters, digits and '_', a message name starts with a "
        "capital letter)"
    )
