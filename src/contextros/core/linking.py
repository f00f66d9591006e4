"""Composing chains once per configuration, so that calls do no look-ups.

Two pieces of machinery, both applied when a configuration is composed, never per call:

- *Relinking `proceed`*: a partial that calls ``proceed(...)`` by name gets a copy of
  its code in which that global name is renamed to a fresh module global bound to the
  next implementation of this chain. The call ``proceed(x)`` is then an ordinary
  call of the next function. Every linked partial gets a code object of its own, and
  the table `_following` maps it to the next implementation, so a partial that reaches
  `proceed` some other way (as an attribute, or from a helper function it calls) is
  found by walking the caller's frames up to the nearest linked partial (slower, but
  nothing is done for it per call of the partial itself).
- *Installing the head*: the stable function object users hold (in a class or a
  module) gets the head's code assigned to its ``__code__`` when both share globals,
  closure and defaults, so a layered call is a plain call. Otherwise it runs a
  one-line trampoline to the head, held in a fresh module global.
"""

from __future__ import annotations

import dis
import inspect
import itertools
import sys
import weakref
from collections.abc import Callable
from types import CodeType, FunctionType
from typing import Any

from contextros.errors import LayerDefinitionError, ProceedError

_keys = itertools.count(1)
# id(code) -> (weak reference to that code, the next implementation, or None for a base):
# what `proceed` finds when it is not called by name in a partial's own body.
_following: dict[int, tuple[weakref.ref[CodeType], Callable[..., Any] | None]] = {}

_GLOBAL_READS = frozenset({"LOAD_GLOBAL", "LOAD_NAME"})
_GLOBAL_WRITES = frozenset({"STORE_GLOBAL", "DELETE_GLOBAL", "STORE_NAME", "DELETE_NAME"})
_ATTRIBUTE_OPS = frozenset({"LOAD_METHOD", "IMPORT_NAME", "IMPORT_FROM"})


def proceed(*args: Any, **kwargs: Any) -> Any:
    """Run the next implementation in the chain: the next older active layer's partial,
    else the base.

    Call it by name inside a partial's body; the chain is bound when the configuration
    is composed, so this costs a plain call. Called any other way (``contextros.proceed``,
    or from a helper function the partial calls), it finds the nearest partial among its
    callers' frames and runs that partial's next implementation.
    """
    frame = sys._getframe(1)
    while frame is not None:
        code = frame.f_code
        entry = _following.get(id(code))
        if entry is not None and entry[0]() is code:
            following = entry[1]
            if following is None:
                break  # reached from a base implementation: nothing to proceed to
            return following(*args, **kwargs)
        frame = frame.f_back  # type: ignore[assignment]
    raise ProceedError(
        "proceed() called outside a partial method: call it in the body of a function "
        "registered with .partial(layer), or in a helper that such a function calls; "
        "not from a base implementation or a plain function"
    )


def remember(code: CodeType, following: Callable[..., Any] | None) -> None:
    key = id(code)

    def forget(_: object, key: int = key) -> None:
        _following.pop(key, None)

    _following[key] = (weakref.ref(code, forget), following)


def mark_base(function: FunctionType) -> None:
    """`proceed` reached from `function` (a base implementation) is an error, even when a
    partial further up the stack proceeded to it."""
    remember(function.__code__, None)


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
    """`partial` with its `proceed` bound to `following`, as a function of its own."""
    if use.names and use.direct:
        key = fresh_key("proceed")
        partial.__globals__[key] = following
        code = _renamed(partial.__code__, use.names, key)
    else:
        code = partial.__code__.replace()  # a code object of its own: the frame names the link
    if code is partial.__code__:  # pragma: no cover - replace() always copies in CPython
        code = code.replace(co_consts=(*code.co_consts, fresh_key("link")))
    remember(code, following)
    return copy_function(partial, code)


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


