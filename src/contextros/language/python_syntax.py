"""The Python flavour's part of the syntax tree: implementations with their `ast` nodes.

The parser builds `PythonFunction`s; their language-neutral data (signature shape, calls of
`proceed`, decorators) is derived here from Python's own syntax tree, so the checker never
looks at `ast` nodes.
"""

from __future__ import annotations

import ast
import copy
from dataclasses import dataclass

from contextros.language.syntax import (
    Decorator,
    Function,
    Guard,
    Position,
    ProceedCall,
    Signature,
    SourceLine,
)


@dataclass
class PythonFunction(Function):
    """An implementation in the Python flavour: its parsed node and its (renamed) lines."""

    node: ast.FunctionDef | ast.AsyncFunctionDef | None = None
    lines: tuple[SourceLine, ...] = ()
    # The guard's condition, piece by piece (one per line it spans), with file positions.
    guard_lines: tuple[SourceLine, ...] = ()


def python_function(
    *,
    name: str,
    owner: str | None,
    layer: str | None,
    at: Position,
    node: ast.FunctionDef | ast.AsyncFunctionDef,
    lines: list[SourceLine],
    generated_name: str,
    guard: Guard | None = None,
    guard_lines: tuple[SourceLine, ...] = (),
) -> PythonFunction:
    args = node.args
    first = [*args.posonlyargs, *args.args][:1]
    return PythonFunction(
        name=name,
        owner=owner,
        layer=layer,
        at=at,
        generated_name=generated_name,
        signature=Signature(
            signature_shape(node),
            signature_text(node, f"{owner}.{name}" if owner else name),
            isinstance(node, ast.AsyncFunctionDef),
        ),
        proceed_calls=_proceed_calls(node, lines, first[0].arg if first else None),
        decorators=tuple(
            Decorator(ast.unparse(d), _position(d, lines)) for d in node.decorator_list
        ),
        takes_instance=bool(args.posonlyargs or args.args or args.vararg),
        instance_name=first[0].arg if first else "self",
        node=node,
        lines=tuple(lines),
        guard=guard,
        guard_lines=guard_lines,
    )


def guard_name(function: Function) -> str:
    """The compiled name of an implementation's guard."""
    return f"{function.generated_name}__when"


def guard_function_lines(
    pieces: tuple[SourceLine, ...] | list[SourceLine],
    function: ast.FunctionDef | ast.AsyncFunctionDef,
    name: str,
) -> list[SourceLine | str]:
    """The guard as a function of the implementation's parameters (annotations dropped:
    they are evaluated once, for the implementation): the `def` line as generated text,
    the condition's lines keeping their positions in the layer file."""
    arguments = copy.deepcopy(function.args)
    for argument in [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]:
        argument.annotation = None
    for extra in (arguments.vararg, arguments.kwarg):
        if extra is not None:
            extra.annotation = None
    out: list[SourceLine | str] = [f"def {name}({ast.unparse(arguments)}):"]
    for index, piece in enumerate(pieces):
        if index == 0:  # the condition starts after the blank(s) that follow `when`
            text = piece.text.lstrip()
            piece = SourceLine(text, piece.line, piece.delta + len(piece.text) - len(text))
        prefix = "    return (" if index == 0 else "        "
        suffix = ")" if index == len(pieces) - 1 else ""
        out.append(SourceLine(prefix + piece.text + suffix, piece.line, piece.delta - len(prefix)))
    return out


def signature_shape(node: ast.FunctionDef | ast.AsyncFunctionDef) -> tuple[object, ...]:
    """What callers rely on: parameter kinds, names and which ones have defaults."""
    args = node.args
    positional = [*args.posonlyargs, *args.args]
    with_default = len(positional) - len(args.defaults)
    return (
        tuple(a.arg for a in args.posonlyargs),
        tuple((a.arg, i >= with_default) for i, a in enumerate(positional)),
        args.vararg is not None,
        tuple(
            (a.arg, d is not None) for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True)
        ),
        args.kwarg is not None,
    )


def signature_text(node: ast.FunctionDef | ast.AsyncFunctionDef, key: str) -> str:
    prefix = "async " if isinstance(node, ast.AsyncFunctionDef) else ""
    return f"{prefix}{key}({ast.unparse(node.args)})"


def _proceed_calls(
    node: ast.FunctionDef | ast.AsyncFunctionDef, lines: list[SourceLine], instance: str | None
) -> tuple[ProceedCall, ...]:
    calls: list[ProceedCall] = []
    for call in ast.walk(node):
        if not (
            isinstance(call, ast.Call)
            and isinstance(call.func, ast.Name)
            and call.func.id == "proceed"
        ):
            continue
        first = call.args[0] if call.args else None
        passes = isinstance(first, ast.Starred) or (
            isinstance(first, ast.Name) and first.id == instance
        )
        calls.append(ProceedCall(_position(call, lines), passes))
    return tuple(calls)


def _position(node: ast.expr, lines: list[SourceLine]) -> Position:
    """Where `node` of an implementation's parsed lines is in the layer file."""
    index = min(max(node.lineno, 1), len(lines)) - 1
    line = lines[index]
    return Position(line.line, line.char_column(line.char_of_byte(node.col_offset)) + 1)


def header_names(module: ast.Module | None) -> tuple[set[str], bool]:
    """Names the header binds at module level, and whether a `*` import hides some."""
    names: set[str] = set()
    star = False
    pending: list[ast.stmt] = list(module.body) if module is not None else []
    while pending:
        stmt = pending.pop()
        if isinstance(stmt, (ast.Import, ast.ImportFrom)):
            for alias in stmt.names:
                if alias.name == "*":
                    star = True
                else:
                    names.add(alias.asname or alias.name.split(".")[0])
        elif isinstance(stmt, (ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            names.add(stmt.name)
        elif isinstance(stmt, (ast.If, ast.Try, ast.With, ast.For, ast.While)):
            for attr in ("body", "orelse", "finalbody", "handlers"):
                pending.extend(getattr(stmt, attr, []))
        elif isinstance(stmt, ast.ExceptHandler):
            pending.extend(stmt.body)
        if isinstance(stmt, (ast.Assign, ast.AnnAssign, ast.AugAssign, ast.For, ast.With)):
            for node in ast.walk(stmt):
                if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                    names.add(node.id)
    return names, star
