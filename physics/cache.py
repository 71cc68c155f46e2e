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
  too, kernels compile in every process (a warning says so). A cache directory that is readable
  but not writable (a prebuilt cache shared read-only: NFS, an image layer, a ``ro`` mount) is
  still *loaded from*; only the kernels it lacks compile, into the fallback, and the first
  compilation says why, once: ``<dir> is not writable: new kernels go to <fallback>`` (walk
  W24b F8: the read-only directory was skipped whole, every process recompiled into /tmp, 35 s
  instead of 2, without a word).
* **Freshness**: a cached kernel carries a stamp: the hash of its module's source *and of every
  ``spinstrike`` module (or module beside it) that module imports, transitively, in any import
  form (read with ``ast``: relative imports too)* (what numba may inline or freeze into
  it: kernels, layout tables, constants). An edit to any of them recompiles the kernels that
  depend on it, wherever the cache lives, read-only installs included.
* ``spinstrike cache`` shows the location and size, the fallback's apart (only where it is in
  use or holds kernels; W24b F8 counted its files as the configured folder's, and named it when
  the folder was writable again); ``spinstrike cache --clear`` removes the
  kernel folders (those with a ``SOURCE`` marker or numba's files; anything else in a folder
  ``SPINSTRIKE_CACHE_DIR`` names stays), and says what it could not remove (a read-only
  folder: it claimed to have removed them);
  ``--prune`` removes only what no run will load again: the folders of source directories that
  are gone (each clone, virtual environment or CI checkout compiles into a folder of its own,
  and a deleted one's kernels would otherwise stay), and in this install's own folders the
  kernels its edited sources have outdated (numba names a kernel's files by its function's
  line, so an edit that moves a function leaves the old files beside the new ones).

On a cache miss the first compilation in a process prints one line to stderr (what, why, first
run only), so a first run that takes a minute does not look hung.

**Processes take turns.** Processes started together on a cold cache (SB3's ``SubprocVecEnv``,
RLlib's env runners, pytest-xdist workers) need the same kernels. A process about to compile a
kernel for a signature takes a file lock beside the cached kernel (one per function and
signature, :func:`take_turns`); one that finds it taken waits, then loads what the holder
saved instead of compiling it again. A holder that dies releases its lock; one that holds it
for :data:`LOCK_TIMEOUT` s is not waited for longer (the waiting process compiles, warned).
"""

from __future__ import annotations

import ast
import contextlib
import errno
import glob
import hashlib
import importlib.util
import os
import pickle
import shutil
import stat
import sys
import tempfile
import threading
import time
import warnings
from functools import cache
from pathlib import Path
from typing import Any

import numba
from filelock import FileLock, Timeout
from numba.core import sigutils
from numba.core.caching import (
    CompileResultCacheImpl,
    FunctionCache,
    IndexDataCacheFile,
    UserWideCacheLocator,
)
from numba.core.compiler_lock import global_compiler_lock

__all__ = ["LOCK_TIMEOUT", "KernelCache", "cache_dir", "cache_info", "clear_cache",
           "module_stamp", "prune_cache", "prune_outdated", "take_turns"]

#: environment variable overriding the cache directory
ENV_VAR = "SPINSTRIKE_CACHE_DIR"
#: the file in each cache folder naming the source directory its kernels were compiled from
SOURCE_MARKER = "SOURCE"


# A fork while another thread loads or compiles a kernel (the first World of a scene family or
# solver in a process, a first call of a jitted helper) gave the child numba's compiler lock,
# and LLVM's, held by a thread the child does not have: the child's first kernel load waited for
# ever (walk W26b F4; a fork-started multiprocessing Pool then waited for that worker). The fork
# waits for the load to finish instead, holding both locks across it; parent and child release
# them. Registered after filelock's own fork hooks (imported above): before-hooks run in the
# reverse order, so this one runs first and filelock's sees no lock being taken (the other
# order deadlocked the parent: a loading thread held the compiler lock and waited at filelock's
# closed fork gate).
def _llvm_lock() -> Any:
    from llvmlite.binding import ffi

    return getattr(getattr(getattr(ffi, "lib", None), "_lock", None), "_lock", None)


_FORK_LOCKS = tuple(lock for lock in (getattr(global_compiler_lock, "_lock", None), _llvm_lock())
                    if lock is not None)
_fork_held = threading.local()  # the locks the forking thread took (a hook that failed: none)


def _before_fork() -> None:
    _fork_held.locks = []
    for lock in _FORK_LOCKS:  # numba's order: the compiler lock, then LLVM's
        lock.acquire()
        _fork_held.locks.append(lock)


def _after_fork() -> None:
    for lock in reversed(getattr(_fork_held, "locks", ())):
        lock.release()
    _fork_held.locks = []


if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_before_fork, after_in_parent=_after_fork,
                        after_in_child=_after_fork)


def cache_dir() -> Path:
    """The directory holding SpinStrike's compiled kernels (see the module docstring)."""
    override = os.environ.get(ENV_VAR)
    if override:  # absolute: a relative one followed the working directory of each save
        return Path(override).expanduser().absolute()
    from platformdirs import user_cache_dir

    return Path(user_cache_dir("spinstrike", appauthor=False)) / "kernels"


def _fallback_dir() -> Path:
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    try:
        tmp = tempfile.gettempdir()
    except FileNotFoundError:  # no writable temporary directory: `import spinstrike` failed
        tmp = os.path.join(os.sep, "nonexistent")  # no cache there: compiled in each process
    return Path(tmp) / f"spinstrike-kernels-{uid}"


def _module_file(name: str) -> Path | None:
    """The source file of module ``name`` (a package: its ``__init__.py``), imported or not
    (a module imported after the kernel's stamp was taken counts too); None if none."""
    module = sys.modules.get(name)
    path = getattr(module, "__file__", None)
    if path is None:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            return None
        path = spec.origin if spec is not None and spec.has_location else None
    return Path(path).resolve() if path else None


def _sibling(path: Path, level: int, dotted: str) -> Path | None:
    """The file a relative import ``from <level dots><dotted>`` in ``path`` names."""
    base = path.parent
    for _ in range(level - 1):
        base = base.parent
    target = base.joinpath(*dotted.split(".")) if dotted else base
    for candidate in (target.with_suffix(".py"), target / "__init__.py"):
        if candidate.is_file():
            return candidate.resolve()
    return None


def _imports(path: Path) -> set[Path]:
    """The source files of the ``spinstrike`` modules (and of modules beside ``path``) that a
    source file imports, in any form: ``import a, spinstrike.x``, ``from spinstrike.x import
    y`` (``y`` a module too), ``from spinstrike import x``, relative (``from .x import y``,
    ``from . import x``), star imports, inside functions (read with ``ast``: a pattern missed
    relative imports, so an edit of a module imported that way kept stale kernels)."""
    found: set[Path | None] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("spinstrike."):
                    found.add(_module_file(alias.name))
        elif isinstance(node, ast.ImportFrom):
            names = [a.name for a in node.names if a.name != "*"]
            if node.level:
                found.add(_sibling(path, node.level, node.module or ""))
                for name in names:
                    found.add(_sibling(path, node.level, f"{node.module}.{name}" if node.module
                                       else name))
            elif node.module and (node.module == "spinstrike"
                                  or node.module.startswith("spinstrike.")):
                found.add(_module_file(node.module))
                for name in names:  # ``from spinstrike.physics import motion``: a module
                    found.add(_module_file(f"{node.module}.{name}"))
    found.discard(None)
    return found  # type: ignore[return-value]


@cache
def _closure(path: Path) -> tuple[Path, ...]:
    """``path`` and every source file of the ``spinstrike`` modules it imports, transitively."""
    seen = {path}
    todo = [path]
    while todo:
        for dep in _imports(todo.pop()):
            if dep not in seen:
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
        blocked = _unwritable(Path(self.get_cache_path()))
        if blocked is not None:
            raise OSError(f"{blocked} is not a writable directory")


def _unwritable(path: Path) -> Path | None:
    """None if kernels can be saved in folder ``path`` (made on the first save): its nearest
    existing ancestor (itself, if it exists) is a writable directory; else that ancestor. The
    one check of writability here: the locators', ``spinstrike cache``'s (which names the
    fallback only while it is in use) and the fallback notice's."""
    while not path.exists() and path.parent != path:
        path = path.parent
    if path.is_dir() and os.access(path, os.W_OK | os.X_OK):
        return None
    return path


class _FallbackLocator(_KernelLocator):
    _root = _fallback_dir()

    def ensure_cache_path(self):
        """Usable if the fallback folder, in the temporary directory every user shares, is
        this user's own: made here with mode 0o700, or one that is a real directory owned by
        this user that no one else can write. One made beforehand by another user (its name
        is predictable), or writable by all, was used: numba unpickles the kernels it loads,
        so files planted there ran in this process (walk W25 F6). Refused, the kernels
        compile uncached (``physics.jit`` says so)."""
        root = Path(self._root)
        try:
            root.mkdir(mode=0o700, parents=True, exist_ok=True)
            st = os.lstat(root)
        except OSError as exc:
            raise OSError(f"{root}: {exc}") from None
        uid = os.getuid() if hasattr(os, "getuid") else None
        if not stat.S_ISDIR(st.st_mode) or (uid is not None and st.st_uid != uid) or (
                st.st_mode & 0o022):
            why = (f"{root} is not this user's own folder (owner {st.st_uid}, mode "
                   f"{oct(st.st_mode & 0o777)}), so kernels are neither loaded from it nor saved "
                   f"there")
            global _refusal_noticed
            if not _refusal_noticed:
                _refusal_noticed = True
                print(f"spinstrike: {why}: remove it, or set {ENV_VAR} to a folder of yours",
                      file=sys.stderr, flush=True)
            raise OSError(why)
        super().ensure_cache_path()


#: the fallback's refusal is said once per process
_refusal_noticed = False


class _KernelCacheImpl(CompileResultCacheImpl):
    _locator_classes = [_KernelLocator, _FallbackLocator]


class KernelCache(FunctionCache):
    """numba's function cache for one SpinStrike kernel (see the module docstring).

    Where the cache directory is not writable (numba picked the fallback's locator) but this
    kernel's folder there is readable, that folder is read too (``_shared``): a kernel it holds,
    fresh, loads from it, and only the others compile, saved into the fallback (walk W24b F8:
    a read-only shared cache was not read at all)."""

    _impl_class = _KernelCacheImpl

    def __init__(self, py_func):
        super().__init__(py_func)
        self._shared: IndexDataCacheFile | None = None
        self._blocked: Path | None = None  # the configured path that is not writable
        locator = self._impl.locator
        if isinstance(locator, _FallbackLocator):
            configured = _KernelLocator(py_func, locator._py_file)
            folder = Path(configured.get_cache_path())
            self._blocked = _unwritable(folder)
            if folder.is_dir() and os.access(folder, os.R_OK | os.X_OK):
                self._shared = IndexDataCacheFile(
                    cache_path=str(folder), filename_base=self._impl.filename_base,
                    source_stamp=configured.get_source_stamp())

    def _load_overload(self, sig, target_context):
        data = super()._load_overload(sig, target_context)
        if data is None and self._enabled and self._shared is not None:
            key = self._index_key(sig, target_context.codegen())
            try:
                data = self._shared.load(key)
            except OSError:  # a file there this user may not read: compiled instead
                data = None
            if data is not None:
                data = self._impl.rebuild(target_context, data)
        return data

    def load_overload(self, sig, target_context):
        data = super().load_overload(sig, target_context)
        if data is None:
            if self._blocked is not None:
                _fallback_notice(self._blocked, _FallbackLocator._root)
            _compile_notice(Path(self._cache_path))
        return data

    def save_overload(self, sig, data):
        if self.claim_folder():  # else not cached: it compiles again next time
            super().save_overload(sig, data)

    def claim_folder(self) -> bool:
        """Make this kernel's cache folder, with its ``SOURCE`` marker (what the cache commands
        recognise and ``prune_cache`` checks); False if it cannot be written."""
        folder = Path(self._cache_path)
        try:
            folder.mkdir(parents=True, exist_ok=True)
            marker = folder / SOURCE_MARKER
            if not marker.exists():
                source = Path(self._impl.locator._py_file).resolve().parent
                marker.write_text(f"{source}\n")
        except OSError:
            return False
        return True


def take_turns(dispatcher: Any) -> None:
    """Make the processes that compile ``dispatcher`` (a kernel with a :class:`KernelCache`)
    for the same signature take turns: the first compiles and saves, the others wait for its
    lock, then load (the module docstring). The lock is taken inside numba's own compiler lock,
    so the threads of one process keep numba's order (one compiles at a time), and it is not
    taken again for a signature the process already holds (a kernel compiling its callees
    takes theirs inside its own: no cycle, for a callee never compiles its caller)."""
    compile_ = getattr(dispatcher, "compile", None)
    if compile_ is None:  # a plain function (NUMBA_DISABLE_JIT): nothing compiles
        return
    cache = dispatcher._cache

    def compile(sig):  # noqa: A001  (numba calls it by this name)
        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in dispatcher.overloads:  # compiled or loaded in this process
            return compile_(sig)
        with global_compiler_lock, _turn(cache, args):
            return compile_(sig)

    dispatcher.compile = compile


#: the longest a process waits for another that compiles the same kernel (s): a kernel compiles
#: in under two minutes on 2 cores; a holder past this is taken to be stuck (a stopped process)
LOCK_TIMEOUT = 900.0
#: the file locks this process holds or held, by path (a FileLock is reentrant per object)
_locks: dict[Path, FileLock] = {}


class _turn:
    """Hold the file lock of ``cache``'s kernel for signature ``args``; nothing if the cache
    folder cannot be written (no cache: no one to share with)."""

    def __init__(self, cache: KernelCache, args: tuple) -> None:
        key = hashlib.sha256(repr(tuple(args)).encode()).hexdigest()[:20]
        self.cache = cache
        self.path = Path(cache._cache_path) / f"{cache._impl.filename_base}.{key}.lock"
        self.lock: FileLock | None = None

    def __enter__(self) -> _turn:
        lock = _locks.get(self.path)
        if lock is None:
            if not self.cache.claim_folder():
                return self
            lock = _locks[self.path] = FileLock(self.path, timeout=LOCK_TIMEOUT)
        try:
            lock.acquire()
        except Timeout:
            warnings.warn(f"spinstrike: another process has held {self.path} for "
                          f"{LOCK_TIMEOUT:g} s; compiling this kernel here too",
                          RuntimeWarning, stacklevel=2)
            return self
        except OSError:  # a lock file that cannot be written (read-only cache): no turns
            return self
        self.lock = lock
        return self

    def __exit__(self, *exc: Any) -> None:
        if self.lock is not None:
            self.lock.release()


_noticed = False
_fallback_noticed = False


def _fallback_notice(blocked: Path, fallback: Path) -> None:
    """One line on stderr, at the first kernel a process compiles into the fallback: why there
    (not silenced by ``SPINSTRIKE_QUIET``: it is about the user's setting, not progress)."""
    global _fallback_noticed
    if _fallback_noticed:
        return
    _fallback_noticed = True
    root = cache_dir()
    where = root if _unwritable(root) is not None else blocked  # a kernel folder in it: that
    print(f"spinstrike: {where} is not writable: new kernels go to {fallback} (the kernels "
          f"already in {root} still load)", file=sys.stderr, flush=True)


def _compile_notice(where: Path) -> None:
    """One line on stderr at the first compilation in a process."""
    global _noticed
    if _noticed or os.environ.get("SPINSTRIKE_QUIET"):
        return
    _noticed = True
    print(f"spinstrike: compiling the physics kernels for this machine (first run, or after an "
          f"update: up to a minute on 2 cores); they are cached in {where.parent} for the "
          "next runs", file=sys.stderr, flush=True)


def _kernel_file(path: Path) -> bool:
    """A file of compiled kernels (numba's index and data, the ``SOURCE`` marker), not one of
    the empty lock files processes take turns with (:func:`take_turns`)."""
    return path.is_file() and path.suffix != ".lock"


def _kernel_dirs() -> list[Path]:
    roots = dict.fromkeys([cache_dir(), _fallback_dir()])  # the same one once
    return [r for r in roots if r.is_dir()]


def _kernel_folders(root: Path) -> list[Path]:
    """The folders of ``root`` that hold SpinStrike's compiled kernels: what the cache commands
    count and remove. A folder with a ``SOURCE`` marker; in SpinStrike's own folders (the
    default and the fallback) also one of numba's index and data files without it (made
    before the marker). A folder ``SPINSTRIKE_CACHE_DIR`` names may be shared with other numba
    caches (``NUMBA_CACHE_DIR`` set to the same place): there only marked folders are
    SpinStrike's (``--clear`` removed another project's numba cache whole)."""
    own = not os.environ.get(ENV_VAR) or root == _fallback_dir()
    return [f for f in sorted(root.iterdir()) if f.is_dir() and (
        (f / SOURCE_MARKER).is_file()
        or own and (any(f.glob("*.nbi")) or any(f.glob("*.nbc"))))]


def _sourced_folders() -> list[tuple[Path, Path]]:
    """(folder, source directory) of every kernel folder with a ``SOURCE`` marker (folders
    from before the marker have none: they are never judged stale or outdated)."""
    out = []
    for root in _kernel_dirs():
        for folder in _kernel_folders(root):
            marker = folder / SOURCE_MARKER
            if marker.is_file():
                out.append((folder, Path(marker.read_text().strip())))
    return out


def _stale_folders() -> list[Path]:
    """Cache folders whose source directory (recorded in their ``SOURCE`` file) is gone: a
    deleted clone, virtual environment or CI checkout; each source directory has its own."""
    return [folder for folder, source in _sourced_folders() if not source.is_dir()]


def _install_sources() -> set[Path]:
    """The source directories of the running ``spinstrike``'s subpackages: the only ones whose
    kernels' stamps this process can compute (another install's imports resolve to its own
    files, which this process does not import)."""
    found: set[Path] = set()
    for sub in ("physics", "envs", "agents", "benchmarks"):
        spec = importlib.util.find_spec(f"spinstrike.{sub}")
        if spec is not None and spec.submodule_search_locations:
            found.update(Path(p).resolve() for p in spec.submodule_search_locations)
    return found


def _fresh_index(index: Path, source: Path) -> dict | None:
    """The entries (signature -> data file) of a numba index whose stamp matches its module's
    sources now; None if it is outdated: another stamp, its module gone, unreadable. An index of
    another numba version (another venv on the same sources) is not this process's to judge:
    ``{"*": None}``, which keeps it and its data."""
    module = source / f"{index.name.split('.', 1)[0]}.py"  # numba: <module>.<qualname>-<line>
    if not module.is_file():
        return None
    try:
        with open(index, "rb") as f:
            if pickle.load(f) != numba.__version__:
                return {"*": None}
            stamp, overloads = pickle.loads(f.read())
    except FileNotFoundError:  # removed meanwhile (another prune, a --clear)
        return {"*": None}
    except Exception:  # noqa: BLE001  (a truncated or foreign file: numba would not load it)
        return None
    return overloads if stamp == module_stamp(module) else None


def _outdated_files() -> list[Path]:
    """The files in this install's cache folders that no run will load again: numba's indexes
    whose stamp no longer matches their module's sources (:func:`_fresh_index`), with their
    data and lock files, and data files no fresh index lists (numba numbers a kernel's data
    files and leaves the higher numbers of an outdated index behind)."""
    sources = _install_sources()
    outdated: list[Path] = []
    for folder, source in _sourced_folders():
        if source.resolve() not in sources:
            continue
        listed: set[str] = set()
        kept: set[str] = set()
        for index in sorted(folder.glob("*.nbi")):
            base = index.name[:-len(".nbi")]
            entries = _fresh_index(index, source)
            if entries is None:
                outdated.append(index)
                outdated.extend(folder.glob(f"{glob.escape(base)}.*.lock"))
            elif "*" in entries:
                kept.add(base)
            else:
                listed.update(entries.values())
        outdated.extend(f for f in folder.glob("*.nbc") if f.name not in listed
                        and f.name.rsplit(".", 2)[0] not in kept)
    return outdated


def _dir_info(root: Path) -> dict:
    """``{"path", "files", "bytes", "folders", "writable"}`` of one kernel directory."""
    folders = _kernel_folders(root) if root.is_dir() else []
    files = [f for d in folders for f in d.rglob("*") if _kernel_file(f)]
    return {"path": str(root), "files": len(files), "bytes": sum(f.stat().st_size for f in files),
            "folders": len(folders), "writable": _unwritable(root) is None}


def cache_info() -> dict:
    """``{"path", "files", "bytes", "folders", "writable", "fallback", "stale", "stale_bytes",
    "outdated", "outdated_bytes"}`` of the kernel cache (``folders``: one per source directory
    that compiled kernels; ``stale``: those whose source directory is gone, what
    :func:`prune_cache` removes; ``outdated``: the files of this install's kernels that its
    edited sources have outdated, what :func:`prune_outdated` removes). The counts at the top
    are the cache directory's own; ``fallback`` is the fallback's ``path``, ``files``,
    ``bytes``, ``folders`` and ``in_use`` (the cache directory is not writable: new kernels go
    there), or None where it is not in use and holds no kernels (walk W24b F8: the fallback's
    files were counted as the cache directory's, and it was named while not in use)."""
    info = _dir_info(cache_dir())
    info["fallback"] = None
    if _fallback_dir() != cache_dir():
        fallback = _dir_info(_fallback_dir())
        fallback["in_use"] = not info["writable"]
        # kernels, not the markers and locks a process leaves while it loads them elsewhere
        held = fallback["files"] and any(
            any(folder.glob("*.nbi")) or any(folder.glob("*.nbc"))
            for folder in _kernel_folders(_fallback_dir()))
        if fallback["in_use"] or held:
            info["fallback"] = fallback
    stale = _stale_folders()
    outdated = [f for f in _outdated_files() if _kernel_file(f)]
    info.update(stale=len(stale),
                stale_bytes=sum(f.stat().st_size for d in stale for f in d.rglob("*")
                                if f.is_file()),
                outdated=len(outdated),
                outdated_bytes=sum(f.stat().st_size for f in outdated))
    return info


def _remove_folder(folder: Path) -> str | None:
    """Remove ``folder`` whole; None if it is gone, else why not (the first error's
    ``strerror``: "Read-only file system", "Permission denied")."""
    errors: list[BaseException] = []

    def note(function, path, exc):  # onexc gets the exception, onerror (3.11) exc_info
        errors.append(exc if isinstance(exc, BaseException) else exc[1])

    for _ in range(3):  # another process may be writing a file meanwhile
        errors.clear()
        if sys.version_info >= (3, 12):
            shutil.rmtree(folder, onexc=note)
        else:
            shutil.rmtree(folder, onerror=note)
        if not folder.exists():
            return None
        if any(isinstance(e, PermissionError) or getattr(e, "errno", None) == errno.EROFS
               for e in errors):
            break  # not a race: trying again changes nothing
        time.sleep(0.1)
    return next((e.strerror or str(e) for e in errors if isinstance(e, OSError)
                 and not isinstance(e, FileNotFoundError)), "it stayed")


def prune_cache() -> tuple[int, list[tuple[Path, str]]]:
    """Remove the cache folders whose source directory is gone (:func:`cache_info`'s
    ``stale``); returns how many, and the (folder, why) of those that could not be removed (a
    read-only cache: ``--prune`` said it removed them, W24b F8). Kernels of the installs that
    still exist stay."""
    removed, failed = 0, []
    for folder in _stale_folders():
        why = _remove_folder(folder)
        if why is None:
            removed += 1
        else:
            failed.append((folder, why))
    return removed, failed


def prune_outdated() -> tuple[int, int, list[tuple[Path, str]]]:
    """Remove the files of this install's kernels that its edited sources have outdated
    (:func:`cache_info`'s ``outdated``); returns the files and bytes removed, lock files not
    counted, and the (file, why) of those that could not be removed. Current kernels stay,
    and so do other installs' (their stamps cannot be computed here)."""
    files = size = 0
    failed = []
    for path in _outdated_files():
        try:
            n = path.stat().st_size
            path.unlink()
        except FileNotFoundError:
            continue
        except OSError as exc:
            if path.suffix != ".lock":
                failed.append((path, exc.strerror or str(exc)))
            continue
        if path.suffix != ".lock":
            files += 1
            size += n
    return files, size, failed


def clear_cache() -> tuple[int, list[tuple[Path, int, str]]]:
    """Remove every cached kernel (the kernel folders of the cache directory and of the
    fallback; nothing else there: ``SPINSTRIKE_CACHE_DIR`` may name a shared folder, which
    was removed whole); returns the number of files removed, and for each directory where
    some could not be removed (read-only), ``(directory, files left, why)`` (walk W24b F8: it
    counted the files it meant to remove, and a read-only cache kept them all). The next run
    recompiles what was removed."""
    removed = 0
    failed = []
    for root in _kernel_dirs():
        left, why = 0, None
        for folder in _kernel_folders(root):
            before = sum(1 for f in folder.rglob("*") if _kernel_file(f))
            reason = _remove_folder(folder)
            after = (sum(1 for f in folder.rglob("*") if _kernel_file(f))
                     if reason is not None else 0)
            removed += before - after
            if reason is not None:
                left += after
                why = why or reason
        if why is not None:
            failed.append((root, left, why))
        elif not os.environ.get(ENV_VAR) and root.is_dir() and not any(root.iterdir()):
            with contextlib.suppress(OSError):
                root.rmdir()  # the default folder, emptied (a folder the user named stays)
    return removed, failed
