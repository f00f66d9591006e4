"""`layered`: functions and methods whose behaviour depends on the active layers."""

from __future__ import annotations

from collections.abc import Callable
from contextvars import ContextVar
from types import FunctionType
from typing import Any, TypeVar, overload

from contextros.core.configuration import Configuration
from contextros.core.layer import Layer, resolve
from contextros.core.linking import (
    ProceedUse,
    analyse,
    can_take_code_of,
    copy_function,
    fresh_key,
    link,
    passing_through,
    same_parameters,
    trampoline_code,
)
from contextros.errors import LayerDefinitionError, NoImplementationError, ProceedError

F = TypeVar("F", bound=Callable[..., Any])


class LayeredFunction:
    """The composition state behind one layered function or method.

    Users never hold this object: they hold `stable`, a plain function that stays the
    same object for the program's life (so bound methods captured by timers and
    callbacks follow every switch) while its behaviour is recomposed per configuration.

    Chains are composed once per configuration and cached by the ordered tuple of the
    active layers that refine this function; layers without a partial here are
    transparent and share a chain.
    """

    def __init__(self, stub: FunctionType, base: FunctionType | None) -> None:
        self.qualname = stub.__qualname__
        self.base = base
        self.partials: dict[str, FunctionType] = {}
        self._uses: dict[str, ProceedUse] = {}
        self._chains: dict[tuple[str, ...], Callable[..., Any]] = {}
        self.stable = copy_function(stub)
        self._freevars = stub.__code__.co_freevars
        self._head_key = fresh_key("head")
        self._scope_key = fresh_key("scope")
        self._self_key = fresh_key("layered")
        call_head = f"return {self._head_key}(*args, **kwargs)"
        self._direct_code = trampoline_code([call_head], self._freevars, self.qualname)
        self._signature = stub.__code__
        parameters, arguments = passing_through(stub.__code__)
        self._exact_code = trampoline_code(
            [f"return {self._head_key}({arguments})"], self._freevars, self.qualname, parameters
        )
        self._scoped_code = trampoline_code(
            [
                f"__contextros_scope = {self._scope_key}.get()",
                "if __contextros_scope is None:",
                f"    {call_head}",
                f"__contextros_head = __contextros_scope.heads.get({self._self_key})",
                "if __contextros_head is None:",
                f"    __contextros_head = __contextros_scope.head({self._self_key})",
                "return __contextros_head(*args, **kwargs)",
            ],
            self._freevars,
            self.qualname,
        )
        self.stable.__wrapped__ = stub  # type: ignore[attr-defined]
        self.stable.partial = self.partial  # type: ignore[attr-defined]
        self.stable.__contextros__ = self  # type: ignore[attr-defined]
        self.global_head: Callable[..., Any] = self._missing()

    def __repr__(self) -> str:
        return f"<layered {self.qualname} partials={sorted(self.partials)}>"

    # -- definition ----------------------------------------------------------------------

    def partial(self, layer: Layer | str, *, replace: bool = False) -> Callable[[F], F]:
        """Decorator registering the partial implementation of this function for `layer`.

        Returns the layered function itself, so the name stays bound to it in a class
        body or module.
        """
        target = resolve(layer)

        def register(function: F) -> F:
            if not isinstance(function, FunctionType):
                raise LayerDefinitionError(
                    f"partial of {self.qualname} for layer {target.name} must be a plain "
                    f"function, got {function!r}"
                )
            if target.name in self.partials and not replace:
                raise LayerDefinitionError(
                    f"{self.qualname} already has a partial for layer {target.name} "
                    "(pass replace=True to redefine it)"
                )
            use = analyse(function)
            from contextros.core.runtime import RUNTIME

            with RUNTIME.lock:
                self.partials[target.name] = function
                self._uses[target.name] = use
                self._chains.clear()
                RUNTIME.recompose(self)
            return self.stable  # type: ignore[return-value]

        return register

    # -- composition ---------------------------------------------------------------------

    def head_for(self, configuration: Configuration) -> Callable[..., Any]:
        """The first implementation to run under `configuration` (composed once, cached)."""
        relevant = tuple(
            layer.name for layer in reversed(configuration) if layer.name in self.partials
        )
        head = self._chains.get(relevant)
        if head is None:
            head = self._compose(relevant)
            self._chains[relevant] = head
        return head

    def _compose(self, relevant: tuple[str, ...]) -> Callable[..., Any]:
        if not relevant:
            return self.base if self.base is not None else self._missing()
        following: Callable[..., Any] = (
            self.base if self.base is not None else self._exhausted(relevant[-1])
        )
        for name in reversed(relevant):
            following = link(self.partials[name], self._uses[name], following)
        return following

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

    def install_scoped(self, scope: ContextVar[Any]) -> None:
        """Make calls of `stable` read the caller's scope first (while scopes are alive)."""
        namespace = self.stable.__globals__
        namespace[self._head_key] = self.global_head
        namespace[self._scope_key] = scope
        namespace[self._self_key] = self
        self.stable.__code__ = self._scoped_code

    def _missing(self) -> Callable[..., Any]:
        qualname = self.qualname

        def no_implementation(*args: Any, **kwargs: Any) -> Any:
            from contextros.core.runtime import RUNTIME

            active = ", ".join(layer.name for layer in RUNTIME.effective()) or "none"
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


@overload
def layered(function: F, /) -> F: ...
@overload
def layered(*, base: bool = True) -> Callable[[F], F]: ...


def layered(function: F | None = None, /, *, base: bool = True) -> F | Callable[[F], F]:
    """Make a function or method layered; its body is the base implementation.

    ``@layered(base=False)`` declares the function without a base: its body is only a
    stub (name, signature, docstring), and a call with no active partial raises
    NoImplementationError naming the function and the active layers.

    Partials are added with ``@name.partial(Layer)``. Applied to a function that is
    already layered, `layered` returns it unchanged.
    """

    def make(target: F) -> F:
        existing = getattr(target, "__contextros__", None)
        if isinstance(existing, LayeredFunction):
            return target
        if not isinstance(target, FunctionType):
            raise LayerDefinitionError(
                f"@layered applies to plain functions and methods, not {target!r}"
            )
        from contextros.core.runtime import RUNTIME

        owner = LayeredFunction(target, target if base else None)
        RUNTIME.adopt(owner)
        return owner.stable  # type: ignore[return-value]

    if function is not None:
        return make(function)
    return make


def layered_function_of(function: object) -> LayeredFunction | None:
    """The composition state behind a layered function, or None if it is not layered."""
    owner = getattr(function, "__contextros__", None)
    return owner if isinstance(owner, LayeredFunction) else None
