"""Installing layered methods on the classes a layer file names (`def Cleaner.clean`).

Called by compiled layer modules at import time. The class comes from the layer file's
header; its existing method, if any, becomes the base implementation. An attribute that
is not a plain function is never overwritten.
"""

from __future__ import annotations

import inspect
import linecache
from collections.abc import Callable
from types import FunctionType, MethodDescriptorType, WrapperDescriptorType
from typing import Any, cast

from contextros.core import layered, layered_function_of
from contextros.language.diagnostics import Diagnostic, LayerTargetError, Severity

# Methods of built-in classes, which a class written in Python inherits as they are.
_BUILTIN_METHODS = (WrapperDescriptorType, MethodDescriptorType)


def layered_method(
    cls: type,
    name: str,
    base: FunctionType | None,
    where: tuple[str, int, int],
) -> Callable[..., Any]:
    """Make `cls.<name>` a layered method and return its dispatch function.

    - `base` given (the file's `base:` block): it becomes the base, replacing a plain
      function the class had; a method that is already layered keeps its own base, so
      giving another one is an error.
    - no `base`: the class's method (own or inherited) is the base; one inherited from a
      built-in class (`object.__init__`) is reached through `super()`; a class without
      one gets a layered method with no base.
    """
    if not isinstance(cls, type):
        _fail(
            f"'{getattr(cls, '__name__', cls)}' is not a class, cannot add method {name!r}", where
        )
    existing = inspect.getattr_static(cls, name, None)
    if layered_function_of(existing) is not None:
        if base is not None:
            _fail(
                f"{cls.__qualname__}.{name} is already layered (by another layer file?); "
                "its base cannot be replaced here: drop this file's base implementation",
                where,
            )
        assert existing is not None
        if name not in vars(cls):
            setattr(cls, name, existing)
        return existing  # type: ignore[no-any-return]
    if isinstance(existing, _BUILTIN_METHODS) and name not in vars(cls):
        # Inherited from a built-in class (`object.__init__`, `dict.get`): a plain function
        # that calls it the way the class would, through super(), becomes the base.
        existing = _inherited(cls, name)
    if existing is not None and not isinstance(existing, FunctionType):
        _fail(
            f"{cls.__qualname__}.{name} is {type(existing).__name__!r}, not a plain function; "
            "a layer file only refines methods and will not overwrite it",
            where,
        )
    if base is not None:
        base.__qualname__ = f"{cls.__qualname__}.{name}"
        dispatch = layered(base)
    elif existing is not None:
        dispatch = layered(existing)
    else:
        dispatch = layered(base=False)(_stub(cls, name))
    setattr(cls, name, dispatch)
    return dispatch


def _inherited(cls: type, name: str) -> FunctionType:
    def inherited(self: Any, *args: Any, **kwargs: Any) -> Any:
        """The method the class inherits from a built-in class."""
        return getattr(super(cls, self), name)(*args, **kwargs)

    inherited.__name__ = name
    inherited.__qualname__ = f"{cls.__qualname__}.{name}"
    inherited.__module__ = cls.__module__
    return cast(FunctionType, inherited)


def _stub(cls: type, name: str) -> FunctionType:
    def stub(self: Any, *args: Any, **kwargs: Any) -> Any:
        """Dispatch of a method that has no base implementation."""

    stub.__name__ = name
    stub.__qualname__ = f"{cls.__qualname__}.{name}"
    stub.__module__ = cls.__module__
    return cast(FunctionType, stub)


def _fail(message: str, where: tuple[str, int, int]) -> None:
    path, line, col = where
    source_line = linecache.getline(path, line) or None  # "": no such line
    raise LayerTargetError([Diagnostic(Severity.ERROR, message, path, line, col, source_line)])
