"""Start-up: message type support without the message generator.

Every generated message module loads its type support with
`from rosidl_generator_py import import_type_support`, and that package's `__init__` also
imports its code generator, which brings in empy and lark (rosidl_parser): 0.16 s of a
CLI command's 1 s, in every ROS process, for nothing a running process uses. Called
before the first message is used, `skip_message_generator` registers the package with
only `import_type_support` loaded; any other name of it loads the whole package as usual.
"""

from __future__ import annotations

import importlib.util
import sys
import threading
from pathlib import Path
from typing import Any

PACKAGE = "rosidl_generator_py"
SUPPORT = "import_type_support_impl"


def skip_message_generator() -> bool:
    """Make `import_type_support` cheap to import; False (nothing changed) when the package
    is loaded already, missing, or not laid out as expected."""
    if PACKAGE in sys.modules:
        return False
    spec = importlib.util.find_spec(PACKAGE)  # found, not run
    if spec is None or spec.loader is None or not spec.submodule_search_locations:
        return False
    support_file = Path(next(iter(spec.submodule_search_locations))) / f"{SUPPORT}.py"
    support_spec = importlib.util.spec_from_file_location(f"{PACKAGE}.{SUPPORT}", support_file)
    if not support_file.is_file() or support_spec is None or support_spec.loader is None:
        return False
    package = importlib.util.module_from_spec(spec)
    support = importlib.util.module_from_spec(support_spec)
    sys.modules[PACKAGE] = package
    sys.modules[support_spec.name] = support
    try:
        support_spec.loader.exec_module(support)
    except BaseException:
        del sys.modules[PACKAGE], sys.modules[support_spec.name]
        raise
    package.import_type_support = support.import_type_support  # type: ignore[attr-defined]
    setattr(package, SUPPORT, support)  # as importing the submodule does
    setattr(package, "__getattr__", _whole_package(package, spec))  # noqa: B010 - PEP 562
    return True


def _whole_package(package: Any, spec: Any) -> Any:
    lock = threading.RLock()
    loading = False

    def load_and_get(name: str) -> Any:
        """Any other name (`generate_py`, `__all__`...): the package's own `__init__` runs
        now, once; if it fails it runs again on the next such name."""
        nonlocal loading
        if name.startswith("__") and name != "__all__":
            raise AttributeError(name)
        with lock:
            if "__getattr__" in vars(package) and not loading:
                loading = True
                try:
                    spec.loader.exec_module(package)
                    del package.__getattr__
                finally:
                    loading = False
        if name in vars(package):
            return vars(package)[name]
        raise AttributeError(f"module {PACKAGE!r} has no attribute {name!r}")

    return load_and_get
