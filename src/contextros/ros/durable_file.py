"""Files the manager must find again after a crash or a power cut (its state file, the
bindings file): a new file written next to the old one, fsynced, renamed over it, and the
rename fsynced too. A reader finds the old content or the new, never a mix, and what was
written stays written."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


def partial_path(path: Path) -> Path:
    """Where the new content of `path` is written before it is renamed over it."""
    return path.with_name(f".{path.name}.{os.getpid()}.tmp")


def write_durably(path: Path, text: str) -> None:
    """Replace `path` by `text`, atomically and on disk when this returns; OSError if not
    (the old content is then still there)."""
    partial = partial_path(path)
    try:
        with partial.open("w", encoding="utf-8") as stream:
            stream.write(text)
            stream.flush()
            os.fsync(stream.fileno())
        partial.replace(path)
    except OSError:
        with contextlib.suppress(OSError):
            partial.unlink()
        raise
    # The rename itself on disk too: after a power cut, the old file must not come back.
    directory = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(directory)
    finally:
        os.close(directory)
