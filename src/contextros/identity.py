"""Who sends a command: the `requester` every state records (`user@pidN` by default)."""

from __future__ import annotations

import getpass
import os


def default_requester() -> str:
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = "unknown"
    return f"{user}@pid{os.getpid()}"
