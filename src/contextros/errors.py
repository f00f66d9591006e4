"""The exception hierarchy: everything ContextROS raises derives from `LayerError`.

Each part of the framework owns a branch: the COP core (definitions, relations,
dispatch), the layer-description language (syntax and checks, with file:line:col),
and the distributed Layer manager (activation failures naming layers and nodes).
"""

from __future__ import annotations


class LayerError(Exception):
    """Root of every error ContextROS raises."""


# -- the COP core ---------------------------------------------------------------------------


class LayerDefinitionError(LayerError):
    """A layer, a layered function or a partial was declared inconsistently."""


class UnknownLayerError(LayerError, LookupError):
    """A layer was named that nobody defined or registered."""

    def __init__(self, name: str, known: tuple[str, ...] = ()) -> None:
        self.name = name
        self.known = known
        hint = f" (known layers: {', '.join(known)})" if known else " (no layers are defined)"
        super().__init__(f"unknown layer {name!r}{hint}")


class RelationError(LayerError):
    """A requested configuration breaks a declared relation (excludes, requires, group).

    Nothing changes when this is raised: switches are validated before they apply.
    """

    def __init__(self, message: str, layers: tuple[str, ...] = ()) -> None:
        self.layers = layers
        super().__init__(message)


class DispatchError(LayerError):
    """A layered call could not find an implementation to run."""


class NoImplementationError(DispatchError, NotImplementedError):
    """A layered function has no base and no active layer provides it."""


class ProceedError(DispatchError):
    """`proceed()` was called where there is no next implementation."""


class HookError(LayerError):
    """An activation or deactivation hook raised; the original error is the __cause__."""

    def __init__(self, message: str, layer: str) -> None:
        self.layer = layer
        super().__init__(message)
