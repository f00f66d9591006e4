"""What every reader of serialized bytes (status_wire) must do with damaged ones: cut at
every byte, or a few bytes changed at random, they give a ValueError naming the field,
never another exception; whatever both it and rclpy read, they read alike."""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any

import pytest


def check_damaged_bytes(
    data: bytes,
    ours: Callable[[bytes], Any],
    theirs: Callable[[bytes], Any],
    what: str,
    seed: int,
) -> None:
    """`what`: the ValueError's first word ("status", "state"). `theirs` raising
    RuntimeError: refused by rclpy (read by us, say a bool that is neither 0 nor 1)."""
    for cut in range(4, len(data)):
        with pytest.raises(ValueError, match=rf"{what} field \w+"):
            ours(data[:cut])
    rng = random.Random(seed)
    alike = refused = 0
    for _ in range(3000):
        damaged = bytearray(data)
        for _ in range(rng.randint(1, 4)):
            damaged[rng.randrange(4, len(data))] = rng.randrange(256)
        try:
            read = ours(bytes(damaged))
        except ValueError as error:
            assert str(error).startswith(f"{what} field "), error
            refused += 1
            continue
        try:
            expected = theirs(bytes(damaged))
        except RuntimeError:
            continue
        assert read == expected
        alike += 1
    assert alike > 100 and refused > 100, (alike, refused)
