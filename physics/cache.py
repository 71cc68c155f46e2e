"""Where the compiled kernels are cached, and when a cached kernel is stale.

numba compiles the kernels on first use (tens of seconds) and caches the machine code on disk.
By default numba writes that cache beside the sources — into ``site-packages`` for an installed
wheel, where it outlives an uninstall and shadows a later editable install — and it judges a
cached kernel fresh by its own source file only, although a kernel inlines code from other files.
SpinStrike's kernels (every function compiled through ``spinstrike.physics.jit``) therefore use
their own cache, and only they do (other numba users in the same process keep numba's
behaviour, ``NUMBA_CACHE_DIR`` included):

* **Location**: ``$SPINSTRIKE_CACHE_DIR`` if set (read when ``spinstrike`` is imported), else the
  per-user cache directory (``platformdirs``: ``~/.cache/spinstrike/kernels`` on Linux), one
  subdirectory per source directory. Nothing is written into the install directory. If neither is
  writable, a per-user directory under the system's temporary directory is used; if that fails
  too, kernels compile in every process (a warning says so).
* **Freshness**: a cached kernel carries a stamp: the hash of its module's source *and of every
  ``spinstrike`` module that module imports, transitively* (what numba may inline or freeze into
  it: kernels, layout tables, constants). An edit to any of them recompiles the kernels that
  depend on it, wherever the cache lives, read-only installs included.
* ``spinstrike cache`` shows the location and size; ``spinstrike cache --clear`` empties it;
  ``--prune`` removes only the folders of source directories that are gone (each clone,
  virtual environment or CI checkout compiles into a folder of its own, and a deleted one's
  kernels would otherwise stay).

On a cache miss the first compilation in a process prints one line to stderr (what, why, first
run only), so a first run that takes half a minute does not look hung.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import sys
import tempfile
import time
from functools import cache
from pathlib import Path

from numba.core.caching import CompileResultCacheImpl, FunctionCache, UserWideCacheLocator

__all__ = ["KernelCache", "cache_dir", "cache_info", "clear_cache", "module_stamp",
           "prune_cache"]

#: environment variable overriding the cache directory
ENV_VAR = "SPINSTRIKE_CACHE_DIR"
#: the file in each cache folder naming the source directory its kernels were compiled from
SOURCE_MARKER = "SOURCE"
#: a ``from spinstrike... import`` of one line or of a parenthesised list (which must not run on
#: into the next statement: it once swallowed the ``from`` of the import after a list, so that
#: module fell out of the stamp), or an ``import spinstrike...``
_IMPORT = re.compile(r"^\s*(?:from\s+(spinstrike(?:\.\w+)+)\s+import\s+(\([^)]*\)|[\w \t,]+)"
                     r"|import\s+(spinstrike(?:\.\w+)+))", re.M)


def cache_dir() -> Path:
    """The directory holding SpinStrike's compiled kernels (see the module docstring)."""
    override = os.environ.get(ENV_VAR)
    if override:
        return Path(override).expanduser()
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("spinstrike", appauthor=False)) / "kernels"


def _fallback_dir() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    return Path(tempfile.gettempdir()) / f"spinstrike-kernels-{uid}"


def _module_file(name: str) -> Path | None:
    module = sys.modules.get(name)
    path = getattr(module, "__file__", None)
    return Path(path) if path else None


def _imports(path: Path) -> set[str]:
    """The ``spinstrike`` modules a source file imports (``from pkg import mod`` names too)."""
    found = set()
    for m in _IMPORT.finditer(path.read_text()):
        if m.group(3):
            found.add(m.group(3))
            continue
        found.add(m.group(1))
        for name in re.split(r"[\s,()]+", m.group(2)):
            if name and f"{m.group(1)}.{name}" in sys.modules:
                found.add(f"{m.group(1)}.{name}")  # ``from spinstrike.physics import motion``
    return found


@cache
def _closure(path: Path) -> tuple[Path, ...]:
    """``path`` and every source file of the ``spinstrike`` modules it imports, transitively."""
    seen = {path}
    todo = [path]
    while todo:
        for name in _imports(todo.pop()):
            dep = _module_file(name)
            if dep is not None and dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return tuple(sorted(seen))


@cache
def _stamp(path: Path) -> str:
    digest = hashlib.sha256()
    for dep in _closure(path):
        digest.update(dep.name.encode())
        digest.update(dep.read_bytes())
    return digest.hexdigest()


