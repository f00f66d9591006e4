"""The C++ flavour's part of the syntax tree: functions and hooks with the spans of their
parts (character offsets in the layer file, which the back end rewrites), and what the
header part declares."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from contextros.language.syntax import Function, Hook, LayerFile

Span = tuple[int, int]  # [start, end) character offsets in the layer file


class Shape(NamedTuple):
    """What callers of a C++ function rely on (the checker compares it for equality)."""

    returns: str
    parameters: tuple[str, ...]  # their types
    qualifiers: str  # `const`, `noexcept`...

    def text(self, key: str) -> str:
        """`double Robot::speed(double) const`."""
        qualifiers = f" {self.qualifiers}" if self.qualifiers else ""
        return f"{self.returns} {key}({', '.join(self.parameters)}){qualifiers}"


@dataclass
class CppFunction(Function):
    """A C++ implementation and where its parts are (character offsets in the layer file)."""

    start: int = 0
    end: int = 0
    target_start: int = 0  # of the (qualified) name
    name_start: int = 0
    name_end: int = 0
    params_open: int = 0  # just after '('
    params_close: int = 0  # at ')'
    no_parameters: bool = True  # `()` or `(void)`
    declarator_end: int = 0  # before the body
    defaults: tuple[Span, ...] = ()  # ` = value` of parameters
    exception_specs: tuple[Span, ...] = ()  # `noexcept(...)`, `throw(...)`
    parameter_names: tuple[str | None, ...] = ()
    body_start: int = 0  # at the body's '{'
    when_span: Span = (0, 0)  # `when (CONDITION)`, cut from the definition
    condition_span: Span = (0, 0)  # CONDITION itself

    @property
    def key(self) -> str:
        return f"{self.owner}::{self.name}" if self.owner else self.name


@dataclass
class CppHook(Hook):
    """`on activate { ... }`: the body is C++, a compound statement (offsets of its braces)."""

    body_start: int = 0
    body_end: int = 0


@dataclass(frozen=True)
class DeclaredMethod:
    """A member function as its class declares it."""

    shape: Shape
    text: str  # as messages show it
    line: int


@dataclass
class CppClass:
    """A class defined in the header part, which the compiler can extend."""

    name: str  # with its namespaces: ns::Robot
    close: int  # offset of the closing brace of its body
    has_macro: bool  # already holds CONTEXTROS_LAYERED_CLASS
    methods: frozenset[str]  # member functions it declares
    # Each member function declared once (none if the body has a syntax error).
    declarations: dict[str, DeclaredMethod] = field(default_factory=dict)
    static_methods: frozenset[str] = frozenset()  # declared `static`: a layer cannot refine them
    overloads: dict[str, tuple[int, ...]] = field(default_factory=dict)  # name: its lines


@dataclass
class CppLayerFile(LayerFile):
    classes: list[CppClass] = field(default_factory=list)
    header_functions: frozenset[str] = frozenset()  # functions the header part declares
    # Functions the header part declares more than once with different parameters: lines.
    header_overloads: dict[str, tuple[int, ...]] = field(default_factory=dict)
    header_end: int = 0  # character offset where the declarations start
    namespaces: frozenset[str] = frozenset()  # namespaces the header part opens (ns, ns::inner)

    def is_namespace(self, owner: str) -> bool:
        return any(ns == owner or ns.endswith("::" + owner) for ns in self.namespaces)

    def class_named(self, owner: str) -> CppClass | None:
        for cls in self.classes:
            if cls.name == owner or cls.name.endswith("::" + owner):
                return cls
        return None