_OPS = {
    name: dis.opmap.get(name, -1)
    for name in (
        "LOAD_GLOBAL",
        "LOAD_FAST",
        "RESUME",
        "PRECALL",
        "CALL",
        "RETURN_VALUE",
        "POP_JUMP_FORWARD_IF_TRUE",
        "POP_JUMP_FORWARD_IF_NONE",
        "JUMP_FORWARD",
        "BINARY_SUBSCR",
        "PUSH_NULL",
        "SWAP",
    )
}
# Opcodes an inlined guard may not run: in the partial's frame they would write its locals
# (its arguments: `n := ...`, `del n`) or use cells. Reading its parameters is all it may do.
_WRITES_LOCALS = frozenset(
    op
    for op in (*dis.haslocal, *dis.hasfree)
    if dis.opname[op] not in ("LOAD_FAST", "LOAD_FAST_CHECK")
)
_NO_LOCATION = 0xF8  # a line-table entry of CPython 3.11 with no location, one code unit long
_NOT_PLAIN = (
    inspect.CO_VARARGS
    | inspect.CO_VARKEYWORDS
    | inspect.CO_GENERATOR
    | inspect.CO_COROUTINE
    | inspect.CO_ASYNC_GENERATOR
    | inspect.CO_ITERABLE_COROUTINE
)


def _op(name: str, argument: int = 0) -> list[int]:
    """One instruction of CPython 3.11 with its inline caches, as bytes."""
    code = _OPS[name]
    return [code, argument] + [0, 0] * dis._inline_cache_entries[code]  # type: ignore[attr-defined]


def _call(count: int) -> list[int]:
    """Call what is below the first `count` locals on the stack with them."""
    loads = [byte for i in range(count) for byte in _op("LOAD_FAST", i)]
    return loads + _op("PRECALL", count) + _op("CALL", count)


def _varint(value: int, signed: bool = False) -> bytes:
    """A number of CPython 3.11's location table."""
    if signed:
        value = (-value << 1) | 1 if value < 0 else value << 1
    out = bytearray()
    while value >= 64:
        out.append(0x40 | (value & 63))
        value >>= 6
    out.append(value)
    return bytes(out)


Position = tuple[int | None, int | None, int | None, int | None]


def _locations(positions: list[Position], line: int) -> tuple[bytes, int]:
    """Location-table entries of one code unit each for `positions`, from the table's
    current line `line`; with the line they leave it at."""
    table = bytearray()
    for start, end, column, end_column in positions:
        if start is None or end is None or column is None or end_column is None:
            table.append(_NO_LOCATION)
            continue
        table.append(0x80 | 14 << 3)  # the long form, one code unit
        table += _varint(start - line, signed=True) + _varint(end - start)
        table += _varint(column + 1) + _varint(end_column + 1)
        line = start
    return bytes(table), line


