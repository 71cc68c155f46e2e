"""Keep numba's on-disk cache of the kernels consistent with their sources.

numba invalidates a cached function when *its own* file changes, but not when a kernel it calls
lives in another file that changed (``solvers.py`` inlines ``events.py``, ``motion.py``, ...). So
a stale compiled solver could run after an edit. Before the kernels are imported, this compares
a hash of every kernel source with the one recorded beside the cache and, if they differ, removes
the package's cached kernels (``physics/__pycache__/*.nbi|*.nbc``) so numba recompiles them.
Nothing happens when the directory is not writable (e.g. a read-only install), and nothing
outside the package's own ``__pycache__`` is touched.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_KERNEL_MODULES = ("contacts.py", "events.py", "impulse.py", "jam.py", "layout.py", "motion.py",
                   "solvers.py", "world.py")


def refresh_kernel_cache() -> None:
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for name in _KERNEL_MODULES:
        try:
            digest.update((here / name).read_bytes())
        except OSError:
            return
    stamp = here / "__pycache__" / "spinstrike-kernels.sha256"
    try:
        if stamp.exists() and stamp.read_text() == digest.hexdigest():
            return
        for pattern in ("*.nbi", "*.nbc"):
            for f in (here / "__pycache__").glob(pattern):
                f.unlink()
        stamp.parent.mkdir(exist_ok=True)
        stamp.write_text(digest.hexdigest())
    except OSError:
        pass