def module_stamp(path: str | Path) -> str:
    """The freshness stamp of the kernels defined in source file ``path``: SHA-256 over it and
    the ``spinstrike`` modules it imports, transitively (their contents, in path order)."""
    return _stamp(Path(path).resolve())


class _KernelLocator(UserWideCacheLocator):
    """numba's user-wide locator, pointed at SpinStrike's cache directory, with a stamp that
    covers the kernel module's import closure instead of its own file only."""

    _root: Path | None = None

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        root = self._root if self._root is not None else cache_dir()
        self._cache_path = str(root / self.get_suitable_cache_subpath(py_file))

    def get_source_stamp(self):
        return module_stamp(self._py_file)

    def ensure_cache_path(self):
        """Usable if the directory could be made: no directory is created at import (the first
        save makes it)."""
        path = Path(self.get_cache_path())
        while not path.exists():
            path = path.parent
        if not (path.is_dir() and os.access(path, os.W_OK | os.X_OK)):
            raise OSError(f"{path} is not a writable directory")


class _FallbackLocator(_KernelLocator):
    _root = _fallback_dir()


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [_KernelLocator, _FallbackLocator]


class KernelCache(FunctionCache):
    """numba's function cache for one SpinStrike kernel (see the module docstring)."""

    _impl_class = _KernelCacheImpl

    def load_overload(self, sig, target_context):
        data = super().load_overload(sig, target_context)
        if data is None:
            _compile_notice(Path(self._cache_path))
        return data

    def save_overload(self, sig, data):
        folder = Path(self._cache_path)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            marker = folder / SOURCE_MARKER
            if not marker.exists():  # what prune_cache checks
                source = Path(self._impl.locator._py_file).resolve().parent
                marker.write_text(f"{source}\n")
        except OSError:
            return  # not cached: it compiles again next time
        super().save_overload(sig, data)


_noticed = False


def _compile_notice(where: Path) -> None:
    """One line on stderr at the first compilation in a process."""
    global _noticed
    if _noticed or os.environ.get("SPINSTRIKE_QUIET"):
        return
    _noticed = True
    print(f"spinstrike: compiling the physics kernels for this machine (first run, or after an "
          f"update: about half a minute on 2 cores); they are cached in {where.parent} for the "
          "next runs", file=sys.stderr, flush=True)


def _kernel_dirs() -> list[Path]:
    roots = [cache_dir(), _fallback_dir()]
    return [r for r in roots if r.is_dir()]


def _stale_folders() -> list[Path]:
    """Cache folders whose source directory (recorded in their ``SOURCE`` file) is gone: a
    deleted clone, virtual environment or CI checkout; each source directory has its own."""
    stale = []
    for root in _kernel_dirs():
        for folder in root.iterdir():
            marker = folder / SOURCE_MARKER
            if marker.is_file() and not Path(marker.read_text().strip()).is_dir():
                stale.append(folder)
    return stale


def cache_info() -> dict:
    """``{"path", "files", "bytes", "fallback", "folders", "stale", "stale_bytes"}`` of the
    kernel cache (``folders``: one per source directory that compiled kernels; ``stale``: those
    whose source directory is gone, what :func:`prune_cache` removes)."""
    files = [f for root in _kernel_dirs() for f in root.rglob("*") if f.is_file()]
    stale = _stale_folders()
    return {"path": str(cache_dir()), "files": len(files),
            "bytes": sum(f.stat().st_size for f in files),
            "fallback": str(_fallback_dir()) if _fallback_dir().is_dir() else None,
            "folders": sum(1 for root in _kernel_dirs() for f in root.iterdir() if f.is_dir()),
            "stale": len(stale),
            "stale_bytes": sum(f.stat().st_size for d in stale for f in d.rglob("*")
                               if f.is_file())}


def prune_cache() -> int:
    """Remove the cache folders whose source directory is gone (:func:`cache_info`'s
    ``stale``); returns how many. Kernels of the installs that still exist stay."""
    stale = _stale_folders()
    for folder in stale:
        shutil.rmtree(folder, ignore_errors=True)
    return len(stale)


def clear_cache() -> int:
    """Remove every cached kernel (both the cache directory and the fallback); returns the
    number of files removed. The next run recompiles."""
    removed = 0
    for root in _kernel_dirs():
        removed += sum(1 for f in root.rglob("*") if f.is_file())
        for _ in range(3):  # another process may be writing a file meanwhile
            shutil.rmtree(root, ignore_errors=True)
            if not root.exists():
                break
            time.sleep(0.1)
    return removed
