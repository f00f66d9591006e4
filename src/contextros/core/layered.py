"""`layered`: functions and methods whose behaviour depends on the active layers."""

from __future__ import annotations

from collections.abc import Callable
from types import FunctionType
from typing import Any, TypeVar, overload

from contextros.core.composition import LayeredFunction, layered_function_of
from contextros.core.layer import Layer
from contextros.core.runtime import RUNTIME
from contextros.errors import LayerDefinitionError

__all__ = ["LayeredFunction", "LayeredProperty", "layered", "layered_function_of"]

F = TypeVar("F", bound=Callable[..., Any])


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

    def make(target: Any) -> Any:
        existing = getattr(target, "__contextros__", None)
        if isinstance(existing, LayeredFunction):
            return target
        if isinstance(target, (classmethod, staticmethod)):
            owner = layered_function_of(make(target.__func__))
            assert owner is not None
            wrapper: Any = type(target)(owner.stable)
            for name in ("partial", "before", "after", "around", "remove_partial"):
                setattr(wrapper, name, getattr(owner, name))
            wrapper.__contextros__ = owner
            owner.descriptor = wrapper
            return wrapper  # type: ignore[return-value]
        if isinstance(target, property) and not isinstance(target, LayeredProperty):
            getter = make(target.fget) if target.fget is not None else None  # type: ignore[type-var]
            if getter is None:
                raise LayerDefinitionError("@layered on a property needs its getter")
            return LayeredProperty(getter, target.fset, target.fdel, target.__doc__)  # type: ignore[return-value]
        if not isinstance(target, FunctionType):
            raise LayerDefinitionError(
                f"@layered applies to plain functions and methods, not {target!r}"
            )
        owner = LayeredFunction(target, target if base else None, RUNTIME)
        RUNTIME.adopt(owner)
        return owner.stable

    if function is not None:
        made: F = make(function)
        return made
    return make


class LayeredProperty(property):
    """A property whose getter is layered: ``@layered`` over ``@property``.

    ``@name.partial(Layer)`` (or before/after/around) refines the getter; setter and
    deleter are plain (``@name.setter`` keeps the getter layered).
    """

    @property
    def __contextros__(self) -> LayeredFunction:
        owner = layered_function_of(self.fget)
        assert owner is not None
        return owner

    def _refine(
        self, kind: str, layer: Layer | str, replace: bool, when: Callable[..., object] | None
    ) -> Callable[[Any], Any]:
        register = getattr(self.__contextros__, kind)(layer, replace=replace, when=when)

        def add(function: Any) -> LayeredProperty:
            register(function.fget if isinstance(function, property) else function)
            return self

        return add

    def partial(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[Any], Any]:
        return self._refine("partial", layer, replace, when)

    def around(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[Any], Any]:
        return self._refine("around", layer, replace, when)

    def before(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[Any], Any]:
        return self._refine("before", layer, replace, when)

    def after(
        self,
        layer: Layer | str,
        *,
        replace: bool = False,
        when: Callable[..., object] | None = None,
    ) -> Callable[[Any], Any]:
        return self._refine("after", layer, replace, when)

    def remove_partial(self, layer: Layer | str) -> None:
        self.__contextros__.remove_partial(layer)
