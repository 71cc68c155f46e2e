"""Keep numba's on-disk cache of the kernels consistent with their sources.

numba invalidates a cached function when *its own* file changes, but not when a kernel it calls
lives in another file that changed (``solvers.py`` inlines ``events.py``, ``motion.py``, ...;
``envs/fast.py`` inlines the solvers). So a stale compiled solver could run after an edit.
Before the kernels are imported, each package holding kernels compares a hash of the sources
they depend on with the one recorded beside its cache and, if they differ, removes that
package's cached kernels (``__pycache__/*.nbi|*.nbc``) so numba recompiles them. Nothing happens
when the directory is not writable (e.g. a read-only install), and nothing outside the
packages' own ``__pycache__`` is touched.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_KERNEL_MODULES = ("contacts.py", "events.py", "impulse.py", "jam.py", "jit.py", "kernels.py",
                   "layout.py", "motion.py",
                   "solvers.py", "world.py")
_HERE = Path(__file__).resolve().parent


def kernel_sources_digest() -> str | None:
    """SHA-256 of the physics kernel sources (None if one cannot be read)."""
    digest = hashlib.sha256()
    for name in _KERNEL_MODULES:
        try:
            digest.update((_HERE / name).read_bytes())
        except OSError:
            return None
    return digest.hexdigest()


def refresh_kernel_cache(directory: Path = _HERE, modules: tuple[str, ...] = (),
                         stamp_name: str = "spinstrike-kernels.sha256") -> None:
    """Clear ``directory``'s cached numba kernels if its ``modules`` or the physics kernels
    (which compiled kernels elsewhere inline, e.g. ``envs/fast.py``) changed since the last
    call. With no ``modules``, the physics package's own cache."""
    physics = kernel_sources_digest()
    if physics is None:
        return
    digest = hashlib.sha256(physics.encode())
    for name in modules:
        try:
            digest.update((directory / name).read_bytes())
        except OSError:
            return
    cache = directory / "__pycache__"
    stamp = cache / stamp_name
    try:
        if stamp.exists() and stamp.read_text() == digest.hexdigest():
            return
        for pattern in ("*.nbi", "*.nbc"):
            for f in cache.glob(pattern):
                f.unlink()
        cache.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:
        pass
