"""Using layer files without a compile step: `load(path)` and an import hook.

The compiled code is cached in `__pycache__/` next to the layer file, keyed by the
source's modification time and size, then by its SHA-256 (a touched but unchanged file
is not recompiled), by the compiler version and by the Python bytecode version. A
cache that cannot be written (read-only tree) only costs a recompilation.
"""

from __future__ import annotations

import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import marshal
import os
import struct
import sys
import tempfile
import warnings
from collections.abc import Sequence
from pathlib import Path
from types import CodeType, ModuleType

from contextros.language.compiler import COMPILER_VERSION, compile_source
from contextros.language.flavours import decode_source, stem_of

SUFFIX = ".layers"
_HEADER = struct.Struct("<4sIqq32sH")  # magic, compiler, mtime_ns, size, sha256, len(path)


class LayerInteractionWarning(UserWarning):
    """A checker warning about a loaded layer file (see `contextros check`)."""


def cache_path(path: str | os.PathLike[str]) -> Path:
    """Where the compiled code of the layer file `path` is cached."""
    source = Path(path)
    tag = sys.implementation.cache_tag or "python"
    return source.parent / "__pycache__" / f"{source.name}.{tag}.pyc"


def code_of(path: str | os.PathLike[str]) -> CodeType:
    """The compiled code of a layer file: from the cache when it is current, else compiled.

    Raises `LayerSyntaxError` for a file with errors; warns `LayerInteractionWarning`
    for each checker warning when it compiles.
    """
    return _code_and_digest(path)[0]


def _digest(path: str) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _code_and_digest(path: str | os.PathLike[str]) -> tuple[CodeType, str]:
    source_path = os.path.abspath(path)
    data = Path(source_path).read_bytes()
    stat = os.stat(source_path)
    digest = hashlib.sha256(data).digest()
    cache = cache_path(source_path)
    cached = _read_cache(cache, source_path, stat, digest)
    if cached is not None:
        return cached, digest.hex()
    compiled = compile_source(decode_source(data), source_path)
    for diagnostic in compiled.warnings:
        # Attributed to the layer file's line, like Python's own SyntaxWarnings.
        warnings.warn_explicit(
            diagnostic.message, LayerInteractionWarning, diagnostic.path, diagnostic.line
        )
    code = compiled.code()
    _write_cache(cache, source_path, stat, digest, code)
    return code, digest.hex()


def _header(path: str, stat: os.stat_result, digest: bytes) -> bytes:
    encoded = path.encode("utf-8", "surrogateescape")
    magic = importlib.util.MAGIC_NUMBER
    fields = _HEADER.pack(
        magic, COMPILER_VERSION, stat.st_mtime_ns, stat.st_size, digest, len(encoded)
    )
    return fields + encoded


def _read_cache(cache: Path, path: str, stat: os.stat_result, digest: bytes) -> CodeType | None:
    try:
        blob = cache.read_bytes()
        magic, version, _mtime, _size, cached_digest, length = _HEADER.unpack_from(blob)
        start = _HEADER.size + length
        cached_path = blob[_HEADER.size : start].decode("utf-8", "surrogateescape")
    except (OSError, struct.error, UnicodeDecodeError):
        return None
    # The digest decides: mtime and size alone miss same-second edits of equal length.
    if (magic, version, cached_digest, cached_path) != (
        importlib.util.MAGIC_NUMBER,
        COMPILER_VERSION,
        digest,
        path,
    ):
        return None
    try:
        code = marshal.loads(blob[start:])
    except (EOFError, ValueError, TypeError):
        return None
    return code if isinstance(code, CodeType) else None


def _write_cache(
    cache: Path, path: str, stat: os.stat_result, digest: bytes, code: CodeType
) -> None:
    try:
        cache.parent.mkdir(exist_ok=True)
        fd, temporary = tempfile.mkstemp(dir=cache.parent, prefix=cache.name, suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as stream:
                stream.write(_header(path, stat, digest) + marshal.dumps(code))
            os.replace(temporary, cache)
        except BaseException:
            os.unlink(temporary)
            raise
    except OSError:
        pass  # a read-only tree: compile again next time


class LayersLoader(importlib.abc.Loader):
    """Executes a layer file as a module (its `__file__` is the `.layers` path)."""

    def __init__(self, path: str) -> None:
        self.path = path

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType | None:
        return None

    def exec_module(self, module: ModuleType) -> None:
        code, digest = _code_and_digest(self.path)
        module.__file__ = self.path
        module.__layers_sha256__ = digest  # type: ignore[attr-defined]
        exec(code, module.__dict__)


def spec_for(name: str, path: str | os.PathLike[str]) -> importlib.machinery.ModuleSpec:
    source = os.path.abspath(path)
    spec = importlib.util.spec_from_file_location(name, source, loader=LayersLoader(source))
    assert spec is not None  # a loader was given
    return spec


def load(
    path: str | os.PathLike[str], name: str | None = None, *, reload: bool = False
) -> ModuleType:
    """Compile (or take from the cache) and execute a layer file; return its module.

    The module is registered in `sys.modules` under `name` (default: the file's stem,
    `robot` for `robot.layers` and `robot.py.layers`),
    so the layer file's header can define dataclasses and pickled types. Like `import`,
    loading the same unchanged file under the same name again returns the same module:
    several parts of a program can each `load` the layer file they use. A changed file,
    or `reload=True`, executes it again; its layers are redefined, which the core accepts.
    """
    module_name = name or stem_of(path)
    source = os.path.abspath(path)
    existing = sys.modules.get(module_name)
    if (
        not reload
        and existing is not None
        and getattr(existing, "__file__", None) == source
        and getattr(existing, "__layers_sha256__", None) == _digest(source)
    ):
        return existing
    spec = spec_for(module_name, path)
    module = importlib.util.module_from_spec(spec)
    previous = sys.modules.get(module_name)
    sys.modules[module_name] = module
    try:
        assert spec.loader is not None
        spec.loader.exec_module(module)
    except BaseException:
        if previous is None:
            sys.modules.pop(module_name, None)
        else:
            sys.modules[module_name] = previous
        raise
    return module


class LayersFinder(importlib.abc.MetaPathFinder):
    """Finds `name.layers` on `sys.path` (or in a package's `__path__`) for `import name`."""

    def find_spec(
        self,
        fullname: str,
        path: Sequence[str] | None,
        target: ModuleType | None = None,
    ) -> importlib.machinery.ModuleSpec | None:
        leaf = fullname.rpartition(".")[2]
        for entry in path if path is not None else sys.path:
            candidate = os.path.join(entry or ".", leaf + SUFFIX)
            if os.path.isfile(candidate):
                return spec_for(fullname, candidate)
        return None


_finder = LayersFinder()


def install_import_hook() -> LayersFinder:
    """Let `import name` find `name.layers` files (after Python's own finders). Idempotent."""
    if _finder not in sys.meta_path:
        sys.meta_path.append(_finder)
    return _finder


def uninstall_import_hook() -> None:
    if _finder in sys.meta_path:
        sys.meta_path.remove(_finder)
