"""Composing chains once per configuration, so that calls do no look-ups.

Two pieces of machinery, both applied when a configuration is composed, never per call:

- *Relinking `proceed`*: a partial that calls ``proceed(...)`` by name gets a copy of
  its code in which that global name is renamed to a fresh module global bound to the
  next implementation of this chain. The call ``proceed(x)`` is then an ordinary
  call of the next function. A partial that reaches `proceed` some other way (as an
  attribute, through a helper) falls back to a context variable set around it.
- *Installing the head*: the stable function object users hold (in a class or a
  module) gets the head's code assigned to its ``__code__`` when both share globals,
  closure and defaults, so a layered call is a plain call. Otherwise it runs a
  one-line trampoline to the head, held in a fresh module global.
"""

from __future__ import annotations

import dis
import functools
import inspect
import itertools
import sys
from collections.abc import Callable
from contextvars import ContextVar
from types import CodeType, FunctionType
from typing import Any

from contextros.errors import LayerDefinitionError, ProceedError

_keys = itertools.count(1)
_next_implementation: ContextVar[Callable[..., Any] | None] = ContextVar(
    "contextros_next_implementation", default=None
)

_GLOBAL_READS = frozenset({"LOAD_GLOBAL", "LOAD_NAME"})
_GLOBAL_WRITES = frozenset({"STORE_GLOBAL", "DELETE_GLOBAL", "STORE_NAME", "DELETE_NAME"})
_ATTRIBUTE_OPS = frozenset({"LOAD_METHOD", "IMPORT_NAME", "IMPORT_FROM"})


def proceed(*args: Any, **kwargs: Any) -> Any:
    """Run the next implementation in the chain: the next older active layer's partial,
    else the base.

    Call it by name inside a partial's body; the chain is bound when the configuration
    is composed, so this costs a plain call.
    """
    following = _next_implementation.get()
    if following is None:
        raise ProceedError(
            "proceed() called outside a partial method: call it by name in the body of a "
            "function registered with .partial(layer), not from the base or a plain function"
        )
    token = _next_implementation.set(None)
    try:
        return following(*args, **kwargs)
    finally:
        _next_implementation.reset(token)


def fresh_key(kind: str) -> str:
    return f"__contextros_{kind}_{next(_keys)}"


class ProceedUse:
    """How a partial's code reaches `proceed` (analysed once, at registration)."""

    __slots__ = ("direct", "names")

    def __init__(self, names: frozenset[str], direct: bool) -> None:
        self.names = names
        self.direct = direct


def analyse(function: FunctionType) -> ProceedUse:
    namespace = function.__globals__
    candidates = {
        name
        for name in _all_names(function.__code__)
        if namespace.get(name, proceed if name == "proceed" else None) is proceed
    }
    if not candidates:
        return ProceedUse(frozenset(), direct=True)
    only_read_as_globals = all(
        _reads_only_as_global(code, candidates) for code in _code_tree(function.__code__)
    )
    return ProceedUse(frozenset(candidates), direct=only_read_as_globals)


def _code_tree(code: CodeType) -> list[CodeType]:
    found = [code]
    for const in code.co_consts:
        if isinstance(const, CodeType):
            found.extend(_code_tree(const))
    return found


def _all_names(code: CodeType) -> set[str]:
    return {name for part in _code_tree(code) for name in part.co_names}


def _reads_only_as_global(code: CodeType, names: set[str]) -> bool:
    for instruction in dis.get_instructions(code):
        if instruction.argval not in names:
            continue
        opname = instruction.opname
        if opname in _GLOBAL_READS:
            continue
        if opname in _GLOBAL_WRITES or opname in _ATTRIBUTE_OPS or "ATTR" in opname:
            return False
    return True


def _renamed(code: CodeType, names: frozenset[str], key: str) -> CodeType:
    return code.replace(
        co_names=tuple(key if name in names else name for name in code.co_names),
        co_consts=tuple(
            _renamed(const, names, key) if isinstance(const, CodeType) else const
            for const in code.co_consts
        ),
    )


def copy_function(function: FunctionType, code: CodeType | None = None) -> FunctionType:
    """A new function object like `function` (same globals, closure, defaults, metadata)."""
    copy = FunctionType(
        code or function.__code__,
        function.__globals__,
        function.__name__,
        function.__defaults__,
        function.__closure__,
    )
    copy.__kwdefaults__ = function.__kwdefaults__
    copy.__qualname__ = function.__qualname__
    copy.__doc__ = function.__doc__
    copy.__module__ = function.__module__
    copy.__annotations__ = dict(function.__annotations__)
    copy.__dict__.update(function.__dict__)
    return copy


def link(
    partial: FunctionType, use: ProceedUse, following: Callable[..., Any]
) -> Callable[..., Any]:
    """`partial` with its `proceed` bound to `following`."""
    if not use.names:
        return partial
    if use.direct:
        key = fresh_key("proceed")
        partial.__globals__[key] = following
        return copy_function(partial, _renamed(partial.__code__, use.names, key))

    @functools.wraps(partial)
    def linked(*args: Any, **kwargs: Any) -> Any:
        token = _next_implementation.set(following)
        try:
            return partial(*args, **kwargs)
        finally:
            _next_implementation.reset(token)

    return linked