def _prefixed(
    code: CodeType,
    names: tuple[str, ...],
    prefix: list[int],
    stack: int,
    positions: tuple[Position, ...] = (),
) -> CodeType | None:
    """`code` with `prefix` (CPython 3.11 bytecode, reading the globals `names`) run first,
    after RESUME; its first code units at `positions` (source positions), the others with
    none. Only for plain functions (positional-or-keyword parameters, no cells, no
    exception handlers, not a generator or coroutine) on 3.11; None otherwise."""
    table = code.co_linetable
    if (
        sys.version_info[:2] != (3, 11)
        or code.co_flags & _NOT_PLAIN
        or code.co_kwonlyargcount
        or code.co_cellvars
        or code.co_freevars
        or code.co_exceptiontable
        or code.co_code[0] != _OPS["RESUME"]
        or not table
        or table[0] & 0x87 != 0x80  # the first entry: RESUME alone
        or code.co_argcount > 255
        or (len(code.co_names) + len(names)) * 2 > 255
        or max(prefix[1::2]) > 255
    ):
        return None
    first = 1 + next((i for i, byte in enumerate(table[1:]) if byte & 0x80), len(table) - 1)
    locations = bytes([_NO_LOCATION]) * (len(prefix) // 2 - len(positions))
    if positions:
        line = next(code.co_positions())[0]
        if line is None:
            return None
        placed, now = _locations(list(positions), line)
        back = bytes([0x80 | 13 << 3]) + _varint(line - now, signed=True)  # no column
        locations = placed + back + locations[1:]
    return code.replace(
        co_code=code.co_code[:2] + bytes(prefix) + code.co_code[2:],
        co_names=(*code.co_names, *names),
        co_linetable=table[:first] + locations + table[first:],
        co_stacksize=max(code.co_stacksize, stack),
    )


def _inlined_guard(
    guard: object, code: CodeType, namespace: dict[str, Any], first_name: int
) -> list[int] | None:
    """The bytecode of `guard`'s body, to run in a frame of `code` (its parameters are the
    first locals of both) with `guard`'s names from index `first_name` of the names and its
    constants after `code`'s, leaving its result on the stack. None unless `guard` is a
    plain function of `namespace` (`code`'s module) taking exactly `code`'s positional
    parameters and no other local, and reading them only (a guard assigning or deleting
    one would change the partial's arguments: it is called instead)."""
    if not isinstance(guard, FunctionType):
        return None
    own = guard.__code__
    if (
        guard.__globals__ is not namespace
        or own.co_flags & _NOT_PLAIN
        or own.co_argcount != code.co_argcount
        or own.co_kwonlyargcount
        or own.co_nlocals != own.co_argcount
        or own.co_cellvars
        or own.co_freevars
        or own.co_exceptiontable  # type: ignore[attr-defined]
        or own.co_code[0] != _OPS["RESUME"]
    ):
        return None
    body = list(own.co_code[2:])
    end = len(body) // 2
    for unit in range(end):
        op, argument = body[2 * unit], body[2 * unit + 1]
        if op == dis.opmap["EXTENDED_ARG"] or op in _WRITES_LOCALS:
            return None
        if op == _OPS["RETURN_VALUE"]:  # on to the test of the result
            op, argument = _OPS["JUMP_FORWARD"], end - unit - 1
        elif op == _OPS["LOAD_GLOBAL"]:
            argument = (first_name + (argument >> 1)) << 1 | (argument & 1)
        elif op in dis.hasname:
            argument += first_name
        elif op in dis.hasconst:
            argument += len(code.co_consts)
        if argument > 255:
            return None
        body[2 * unit], body[2 * unit + 1] = op, argument
    return body


def guarded_code(
    function: FunctionType, guard: Callable[..., object], names: tuple[str, str]
) -> CodeType | None:
    """`function`'s code (a partial's) opening with `if not guard(args): return
    skipped(args)`, `names` being the global names of the guard and of what is skipped to:
    a guarded partial in one frame, not behind a dispatcher of its own. A plain guard of
    the partial's module (such as a lambda) has its body run in that frame too: no call.
    None where `_prefixed` cannot write it."""
    code = function.__code__
    count, index = code.co_argcount, len(code.co_names)
    skip = _op("LOAD_GLOBAL", (index + 1) << 1 | 1) + _call(count) + _op("RETURN_VALUE")
    test = _inlined_guard(guard, code, function.__globals__, index + 2)
    if test is not None:
        own = guard.__code__  # type: ignore[attr-defined]
        prefix = test + _op("POP_JUMP_FORWARD_IF_TRUE", len(skip) // 2) + skip
        # The guard's own source positions: an error in it points at the guard.
        same_file = own.co_filename == code.co_filename
        positions = tuple(own.co_positions())[1:] if same_file else ()  # type: ignore[attr-defined]
        stack = max(count + 2, own.co_stacksize)
        inlined = _prefixed(code, (*names, *own.co_names), prefix, stack, positions)
        if inlined is not None:
            return inlined.replace(co_consts=(*code.co_consts, *own.co_consts))
    test = _op("LOAD_GLOBAL", index << 1 | 1) + _call(count)
    prefix = test + _op("POP_JUMP_FORWARD_IF_TRUE", len(skip) // 2) + skip
    return _prefixed(code, names, prefix, count + 2)


def inline_head_code(code: CodeType, find: str, receiver: bool) -> CodeType | None:
    """`code` (a head's) opening with `if <find>[key] is not None: return <find>(key)(args)`,
    `find` being a global name (a C Finder whose subscript gives None for this head) and key
    the first parameter (`receiver`) or `find` itself: a dispatcher that runs the head it
    expects in its own frame (None where `_prefixed` cannot write it)."""
    count, index = code.co_argcount, len(code.co_names)
    if receiver and not count:
        return None
    key = _op("LOAD_FAST", 0) if receiver else _op("LOAD_GLOBAL", index << 1)
    other = _op("LOAD_GLOBAL", index << 1 | 1) + key + _op("PRECALL", 1) + _op("CALL", 1)
    other += _op("PUSH_NULL") + _op("SWAP", 2) + _call(count) + _op("RETURN_VALUE")
    prefix = _op("LOAD_GLOBAL", index << 1) + key + _op("BINARY_SUBSCR")
    prefix += _op("POP_JUMP_FORWARD_IF_NONE", len(other) // 2) + other
    return _prefixed(code, (find,), prefix, count + 3)


def remember_like(code: CodeType, function: FunctionType) -> None:
    """`proceed` reached from a frame of `code` runs what it runs from `function`'s."""
    entry = _following.get(id(function.__code__))
    if entry is not None and entry[0]() is function.__code__:
        remember(code, entry[1])
