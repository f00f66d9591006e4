"""One-line declarations shared by every flavour: `rule`, `parameter`, `lifecycle`, `topic`.

They hold no code of the host language, so both parsers hand such a line here (the Python
flavour as it is, the C++ flavour without its `//` comment and optional `;`), and the tree
they produce (`LayerFile.rules`, `.parameters`, `.lifecycles`, `.topics`) is the same.
"""

from __future__ import annotations

import re

from contextros.language.bindings import parse_lifecycle, parse_parameter
from contextros.language.diagnostics import DiagnosticSink
from contextros.language.rules import parse_rule
from contextros.language.syntax import LayerFile, Position, Ref
from contextros.language.topics import parse_topic

_NAME = r"[^\W\d]\w*"
# What starts such a declaration at column 1, in every flavour (enough to end a header: none
# is valid Python or C++): the word and a name, then ':', or (a declaration missing its ':',
# reported as such) what would follow the ':' (a name, a ROS node name `/base`, `~/x`) or
# the end of the line. Not after a word that continues a Python expression (`rule in rules`,
# `parameter if x else y`).
LINE_START = re.compile(
    rf"(?:rule|parameter|lifecycle)[ \t]+(?P<name>{_NAME})"
    rf"(?:(?P<colon>[ \t]*:)|[ \t]+(?=[^\W\d]|~/|/(?![/*]))|[ \t]*(?=\#|\r|\n|$))"
)
_CONTINUES_EXPRESSION = frozenset({"and", "or", "is", "in", "not", "if", "else", "for", "async"})
# `topic NAME: TYPE`, NAME a ROS topic name (`gps/fix`, `/robot1/battery`, `~/state`): a
# name (or what was meant as one) and ':', or a relative or private name followed by a word
# or nothing; none of that is Python or C++. (`topic /x` without ':' is Python, a division:
# an absolute name needs its ':'.)
TOPIC_START = re.compile(
    r"topic[ \t]+(?P<name>[~/\w.]+)"
    r"(?:(?P<colon>[ \t]*:)|[ \t]+(?=[^\W\d])|[ \t]*(?=\#|\r|\n|$))"
)
_HEAD = re.compile(
    rf"(?P<word>rule|parameter|lifecycle)[ \t]+(?P<name>{_NAME})?[ \t]*(?P<colon>:)?"
)


def is_line_declaration(text: str, pos: int = 0) -> bool:
    """Whether the line starting at `pos` of `text` (a line, or a whole source with `pos`
    at a line start) is a `rule`/`parameter`/`lifecycle`/`topic` declaration. The one detector of
    both flavours' parsers; it reads the whole line (it never looks past the line's end)."""
    match = LINE_START.match(text, pos) or TOPIC_START.match(text, pos)
    if match is None:
        return False
    if match.group("colon") is not None:
        return True
    name = match.group("name")
    if match.re is TOPIC_START and not re.match(rf"~/|{_NAME}", name):
        return False
    return name.split("/")[0] not in _CONTINUES_EXPRESSION


def parse_line_declaration(text: str, line: int, result: LayerFile, sink: DiagnosticSink) -> None:
    """Parse `text` (the declaration line `line`, from column 1) into `result`; errors, with
    their column, go to `sink`."""
    if text.startswith("topic"):
        topic = parse_topic(text, line, sink)
        if topic is not None:
            result.topics.append(topic)
        return
    head = _HEAD.match(text)
    word = head.group("word") if head else "rule"
    what = "a rule name" if word == "rule" else "a layer name"
    if head is None or head.group("name") is None:
        col = head.end() if head else 4
        rest = text[col:].split()
        found = repr(rest[0]) if rest else "the end of the line"
        sink.error(f"expected {what} after {word!r}, found {found}", line, col + 1)
        return
    if head.group("colon") is None:
        after = text[head.end("name") :]
        col = head.end("name") + len(after) - len(after.lstrip(" \t"))
        sink.error(f"expected ':' after the {what[2:]}", line, col + 1)
        return
    name = Ref(head.group("name"), Position(line, head.start("name") + 1))
    colon = head.end("colon")
    body, col = text[colon:], colon + 1
    if word == "rule":
        rule = parse_rule(name, body, line, col, sink)
        if rule is not None:
            result.rules.append(rule)
    elif word == "parameter":
        binding = parse_parameter(name, body, line, col, sink)
        if binding is not None:
            result.parameters.append(binding)
    else:
        result.lifecycles += parse_lifecycle(name, body, line, col, sink)
