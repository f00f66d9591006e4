"""The composition state of one layered function: its partials and the chains composed
from them, installed into the stable function users hold.

It depends on the runtime only through `Host` (what it needs from whoever holds the active
configuration), so the runtime imports this module and never the other way round.
"""

from __future__ import annotations

import importlib
import inspect
import os
import warnings
import weakref
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager
from types import CodeType, FunctionType, MappingProxyType
from typing import Any, Protocol, TypeVar

from contextros.core.configuration import Configuration
from contextros.core.layer import Layer, resolve
from contextros.core.linking import (
    ProceedUse,
    analyse,
    can_take_code_of,
    copy_function,
    fresh_key,
    guarded_code,
    inline_head_code,
    link,
    mark_base,
    passing_through,
    proceed,
    remember,
    remember_like,
    same_parameters,
    trampoline_code,
)
from contextros.errors import LayerDefinitionError, NoImplementationError, ProceedError

F = TypeVar("F", bound=Callable[..., Any])


_ABI = 2  # the version of `_dispatch.c` this module drives


def _finder_type() -> Any:
    """The C look-up of the scoped and per-receiver dispatchers (`_dispatch.c`), or None:
    not built, built from other sources (warned), or CONTEXTROS_PURE_PYTHON=1; the
    dispatchers are then pure Python."""
    if os.environ.get("CONTEXTROS_PURE_PYTHON", "") not in ("", "0"):
        return None
    try:  # by its full name, not through contextros.core's namespace (an import circle)
        _dispatch = importlib.import_module("contextros.core._dispatch")
    except ImportError:
        return None
    if getattr(_dispatch, "ABI", None) != _ABI:
        warnings.warn(
            f"contextros: {_dispatch.__file__} was built from other sources than this "
            "package's (`make` builds it again); the core uses its pure-Python dispatchers",
            RuntimeWarning,
            stacklevel=1,
        )
        return None
    return _dispatch.Finder


_FINDER = _finder_type()
# Which dispatcher the scoped and per-receiver paths use: "c" or "python".
DISPATCHER = "python" if _FINDER is None else "c"


class Host(Protocol):
    """What a layered function needs from the runtime that adopted it."""

    @property
    def lock(self) -> AbstractContextManager[Any]: ...

    def rewire(self, function: LayeredFunction) -> None: ...

    def effective(self, receiver: object = None) -> Configuration: ...


class _Partials:
    """One published set of partials: each function with its `proceed` analysis, and the
    chains composed from exactly these (by the ordered names of the layers that refine).

    Never changed once published (only `chains`, a cache of this set's own chains, grows):
    adding, replacing or removing a partial publishes a new one, so a call composing its
    chain without the runtime's lock reads one consistent set, and a chain composed from
    a replaced partial can only be cached in the set it was composed from."""

    __slots__ = ("chains", "functions", "guards", "uses")

    def __init__(
        self,
        functions: dict[str, FunctionType],
        uses: dict[str, ProceedUse],
        guards: dict[str, Callable[..., object]],
    ) -> None:
        self.functions = functions
        self.uses = uses
        self.guards = guards  # by layer name, only for guarded partials
        self.chains: dict[tuple[str, ...], Callable[..., Any]] = {}


