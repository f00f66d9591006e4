"""Imported first by every child of a benchmark's "before" run (see benchmarks/code_before.py):
removes the editable install's import hook, so that `contextros` comes from PYTHONPATH
(the tree before) and not from this checkout."""

import sys

sys.meta_path[:] = [
    finder for finder in sys.meta_path if not type(finder).__module__.startswith("_editable_")
]
