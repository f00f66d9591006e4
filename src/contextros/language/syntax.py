"""The syntax tree of a layer file: what a flavour's parser produces and the checker reads.

Describe, then execute: these are inert values. Lines and columns are 1-based and refer
to the layer file, so every diagnostic and every traceback can point there.

The tree is language-neutral: layers, groups, relations and, for each implementation of a
method, its name, owner class, signature (as data the checker compares) and its calls of
`proceed`. Each flavour (Python: parser.py, C++: cpp/parser.py) subclasses `Function` with
what its back end needs (Python's `ast` nodes, the C++ text spans).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from contextros.language.bindings import LifecycleBinding, ParameterBinding
from contextros.language.positions import Position, Ref
from contextros.language.rules import RuleDecl
from contextros.language.topics import TopicDecl

__all__ = [
    "BaseBlock",
    "Decorator",
    "Function",
    "GroupDecl",
    "Guard",
    "Hook",
    "LayerDecl",
    "LayerFile",
    "Position",
    "ProceedCall",
    "Ref",
    "Signature",
    "SourceLine",
    "char_of_byte",
]


@dataclass(frozen=True)
class SourceLine:
    """One line of generated text and where it came from.

    `delta` is added to a generated column to get the `.layers` column (it is the cut
    indentation: the same in bytes and in characters). The `def` line of a renamed function
    shifts differently after the new name: by `delta_after` UTF-8 bytes from byte
    `split_col` on, by `delta_after_char` characters from character `split_char` on.
    """

    text: str
    line: int
    delta: int
    split_col: int = -1
    delta_after: int = 0
    split_char: int = -1
    delta_after_char: int = 0

    def column(self, col: int) -> int:
        """A 0-based UTF-8 byte column of `text` (as Python's AST counts) in the file's line,
        in bytes: for the positions of compiled code."""
        if self.split_col >= 0 and col >= self.split_col:
            return col + self.delta_after
        return col + self.delta

    def char_column(self, col: int) -> int:
        """A 0-based character column of `text` (as a parser's SyntaxError counts) in the
        file's line, in characters: for diagnostics."""
        if self.split_char >= 0 and col >= self.split_char:
            return col + self.delta_after_char
        return col + self.delta

    def char_of_byte(self, col: int) -> int:
        """The character column of `text` at its UTF-8 byte column `col`."""
        return char_of_byte(self.text, col)


def char_of_byte(text: str, col: int) -> int:
    """The 0-based character column of `text` at its 0-based UTF-8 byte column `col` (Python's
    AST, and the errors of its compiler, count bytes)."""
    return len(
        text.encode("utf-8", errors="surrogatepass")[: max(col, 0)].decode("utf-8", errors="ignore")
    )


@dataclass(frozen=True)
class Signature:
    """What callers of a method rely on, as the checker compares it between implementations.

    `shape` is compared for equality (its content is the flavour's business: parameter kinds
    and names in Python, parameter types and qualifiers in C++); `text` shows it in messages.
    """

    shape: tuple[object, ...]
    text: str
    is_async: bool = False


@dataclass(frozen=True)
class ProceedCall:
    """A call of `proceed` in an implementation; whether it passes the instance first.

    (Python methods pass `self` explicitly; a C++ method's `proceed` knows its object.)
    """

    at: Position
    passes_instance: bool = True


@dataclass(frozen=True)
class Decorator:
    """A decorator on an implementation (Python): its expression as written, and where."""

    text: str
    at: Position


@dataclass(frozen=True)
class Guard:
    """`when CONDITION` on a partial: the partial applies to a call only while CONDITION,
    evaluated on that call's arguments, holds; otherwise the call goes on to the next
    implementation of the chain (as if this layer had no partial there).

    `text` is the condition as written, in the flavour's expression language (a Python
    expression, a C++ expression); `at` is where it starts in the layer file.
    """

    text: str
    at: Position


@dataclass
class Function:
    """A method implementation: in a layer (a partial) or in the base block.

    `owner` is the class name for a method (`Cleaner.clean`, `Robot::getPos`), None for a
    free function. `takes_instance` says whether it has a way to reach its object (a
    Python method needs a first parameter; a C++ method always has `this`).
    """

    name: str
    owner: str | None
    layer: str | None
    at: Position
    generated_name: str
    signature: Signature
    proceed_calls: tuple[ProceedCall, ...] = ()
    decorators: tuple[Decorator, ...] = ()
    takes_instance: bool = True
    instance_name: str = "self"
    # `when CONDITION` on a layer's partial; None for an unguarded one (and the base's).
    guard: Guard | None = None

    @property
    def key(self) -> str:
        """What the method is called in diagnostics: `get_pos`, `Cleaner.clean`."""
        return f"{self.owner}.{self.name}" if self.owner else self.name

    @property
    def is_async(self) -> bool:
        return self.signature.is_async


@dataclass
class Hook:
    """An `on activate:` / `on deactivate:` block, compiled to a function of no arguments."""

    event: str
    layer: str
    at: Position
    lines: list[SourceLine]
    generated_name: str


@dataclass
class LayerDecl:
    name: str
    at: Position
    excludes: list[Ref] = field(default_factory=list)
    requires: list[Ref] = field(default_factory=list)
    after: list[Ref] = field(default_factory=list)
    implies: list[Ref] = field(default_factory=list)
    description: str | None = None
    functions: list[Function] = field(default_factory=list)
    hooks: list[Hook] = field(default_factory=list)


@dataclass
class GroupDecl:
    """`group location: Indoor, Outdoor`: at most one member is active at a time."""

    name: str
    at: Position
    members: list[Ref] = field(default_factory=list)


@dataclass
class BaseBlock:
    at: Position
    functions: list[Function] = field(default_factory=list)


@dataclass
class LayerFile:
    """A parsed layer file: the header, then the declarations in file order.

    `header_names` are the names the header defines that generated names could collide
    with; `header_opaque` says the header may define more than can be seen (a Python
    `import *`, a C++ `#include`).
    """

    path: str
    source: str
    header: str
    header_lines: int
    language: str = "python"
    header_names: frozenset[str] = frozenset()
    header_opaque: bool = False
    layers: list[LayerDecl] = field(default_factory=list)
    groups: list[GroupDecl] = field(default_factory=list)
    bases: list[BaseBlock] = field(default_factory=list)
    # Context rules (`rule NAME: ...`), language-neutral: see contextros.language.rules.
    rules: list[RuleDecl] = field(default_factory=list)
    # Layers that drive ROS (`parameter L: NODE NAME = VALUE`, `lifecycle L: NODE STATE`):
    # see contextros.language.bindings.
    parameters: list[ParameterBinding] = field(default_factory=list)
    lifecycles: list[LifecycleBinding] = field(default_factory=list)
    # The message types of the rules' topics (`topic NAME: PACKAGE/msg/TYPE`): see
    # contextros.language.topics.
    topics: list[TopicDecl] = field(default_factory=list)

    def all_functions(self) -> list[Function]:
        found: list[Function] = [f for b in self.bases for f in b.functions]
        found += [f for layer in self.layers for f in layer.functions]
        return found