class LayeredFunction:
    """The composition state behind one layered function or method.

    Users never hold this object: they hold `stable`, a plain function that stays the
    same object for the program's life (so bound methods captured by timers and
    callbacks follow every switch) while its behaviour is recomposed per configuration.

    Chains are composed once per configuration and cached by the ordered tuple of the
    active layers that refine this function; layers without a partial here are
    transparent and share a chain.
    """

    def __init__(self, stub: FunctionType, base: FunctionType | None, host: Host) -> None:
        self.qualname = stub.__qualname__
        self._host = host
        self.base = base
        if base is not None:
            mark_base(base)
        self._published = _Partials({}, {}, {})
        self.stable = copy_function(stub)
        self._freevars = stub.__code__.co_freevars
        self._head_key = fresh_key("head")
        self._scope_key = fresh_key("scope")
        self._runtime_key = fresh_key("runtime")
        self._self_key = fresh_key("layered")
        call_head = f"return {self._head_key}(*args, **kwargs)"
        self._direct_code = trampoline_code([call_head], self._freevars, self.qualname)
        self._signature = stub.__code__
        parameters, arguments = passing_through(stub.__code__)
        self._exact_code = trampoline_code(
            [f"return {self._head_key}({arguments})"], self._freevars, self.qualname, parameters
        )
        self._find_key = fresh_key("find")
        # The C dispatchers with a head's code inlined, by that head and receiver or not,
        # each with the global name of its own Finder (which expects that head).
        self._inlined: weakref.WeakKeyDictionary[
            FunctionType, dict[bool, tuple[CodeType, str] | None]
        ] = weakref.WeakKeyDictionary()
        self._objects_key = fresh_key("objects")
        self._classes_key = fresh_key("classes")
        # "" (no receiver has layers of its own), "object" or "class" (a classmethod).
        self.receiver_kind = ""
        # The scoped and per-receiver dispatchers: taking *args/**kwargs (any partials),
        # and passing each parameter straight on, which saves building a tuple and a dict
        # per call but is exact only while every implementation takes the stub's parameters
        # with the same defaults (`_uniform`).
        self._scoped_code = self._scoped_dispatcher("*args, **kwargs", "*args, **kwargs")
        self._receiver_code = self._receiver_dispatchers("*args, **kwargs", "*args, **kwargs", "")
        self._scoped_exact_code = self._scoped_dispatcher(parameters, arguments)
        first = stub.__code__.co_varnames[:1] if stub.__code__.co_argcount else ()
        self._receiver_exact_code = (
            self._receiver_dispatchers(parameters, arguments, first[0]) if first else None
        )
        self._uniform = True
        self.stable.__wrapped__ = stub  # type: ignore[attr-defined]
        self.stable.partial = self.partial  # type: ignore[attr-defined]
        self.stable.before = self.before  # type: ignore[attr-defined]
        self.stable.after = self.after  # type: ignore[attr-defined]
        self.stable.around = self.around  # type: ignore[attr-defined]
        self.stable.remove_partial = self.remove_partial  # type: ignore[attr-defined]
        self.stable.__contextros__ = self  # type: ignore[attr-defined]
        # A classmethod or staticmethod wrapping `stable`, when it was layered as one.
        self.descriptor: classmethod[Any, Any, Any] | staticmethod[Any, Any] | None = None
        self.global_head: Callable[..., Any] = self._missing()

    def _scoped_dispatcher(self, parameters: str, arguments: str) -> CodeType:
        """Calls read the caller's scope first; one with no scope in a process with none
        alive puts the direct path back (in C: the Finder does both)."""
        if _FINDER is not None:
            return trampoline_code(
                [f"return {self._find_key}[None]({arguments})"],
                self._freevars,
                self.qualname,
                parameters,
            )
        return trampoline_code(
            [
                f"__contextros_scope = {self._scope_key}.get()",
                "if __contextros_scope is None:",
                f"    if not {self._runtime_key}._live_scopes:",
                f"        {self._runtime_key}.back_to_direct({self._self_key})",
                f"    return {self._head_key}({arguments})",
                *self._through_scope(arguments),
            ],
            self._freevars,
            self.qualname,
            parameters,
        )

    def _through_scope(self, arguments: str) -> list[str]:
        """The end of a dispatcher: call the head of `__contextros_scope`'s configuration."""
        return [
            "try:",
            f"    __contextros_head = __contextros_scope.heads[{self._self_key}]",
            "except KeyError:",
            f"    __contextros_head = __contextros_scope.head({self._self_key})",
            f"return __contextros_head({arguments})",
        ]

    def _receiver_dispatchers(
        self, parameters: str, arguments: str, receiver: str
    ) -> dict[str, CodeType]:
        """Calls look up their receiver's own layers first (per-object, then class-wide),
        then the caller's scope. `receiver` names the first parameter ("": `args[0]`)."""
        codes: dict[str, CodeType] = {}
        if _FINDER is not None:  # the Finder knows the kind
            lookup = (
                f"{self._find_key}[{receiver}]"
                if receiver
                else f"({self._find_key}[args[0]] if args else {self._find_key}())"
            )
            code = trampoline_code(
                [f"return {lookup}({arguments})"], self._freevars, self.qualname, parameters
            )
            return {"object": code, "class": code}
        for kind in ("object", "class"):
            target = receiver or "args[0]"
            cls = f"type({target})" if kind == "object" else target
            find = [
                f"__contextros_r = {self._objects_key}.get(id({target}))",
                "if __contextros_r is None:",
                f"    __contextros_r = {self._classes_key}[{cls}]",
            ]
            if not receiver:
                find = ["__contextros_r = None", "if args:", *[f"    {line}" for line in find]]
            codes[kind] = trampoline_code(
                [
                    *find,
                    # No scope alive anywhere (the usual case): no context variable to read.
                    f"__contextros_scope = {self._scope_key}.get() "
                    f"if {self._runtime_key}._live_scopes else None",
                    "if __contextros_r is not None:",
                    "    if __contextros_scope is None:",
                    "        try:",
                    f"            __contextros_head = __contextros_r.heads[{self._self_key}]",
                    "        except KeyError:",
                    f"            __contextros_head = __contextros_r.head({self._self_key}, None)",
                    f"        return __contextros_head({arguments})",
                    f"    return __contextros_r.head({self._self_key}, __contextros_scope)"
                    f"({arguments})",
                    "if __contextros_scope is None:",
                    f"    return {self._head_key}({arguments})",
                    *self._through_scope(arguments),
                ],
                self._freevars,
                self.qualname,
                parameters,
            )
        return codes

    def __repr__(self) -> str:
        return f"<layered {self.qualname} partials={sorted(self.partials)}>"

    @property
    def partials(self) -> Mapping[str, FunctionType]:
        """The partials by layer name (a read-only view of the published set)."""
        return MappingProxyType(self._published.functions)

    # -- definition ----------------------------------------------------------------------

    def partial(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[F], F]:
        """Decorator registering the partial implementation of this function for `layer`.

        Returns the layered function itself (for a layered classmethod or staticmethod,
        that descriptor), so the name stays bound to it in a class body or module. The
        partial may itself be decorated with @classmethod / @staticmethod, to match.

        `when` is a guard: called with each call's arguments (as the partial would be);
        while it returns false the partial is skipped and the call goes to the next
        implementation of the chain, as if this layer had no partial here.
        """
        target = resolve(layer)
        if when is not None and not callable(when):
            raise LayerDefinitionError(
                f"the guard (when=) of {self.qualname}'s partial for layer {target.name} "
                f"must be callable with the call's arguments, got {when!r}"
            )

        def register(function: F) -> F:
            plain: object = function
            if isinstance(plain, (classmethod, staticmethod)):
                plain = plain.__func__
            if isinstance(plain, property):
                plain = plain.fget
            if not isinstance(plain, FunctionType):
                raise LayerDefinitionError(
                    f"partial of {self.qualname} for layer {target.name} must be a plain "
                    f"function, got {function!r}"
                )
            if target.name in self.partials and not replace:
                raise LayerDefinitionError(
                    f"{self.qualname} already has a partial for layer {target.name} "
                    "(pass replace=True to redefine it)"
                )
            self._set_partial(target.name, plain, when)
            return self.public  # type: ignore[return-value]

        return register

    def around(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[F], F]:
        """The same as `partial`: the partial runs around the rest of the chain and calls
        `proceed(...)` where the rest should run (ContextPy3's name for it)."""
        return self.partial(layer, replace=replace, when=when)

    def before(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[F], F]:
        """A partial that runs before the rest of the chain, with the same arguments; the
        rest then runs with those arguments and its result is the call's result."""
        register = self.partial(layer, replace=replace, when=when)

        def decorate(function: F) -> F:
            partial: Any = _before(_unwrapped(function), self.is_async)
            return register(partial)  # type: ignore[no-any-return]

        return decorate

    def after(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[F], F]:
        """A partial that runs after the rest of the chain: it is called with the call's
        arguments (`self` first, for a method) and that result by keyword,
        ``function(*args, result=result, **kwargs)`` (write ``def m(self, x, *, result)``),
        and what it returns is the call's result (return `result` to keep it)."""
        register = self.partial(layer, replace=replace, when=when)

        def decorate(function: F) -> F:
            plain = _unwrapped(function)
            _check_after(plain, self.stable.__wrapped__, self.qualname, layer)  # type: ignore[attr-defined]
            partial: Any = _after(plain, self.is_async)
            return register(partial)  # type: ignore[no-any-return]

        return decorate

    def remove_partial(self, layer: Layer | str) -> None:
        """Remove this function's partial for `layer` at run time; calls are rewired at
        once (in every thread, scopes included). KeyError-free: LayerDefinitionError
        when there is none."""
        name = layer.name if isinstance(layer, Layer) else layer
        if name not in self.partials:
            raise LayerDefinitionError(f"{self.qualname} has no partial for layer {name}")
        self._set_partial(name, None)

    def _set_partial(
        self,
        name: str,
        function: FunctionType | None,
        guard: Callable[..., object] | None = None,
    ) -> None:
        use = analyse(function) if function is not None else None  # before publishing
        with self._host.lock:
            current = self._published
            functions, uses = dict(current.functions), dict(current.uses)
            guards = dict(current.guards)
            guards.pop(name, None)
            if function is None or use is None:
                del functions[name]
                del uses[name]
            else:
                functions[name] = function
                uses[name] = use
                if guard is not None:
                    guards[name] = guard
            # One assignment: all or nothing.
            self._published = _Partials(functions, uses, guards)
            implementations = [*functions.values(), *([self.base] if self.base else [])]
            self._uniform = all(
                same_parameters(self.stable, self._signature, f) for f in implementations
            )
            self._host.rewire(self)

    @property
    def is_async(self) -> bool:
        return inspect.iscoroutinefunction(self.stable.__wrapped__)  # type: ignore[attr-defined]

    @property
    def public(self) -> object:
        """What user code holds: the stable function, or the descriptor wrapping it."""
        return self.descriptor if self.descriptor is not None else self.stable

    # -- composition ---------------------------------------------------------------------

    def head_for(self, configuration: Configuration) -> Callable[..., Any]:
        """The first implementation to run under `configuration` (composed once, cached).

        Safe without the runtime's lock: it reads one published set of partials."""
        published = self._published
        functions = published.functions
        relevant = tuple(layer.name for layer in reversed(configuration) if layer.name in functions)
        head = published.chains.get(relevant)
        if head is None:
            head = published.chains[relevant] = self._compose(published, relevant)
        return head

    def _compose(self, published: _Partials, relevant: tuple[str, ...]) -> Callable[..., Any]:
        if not relevant:
            return self.base if self.base is not None else self._missing()
        following: Callable[..., Any] = (
            self.base if self.base is not None else self._exhausted(relevant[-1])
        )
        # What a guarded partial that does not apply passes the call to: the same as its
        # `proceed`, except below the innermost partial of a function without a base.
        skipped: Callable[..., Any] = self.base if self.base is not None else self._missing()
        for name in reversed(relevant):
            linked = link(published.functions[name], published.uses[name], following)
            guard = published.guards.get(name)
            if guard is not None:
                linked = self._guarded(published.functions[name], guard, linked, skipped, following)
            following = skipped = linked
        return following

    def _guarded(
        self,
        partial: FunctionType,
        guard: Callable[..., object],
        linked: Callable[..., Any],
        skipped: Callable[..., Any],
        following: Callable[..., Any],
    ) -> FunctionType:
        """A guarded partial's place in a chain: the partial while the guard holds on the
        call's arguments, else the next implementation (`skipped`).

        Where CPython's bytecode allows (`guarded_code`), the linked partial itself opens
        with the guard's test: one frame. Otherwise a dispatcher generated with the
        partial's own parameters and defaults, in the stable function's module, so that
        the stable function can take its code (no trampoline, no tuple or dict per call)."""
        keys = {kind: fresh_key(kind) for kind in ("guard", "partial", "skipped")}
        assert isinstance(linked, FunctionType)
        merged = guarded_code(linked, guard, (keys["guard"], keys["skipped"]))
        if merged is not None:
            linked.__globals__[keys["guard"]] = guard
            linked.__globals__[keys["skipped"]] = skipped
            remember(merged, following)
            return copy_function(linked, merged)
        parameters, arguments = passing_through(partial.__code__)
        namespace = self.stable.__globals__
        namespace[keys["guard"]] = guard
        namespace[keys["partial"]] = linked
        namespace[keys["skipped"]] = skipped
        code = trampoline_code(
            [
                f"if {keys['guard']}({arguments}):",
                f"    return {keys['partial']}({arguments})",
                f"return {keys['skipped']}({arguments})",
            ],
            self._freevars,
            self.qualname,
            parameters,
        )
        guarded = FunctionType(
            code, namespace, partial.__name__, partial.__defaults__, self.stable.__closure__
        )
        guarded.__kwdefaults__ = partial.__kwdefaults__
        return guarded

    def install(self, head: Callable[..., Any]) -> None:
        """Make calls of `stable` run `head`: by taking its code, else via a trampoline
        (one that passes the parameters straight on when `head` takes the same ones)."""
        if can_take_code_of(self.stable, head):
            self.stable.__code__ = head.__code__  # type: ignore[attr-defined]
            return
        self.stable.__globals__[self._head_key] = head
        if same_parameters(self.stable, self._signature, head):
            self.stable.__code__ = self._exact_code
        else:
            self.stable.__code__ = self._direct_code

    def install_scoped(self, runtime: Any) -> None:
        """Make calls of `stable` read the caller's scope first (while scopes are alive);
        a call that finds no scope alive at all puts the direct path back. With the C
        dispatcher, the newest scope's head is the one it expects."""
        namespace = self.stable.__globals__
        if _FINDER is not None:
            scope = runtime.newest_scope()
            guess = self.head_for(scope.configuration()) if scope is not None else None
            code = self._scoped_exact_code if self._uniform else self._scoped_code
            finder = (self, runtime.scope, runtime, self.global_head)
            self._install_dispatcher(code, guess, finder, receiver=False)
            return
        namespace[self._head_key] = self.global_head
        namespace[self._scope_key] = runtime.scope
        namespace[self._runtime_key] = runtime
        namespace[self._self_key] = self
        self.stable.__code__ = self._scoped_exact_code if self._uniform else self._scoped_code

    def install_receiver(self, runtime: Any) -> None:
        """Make calls of `stable` look up their receiver's own layers first (per-object
        and class-wide activation), then the caller's scope. With the C dispatcher, the
        head of the receiver whose layers changed last is the one it expects."""
        namespace = self.stable.__globals__
        receivers = runtime.receivers
        if _FINDER is not None:
            latest = receivers.latest()
            found = receivers.of(latest) if latest is not None else None
            guess = self.head_for(found.configuration()) if found is not None else None
            finder = (
                self,
                runtime.scope,
                runtime,
                self.global_head,
                receivers.objects,
                receivers.classes,
                self.receiver_kind == "class",
            )
            self._install_dispatcher(
                self._receiver_exact_code[self.receiver_kind]
                if self._uniform and self._receiver_exact_code
                else self._receiver_code[self.receiver_kind],
                guess,
                finder,
                receiver=True,
            )
            return
        namespace[self._head_key] = self.global_head
        namespace[self._scope_key] = runtime.scope
        namespace[self._objects_key] = receivers.objects
        namespace[self._classes_key] = receivers.classes
        namespace[self._runtime_key] = runtime
        namespace[self._self_key] = self
        exact = self._receiver_exact_code if self._uniform else None
        self.stable.__code__ = (exact or self._receiver_code)[self.receiver_kind]

    def _install_dispatcher(
        self,
        code: CodeType,
        guess: Callable[..., Any] | None,
        finder: tuple[Any, ...],
        *,
        receiver: bool,
    ) -> None:
        """Install a C dispatcher (`code`, with a Finder made of `finder`), or where it can,
        the same dispatcher opening the code of `guess`, the head it expects (of the newest
        scope, or of the receiver whose layers changed last): a call that finds that head
        runs it in this frame, one that finds another calls it (one frame more).

        Each such code reads a Finder of its own, which expects its head: a call still
        running an older dispatcher while this one is installed runs that one's head only
        if it is the head it finds."""
        namespace = self.stable.__globals__
        namespace[self._find_key] = _FINDER(*finder)
        inlined = None
        if (
            self._uniform
            and isinstance(guess, FunctionType)
            and can_take_code_of(self.stable, guess)
            and same_parameters(self.stable, self._signature, guess)
        ):
            codes = self._inlined.setdefault(guess, {})
            if receiver not in codes:
                key = fresh_key("find")
                made = inline_head_code(guess.__code__, key, receiver)
                if made is not None:
                    remember_like(made, guess)
                codes[receiver] = None if made is None else (made, key)
            inlined = codes[receiver]
        if inlined is not None:
            namespace[inlined[1]] = _FINDER(*finder, expected=guess)
            self.stable.__code__ = inlined[0]
        else:
            self.stable.__code__ = code

    def installed_objects(self) -> dict[int, Any] | None:
        """The per-object table calls of `stable` read (None: not on the per-receiver path)."""
        namespace = self.stable.__globals__
        if _FINDER is not None:
            finder = namespace.get(self._find_key)
            return None if finder is None else finder.objects
        return namespace.get(self._objects_key)

    def _missing(self) -> Callable[..., Any]:
        qualname = self.qualname
        owner = self

        def no_implementation(*args: Any, **kwargs: Any) -> Any:
            # On the per-receiver path the call saw its receiver's layers: name those.
            receiver = args[0] if owner.receiver_kind and args else None
            layers = owner._host.effective(receiver)
            active = ", ".join(layer.name for layer in layers) or "none"
            raise NoImplementationError(
                f"{qualname}() has no base implementation and no active layer provides it "
                f"(active layers: {active})"
            )

        return no_implementation

    def _exhausted(self, innermost: str) -> Callable[..., Any]:
        qualname = self.qualname

        def nothing_below(*args: Any, **kwargs: Any) -> Any:
            raise ProceedError(
                f"proceed() in layer {innermost}'s partial of {qualname}: there is no further "
                "implementation (no base, and no older active layer provides one)"
            )

        return nothing_below


