"""The syntax tree of a `.layers` file: what the parser produces and the checker reads.

Describe, then execute: these are inert values. Lines and columns are 1-based and refer
to the `.layers` file, so every diagnostic and every traceback can point there.
"""

from __future__ import annotations

import ast
from dataclasses import dataclass, field


@dataclass(frozen=True)
class Position:
    line: int
    col: int


@dataclass(frozen=True)
class Ref:
    """A layer named in a relation or a group, where it was named."""

    name: str
    at: Position


@dataclass(frozen=True)
class SourceLine:
    """One line of generated text and where it came from.

    `delta` is added to a generated column to get the `.layers` column. The `def` line
    of a renamed function shifts differently after the new name (`split_col`).
    """

    text: str
    line: int
    delta: int
    split_col: int = -1
    delta_after: int = 0

    def column(self, col: int) -> int:
        if self.split_col >= 0 and col >= self.split_col:
            return col + self.delta_after
        return col + self.delta


@dataclass
class Function:
    """A method implementation: in a layer (a partial) or in the `base:` block.

    `owner` is the class name for `def Class.name(...)`, None for a free function.
    `lines` is the dedented Python text with the `def` renamed to `generated_name`.
    """

    name: str
    owner: str | None
    layer: str | None
    at: Position
    node: ast.FunctionDef | ast.AsyncFunctionDef
    lines: list[SourceLine]
    generated_name: str

    @property
    def key(self) -> str:
        """What the method is called in diagnostics: `get_pos`, `Cleaner.clean`."""
        return f"{self.owner}.{self.name}" if self.owner else self.name

    @property
    def is_async(self) -> bool:
        return isinstance(self.node, ast.AsyncFunctionDef)


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
    """A parsed `.layers` file: the Python header, then the declarations in file order."""

    path: str
    source: str
    header: str
    header_lines: int
    header_node: ast.Module | None
    layers: list[LayerDecl] = field(default_factory=list)
    groups: list[GroupDecl] = field(default_factory=list)
    bases: list[BaseBlock] = field(default_factory=list)

    def all_functions(self) -> list[Function]:
        found: list[Function] = [f for b in self.bases for f in b.functions]
        found += [f for layer in self.layers for f in layer.functions]
        return found