def _cells_match(a: tuple[Any, ...] | None, b: tuple[Any, ...] | None) -> bool:
    if not a and not b:
        return True
    if a is None or b is None or len(a) != len(b):
        return False
    for left, right in zip(a, b, strict=False):
        if left is right:
            continue
        try:
            if left.cell_contents is not right.cell_contents:
                return False
        except ValueError:  # an empty cell
            return False
    return True


_PLAIN_CONSTANTS = (int, float, complex, str, bytes, bool, type(None))


def _same_value(a: object, b: object) -> bool:
    if a is b:
        return True
    return type(a) is type(b) and isinstance(a, _PLAIN_CONSTANTS) and a == b


def _same_defaults(a: tuple[Any, ...] | None, b: tuple[Any, ...] | None) -> bool:
    a, b = a or (), b or ()
    return len(a) == len(b) and all(_same_value(x, y) for x, y in zip(a, b, strict=False))


def _same_kwdefaults(a: dict[str, Any] | None, b: dict[str, Any] | None) -> bool:
    a, b = a or {}, b or {}
    return a.keys() == b.keys() and all(_same_value(a[k], b[k]) for k in a)


def can_take_code_of(stable: FunctionType, head: object) -> bool:
    """Whether `stable.__code__ = head.__code__` runs exactly what calling `head` runs."""
    return (
        isinstance(head, FunctionType)
        and head.__globals__ is stable.__globals__
        and head.__code__.co_freevars == stable.__code__.co_freevars
        and _cells_match(head.__closure__, stable.__closure__)
        and _same_defaults(head.__defaults__, stable.__defaults__)
        and _same_kwdefaults(head.__kwdefaults__, stable.__kwdefaults__)
    )


_ARGUMENT_FLAGS = inspect.CO_VARARGS | inspect.CO_VARKEYWORDS


def _keyword_only(code: CodeType) -> tuple[str, ...]:
    start = code.co_argcount
    return code.co_varnames[start : start + code.co_kwonlyargcount]


def same_parameters(stable: FunctionType, signature: CodeType, head: object) -> bool:
    """Whether `head` takes exactly the parameters (kinds, keyword names, defaults) of
    `signature` as installed in `stable`, so passing each one through is exact."""
    if not isinstance(head, FunctionType):
        return False
    code = head.__code__
    return (
        code.co_argcount == signature.co_argcount
        and code.co_posonlyargcount == signature.co_posonlyargcount
        and code.co_flags & _ARGUMENT_FLAGS == signature.co_flags & _ARGUMENT_FLAGS
        and _keyword_only(code) == _keyword_only(signature)
        and _same_defaults(head.__defaults__, stable.__defaults__)
        and _same_kwdefaults(head.__kwdefaults__, stable.__kwdefaults__)
    )


def passing_through(signature: CodeType) -> tuple[str, str]:
    """(parameter list, argument list) that pass every parameter of `signature` on."""
    names = signature.co_varnames
    positional = list(names[: signature.co_argcount])
    keyword = list(_keyword_only(signature))
    index = signature.co_argcount + signature.co_kwonlyargcount
    star = names[index] if signature.co_flags & inspect.CO_VARARGS else None
    index += 1 if star else 0
    double_star = names[index] if signature.co_flags & inspect.CO_VARKEYWORDS else None
    parameters = list(positional)
    if signature.co_posonlyargcount:
        parameters.insert(signature.co_posonlyargcount, "/")
    if star:
        parameters.append(f"*{star}")
    elif keyword:
        parameters.append("*")
    parameters += keyword
    arguments = list(positional) + ([f"*{star}"] if star else []) + [f"{k}={k}" for k in keyword]
    if double_star:
        parameters.append(f"**{double_star}")
        arguments.append(f"**{double_star}")
    return ", ".join(parameters), ", ".join(arguments)


def trampoline_code(
    body: list[str], freevars: tuple[str, ...], qualname: str, parameters: str = "*args, **kwargs"
) -> CodeType:
    """Code for `def f(<parameters>): <body>` whose free variables are `freevars`.

    The free variables only match the stable function's closure (its __code__ must keep
    their number); the body never reads them. Parameter defaults come from the stable
    function object, not from this code.
    """
    lines = ["def __contextros_outer():"]
    lines += [f"    {name} = None" for name in freevars]
    lines += [f"    def __contextros_dispatch({parameters}):"]
    if freevars:
        lines += [f"        {', '.join(freevars)}"]
    lines += [f"        {line}" for line in body]
    lines += ["    return __contextros_dispatch"]
    module = compile("\n".join(lines), f"<contextros dispatch of {qualname}>", "exec")
    outer = next(c for c in module.co_consts if isinstance(c, CodeType))
    inner = next(c for c in outer.co_consts if isinstance(c, CodeType))
    if inner.co_freevars != freevars:
        raise LayerDefinitionError(
            f"cannot build a dispatcher for {qualname}: its closure {freevars} is not supported"
        )
    inner = inner.replace(co_name=qualname.rpartition(".")[2])
    if sys.version_info >= (3, 11):
        inner = inner.replace(co_qualname=qualname)
    return inner