def layered_function_of(function: object) -> LayeredFunction | None:
    """The composition state behind a layered function, or None if it is not layered.

    Accepts the function, a layered classmethod/staticmethod, or a layered property
    (its getter's state)."""
    owner = getattr(function, "__contextros__", None)
    return owner if isinstance(owner, LayeredFunction) else None


def _unwrapped(function: object) -> FunctionType:
    if isinstance(function, (classmethod, staticmethod)):
        function = function.__func__
    if isinstance(function, property):
        function = function.fget
    if not isinstance(function, FunctionType):
        raise LayerDefinitionError(f"before/after take a plain function, got {function!r}")
    return function


# before/after are partials that call `proceed` by name (relinked like any other).


def _before(function: FunctionType, is_async: bool) -> FunctionType:
    if is_async:

        async def before_async(*args: Any, **kwargs: Any) -> Any:
            result = function(*args, **kwargs)
            if inspect.isawaitable(result):
                await result
            return await proceed(*args, **kwargs)

        chosen: FunctionType = before_async  # type: ignore[assignment]
    else:

        def before(*args: Any, **kwargs: Any) -> Any:
            function(*args, **kwargs)
            return proceed(*args, **kwargs)

        chosen = before  # type: ignore[assignment]
    return _named_like(chosen, function)


