from collections.abc import Callable
from contextvars import ContextVar
from typing import Any

ABI: int

class Finder:
    """FIND[receiver] or FIND(receiver) (FIND(): no receiver): the head a layered call
    runs (_dispatch.c)."""

    head: Callable[..., Any]
    function: object
    objects: dict[int, Any] | None
    expected: Callable[..., Any] | None
    def __init__(
        self,
        function: object,
        scope: ContextVar[Any],
        runtime: object,
        head: Callable[..., Any],
        objects: dict[int, Any] | None = None,
        classes: dict[type, Any] | None = None,
        by_class: bool = False,
        expected: Callable[..., Any] | None = None,
    ) -> None: ...
    def __call__(self, receiver: object = ..., /) -> Callable[..., Any]: ...
    def __getitem__(self, receiver: object, /) -> Callable[..., Any] | None: ...
