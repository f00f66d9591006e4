"""`contextros` subcommands for the language part (registered by contextros.cli)."""

from __future__ import annotations

import argparse
from typing import Any


def register(commands: Any) -> None:
    """Add this part's subcommands to the `contextros` parser.

    Each subparser sets `run=callable(args) -> int` via set_defaults.
    """
    del commands


def _unused(_: argparse.Namespace) -> int:
    return 0