def _check_after(
    function: FunctionType, layered: FunctionType, qualname: str, layer: object
) -> None:
    """After-advice takes the call's arguments in order, then the result by keyword
    (`def m(self, x, *, result)`); the old form with the result first is refused."""
    name = layer.name if isinstance(layer, Layer) else layer
    code = function.__code__
    positional = code.co_varnames[: code.co_posonlyargcount + code.co_argcount]
    keywords = code.co_varnames[code.co_posonlyargcount : code.co_argcount + code.co_kwonlyargcount]
    own = layered.__code__
    own_names = own.co_varnames[: own.co_argcount + own.co_kwonlyargcount]
    has_kwargs = bool(code.co_flags & inspect.CO_VARKEYWORDS)
    where = f"after-advice of {qualname} for layer {name} ({function.__qualname__})"
    if "result" in own_names:
        raise LayerDefinitionError(
            f"{where}: {qualname} has a parameter named 'result' itself, so the result "
            "cannot be passed by keyword; write a partial that calls proceed(...) instead"
        )
    if positional[:1] == ("result",) and own_names[:1] != ("result",):
        fixed = ", ".join([*positional[1:], "*", "result"])
        raise LayerDefinitionError(
            f"{where} takes the result first (the old form): the result is now passed by "
            f"keyword after the call's arguments, `self` first: write "
            f"def {function.__name__}({fixed})"
        )
    if "result" not in keywords and not has_kwargs:
        raise LayerDefinitionError(
            f"{where} has no parameter 'result': after-advice receives the call's arguments "
            f"and then the result by keyword, e.g. def {function.__name__}(self, x, *, result)"
        )


def _after(function: FunctionType, is_async: bool) -> FunctionType:
    if is_async:

        async def after_async(*args: Any, **kwargs: Any) -> Any:
            result = function(*args, result=await proceed(*args, **kwargs), **kwargs)
            return (await result) if inspect.isawaitable(result) else result

        chosen: FunctionType = after_async  # type: ignore[assignment]
    else:

        def after(*args: Any, **kwargs: Any) -> Any:
            return function(*args, result=proceed(*args, **kwargs), **kwargs)

        chosen = after  # type: ignore[assignment]
    return _named_like(chosen, function)


def _named_like(wrapper: FunctionType, function: FunctionType) -> FunctionType:
    wrapper.__name__ = function.__name__
    wrapper.__qualname__ = function.__qualname__
    wrapper.__doc__ = function.__doc__
    wrapper.__wrapped__ = function  # type: ignore[attr-defined]
    return wrapper
