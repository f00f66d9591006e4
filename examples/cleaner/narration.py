"""What every context node of the demo prints when it applies a state (the C++ node prints
the same line: examples/cleaner/cpp/localization_node.cpp)."""

from __future__ import annotations

import time

from contextros.protocol import LayerState


def report_applied(state: LayerState) -> None:
    """How long after the manager published a state this node had applied it."""
    after = (time.time() - state.stamp) * 1000
    print(
        f"applied epoch {state.epoch} [{', '.join(state.active)}] "
        f"{after:.1f} ms after the manager published it",
        flush=True,
    )
