"""Where things are in a layer file: the leaves of every syntax tree (the layers part's, the
rules', the bindings'), so that each of those depends on this module and none on another."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Position:
    """1-based line and column in the layer file."""

    line: int
    col: int


@dataclass(frozen=True)
class Ref:
    """A layer named in a relation or a group, where it was named."""

    name: str
    at: Position
