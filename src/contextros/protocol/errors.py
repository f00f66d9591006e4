"""Errors of the manager protocol (branch of the `LayerError` hierarchy)."""

from __future__ import annotations

from contextros.errors import LayerError


class ManagerError(LayerError):
    """The distributed Layer manager could not do what was asked."""


class ActivationFailed(ManagerError):
    """An activation command was rejected or not acknowledged; the message names why."""

    def __init__(self, message: str, not_acknowledged: tuple[str, ...] = ()) -> None:
        self.not_acknowledged = not_acknowledged
        super().__init__(message)


class StateFileError(ManagerError):
    """The manager's state file cannot be read back."""
