"""The compiled-kernel cache: its own directory, and freshness over a kernel's import closure.

Runs a copy of the package (so its sources can be edited) in fresh processes with its own
``SPINSTRIKE_CACHE_DIR``, and reads numba's cache hits and misses of three small kernels:
``contacts.capsule_capsule``, ``motion.slide`` (neither imports the other) and
``events.geometry`` (imports both). An edit of ``contacts.py`` must recompile the two kernels
that depend on it and reuse the third — numba alone would reuse ``events.geometry`` stale.
"""

from __future__ import annotations

import importlib
import json
import os
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

import spinstrike

PROBE = """
import json
from spinstrike.physics import contacts, events, motion
contacts.capsule_capsule(0.0, 0.0, 0.0, 0.1, 0.02, 0.5, 0.0, 0.0, 0.1, 0.02)
motion.slide(0.0, 0.0, 1.0, 0.0, 0.5, 0.1)
events.geometry(0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.1, 0.02, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1,
                0.02, -1, 1.0, 1.0)
print(json.dumps({f.__name__: [sum(f.stats.cache_hits.values()),
                               sum(f.stats.cache_misses.values()), f.stats.cache_path]
                  for f in (contacts.capsule_capsule, motion.slide, events.geometry)}))
"""


def _copy_package(dest: Path) -> Path:
    """A runnable copy of the installed package tree: ``dest/spinstrike/{physics,envs,...}``."""
    root = dest / "spinstrike"
    root.mkdir(parents=True)
    shutil.copy(spinstrike.__file__, root / "__init__.py")
    for name in ("physics", "envs", "agents", "benchmarks", "configs"):
        src = Path(importlib.import_module(f"spinstrike.{name}").__path__[0])
        shutil.copytree(src, root / name, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _probe(tree: Path, cache: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree), SPINSTRIKE_CACHE_DIR=str(cache),
               SPINSTRIKE_QUIET="1")
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, cwd=tree, capture_output=True,
                         text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_cache_lives_in_its_own_directory_and_follows_the_import_closure(tmp_path):
    tree = tmp_path / "tree"
    root = _copy_package(tree)
    cache = tmp_path / "cache"

    first = _probe(tree, cache)
    assert all(misses > 0 for _, misses, _ in first.values()), first
    for _, _, path in first.values():
        assert Path(path).is_relative_to(cache), path
    # nothing was written beside the sources
    assert not list(root.rglob("*.nbi")) and not list(root.rglob("*.nbc"))
    # each folder names the source directory it was compiled from (what --prune checks)
    folders = [d for d in cache.iterdir() if d.is_dir()]
    assert folders and all(Path((d / "SOURCE").read_text().strip()).is_relative_to(root)
                           for d in folders)

    again = _probe(tree, cache)
    assert all(hits > 0 and misses == 0 for hits, misses, _ in again.values()), again

    contacts = root / "physics" / "contacts.py"
    contacts.write_text(contacts.read_text() + "\n# an edit\n")
    edited = _probe(tree, cache)
    assert edited["capsule_capsule"][1] > 0, "its own file changed"
    assert edited["geometry"][1] > 0, "events.py imports contacts.py: its kernel is stale"
    assert edited["slide"][0] > 0 and edited["slide"][1] == 0, "motion.py does not depend on it"


@pytest.mark.parametrize("where", ["SPINSTRIKE_CACHE_DIR", "default"])
def test_cache_command_reports_and_clears(tmp_path, where):
    """In a folder ``SPINSTRIKE_CACHE_DIR`` names, a kernel folder is one with SpinStrike's
    ``SOURCE`` marker; in the default folder, SpinStrike's own, also one from before the
    marker (numba's files alone)."""
    env = {k: v for k, v in os.environ.items() if k != "SPINSTRIKE_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(tmp_path / "xdg"), TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    if where == "default":
        cache = tmp_path / "xdg" / "spinstrike" / "kernels"
    else:
        cache = tmp_path / "cache"
        env["SPINSTRIKE_CACHE_DIR"] = str(cache)
    (cache / "physics_x").mkdir(parents=True)
    (cache / "physics_x" / "k.nbi").write_bytes(b"x" * 10)
    (cache / "physics_x" / "k.py311.0123abcd.lock").touch()  # processes' turns: not a kernel
    if where != "default":
        (cache / "physics_x" / "SOURCE").write_text(str(tmp_path))
    script = Path(sys.executable).with_name("spinstrike")
    out = subprocess.run([str(script), "cache"], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    files = 1 if where == "default" else 2  # the index (and the marker)
    assert out.returncode == 0 and str(cache) in out.stdout
    assert f"({files} files, 0.0 MB in 1 folder," in out.stdout
    out = subprocess.run([str(script), "cache", "--clear"], env=env, capture_output=True,
                         text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0 and f"removed {files}" in out.stdout
    assert not (cache / "physics_x").exists()


def test_clearing_a_shared_cache_folder_removes_the_kernels_only(tmp_path):
    """``SPINSTRIKE_CACHE_DIR`` may name a folder that holds other things (``~/.cache``,
    ``/scratch/$USER``, a numba cache shared with other projects through
    ``NUMBA_CACHE_DIR``): ``--clear`` removed the whole folder, then (W16) every folder with
    numba's files, another project's numba cache too, and ``spinstrike cache`` counted its
    files as kernels. Only SpinStrike's kernel folders (a ``SOURCE`` marker) are touched."""
    cache = tmp_path / "shared"
    (cache / "other_tool").mkdir(parents=True)
    (cache / "other_tool" / "blob").write_text("x")
    (cache / "notes.txt").write_text("my data")
    for name, marker in (("physics_new", "SOURCE"), ("myproj_numba", "k.nbi")):
        (cache / name).mkdir()
        (cache / name / marker).write_text(str(tmp_path))
        (cache / name / "k.nbc").write_bytes(b"x" * 10)
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(cache), TMPDIR=str(tmp_path))
    script = Path(sys.executable).with_name("spinstrike")
    out = subprocess.run([str(script), "cache"], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert out.returncode == 0 and "(2 files, 0.0 MB in 1 folder," in out.stdout
    out = subprocess.run([str(script), "cache", "--clear"], env=env, capture_output=True,
                         text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0 and "removed 2" in out.stdout
    assert sorted(p.name for p in cache.iterdir()) == ["myproj_numba", "notes.txt", "other_tool"]
    assert (cache / "other_tool" / "blob").read_text() == "x"
    assert sorted(p.name for p in (cache / "myproj_numba").iterdir()) == ["k.nbc", "k.nbi"]


def test_a_relative_cache_dir_is_made_absolute(tmp_path, monkeypatch):
    from spinstrike.physics.cache import cache_dir

    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SPINSTRIKE_CACHE_DIR", "kc")
    assert cache_dir() == tmp_path / "kc"


def test_cache_prune_removes_the_folders_of_deleted_installs_only(tmp_path):
    """Each clone, venv or CI checkout compiles into a folder of its own; once it is deleted,
    ``spinstrike cache`` says so and ``--prune`` removes its kernels, not the others'."""
    cache = tmp_path / "cache"
    for name, source in (("physics_gone", tmp_path / "deleted-clone"), ("physics_here", tmp_path)):
        (cache / name).mkdir(parents=True)
        (cache / name / "k.nbc").write_bytes(b"x" * 2_000_000)
        (cache / name / "SOURCE").write_text(f"{source}\n")
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(cache))
    script = Path(sys.executable).with_name("spinstrike")
    out = subprocess.run([str(script), "cache"], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "in 2 folders" in out.stdout and "from SPINSTRIKE_CACHE_DIR" in out.stdout
    assert "1 of them (2.0 MB) belong to source directories that are gone" in out.stdout
    out = subprocess.run([str(script), "cache", "--prune"], env=env, capture_output=True,
                         text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0 and "removed 1 cache folders" in out.stdout
    assert sorted(d.name for d in cache.iterdir()) == ["physics_here"]


def _cache_cli(tree: Path, cache: Path, *args: str) -> str:
    """``python -m spinstrike cache ARGS`` run by the package copy in ``tree``."""
    env = dict(os.environ, PYTHONPATH=str(tree), SPINSTRIKE_CACHE_DIR=str(cache))
    out = subprocess.run([sys.executable, "-m", "spinstrike", "cache", *args], env=env, cwd=tree,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_cache_prune_removes_the_kernels_an_edit_has_outdated(tmp_path):
    """numba names a kernel's files by its function's line: an edit that moves a function left
    the old files beside the new ones, so an edited checkout's cache grew until ``--clear``.
    ``spinstrike cache`` counts them, ``--prune`` removes them: the kernels of the sources as
    they are stay (the next run loads every one, compiles none), and another install's
    outdated kernels stay too (its stamps are its own process's to compute)."""
    tree, other = tmp_path / "tree", tmp_path / "other"
    root, other_root = _copy_package(tree), _copy_package(other)
    cache = tmp_path / "cache"
    for t in (tree, other):
        _probe(t, cache)
    for r in (root, other_root):  # moves every function of contacts.py down a line
        contacts = r / "physics" / "contacts.py"
        contacts.write_text("# an edit\n" + contacts.read_text())
    for t in (tree, other):
        edited = _probe(t, cache)
        assert edited["capsule_capsule"][1] > 0 and edited["slide"][1] == 0, edited

    def folder(r: Path) -> Path:
        return next(d for d in cache.iterdir()
                    if Path((d / "SOURCE").read_text().strip()) == (r / "physics").resolve())

    here, there = folder(root), folder(other_root)
    old = sorted(here.glob("contacts.capsule_capsule-*.nbi"),
                 key=lambda p: int(p.name.split("-")[1].split(".")[0]))
    assert len(old) == 2, old  # the function's first line before and after the edit
    files_before = {p.name for p in there.iterdir()}

    report = _cache_cli(tree, cache)
    assert "this install's kernels that its edited sources have outdated" in report, report
    out = _cache_cli(tree, cache, "--prune")
    assert "removed 0 cache folders" in out
    removed = int(out.split("removed ")[2].split()[0])
    assert removed >= 2, out  # at least the old capsule_capsule index and its data
    left = sorted(here.glob("contacts.capsule_capsule-*"))
    assert old[0] not in left and old[1] in left, left  # the newer line is the current one
    assert not [p for p in here.glob("*.nbc")
                if not (here / (p.name.rsplit(".", 2)[0] + ".nbi")).is_file()]
    assert {p.name for p in there.iterdir()} == files_before, "another install's: kept"
    assert "outdated" not in _cache_cli(tree, cache)

    again = _probe(tree, cache)
    assert all(hits > 0 and misses == 0 for hits, misses, _ in again.values()), again


def test_importing_creates_no_cache_directory(tmp_path):
    cache = tmp_path / "never"
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(cache))
    out = subprocess.run([sys.executable, "-c", "import spinstrike.envs.fast"], env=env,
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    assert not cache.exists()


@pytest.mark.parametrize("value", ["", None])
def test_default_location_is_the_user_cache(monkeypatch, value):
    from spinstrike.physics.cache import cache_dir

    if value is None:
        monkeypatch.delenv("SPINSTRIKE_CACHE_DIR", raising=False)
    else:
        monkeypatch.setenv("SPINSTRIKE_CACHE_DIR", value)
    path = cache_dir()
    assert path.name == "kernels" and "spinstrike" in path.parts
    assert not path.is_relative_to(Path(spinstrike.__file__).parent.parent)


def test_warm_up_compiles_an_envs_kernels_for_the_next_process(tmp_path):
    """``spinstrike.envs.warm`` (what ``spinstrike train`` starts while PyTorch imports) leaves
    the env's kernels in the cache: the next process's strike is a cache hit, not a compile."""
    cache = tmp_path / "cache"
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(cache), SPINSTRIKE_QUIET="1")
    code = ("import os; from spinstrike.envs.warm import warm_up; "
            "assert warm_up('SpinStrike/PuckSpeed-v0', 2, {'restitution': 0.8}).wait()")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=600)
    assert out.returncode == 0, out.stderr
    check = ("import gymnasium as gym, numpy as np, spinstrike\n"
             "from spinstrike.envs import fast\n"
             "v = gym.make_vec('SpinStrike/PuckSpeed-v0', num_envs=2, restitution=0.8,\n"
             "                 vectorization_mode='vector_entry_point')\n"
             "v.reset(seed=1); v.step(np.zeros((2, 3), np.float32))\n"
             "s = fast.strike_body.stats\n"
             "print(sum(s.cache_hits.values()), sum(s.cache_misses.values()))\n")
    out = subprocess.run([sys.executable, "-c", check], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=600)
    assert out.returncode == 0, out.stderr
    hits, misses = map(int, out.stdout.split())
    assert hits >= 1 and misses == 0


def test_warm_up_imports_the_package_this_process_runs(tmp_path, monkeypatch):
    """The warm-up runs ``python -m spinstrike.envs.warm``, which puts its working directory
    first on ``sys.path``: started from the root of a checkout while the installed package ran,
    it compiled the checkout's kernels. It now runs beside the package this process imported."""
    from spinstrike.envs import warm

    seen = {}

    class Recorder:
        def __init__(self, args, **kwargs):
            seen.update(kwargs, args=args)

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(warm.subprocess, "Popen", Recorder)
    warm.warm_up("SpinStrike/RodSpin-v0")
    monkeypatch.undo()  # subprocess.Popen is the module's: put it back before using it
    out = subprocess.run([sys.executable, "-c", "import spinstrike; print(spinstrike.__file__)"],
                         cwd=seen["cwd"], capture_output=True, text=True, timeout=300)
    assert Path(out.stdout.strip()).resolve() == Path(spinstrike.__file__).resolve()


@pytest.mark.parametrize("module", ["spinstrike.physics.kernels", "spinstrike.physics.solvers",
                                    "spinstrike.envs.fast"])
def test_the_stamp_covers_every_import_of_a_kernel_module(module):
    """Every ``spinstrike`` module a kernel module imports is in its stamp, also an import
    that follows a parenthesised list (the pattern once ran on into it: ``kernels.py``'s stamp
    missed ``solvers.py``, so an edit of the solvers kept stale kernels)."""
    import ast

    from spinstrike.physics.cache import _closure

    path = Path(importlib.import_module(module).__file__).resolve()
    stamped = {p.resolve() for p in _closure(path)}
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("spinstrike."):
            dep = Path(importlib.import_module(node.module).__file__).resolve()
            assert dep in stamped, f"{module}: {node.module} is not in its kernels' stamp"


def test_the_stamp_follows_every_form_of_import(tmp_path):
    """Relative imports, ``from spinstrike import pkg``, several modules on one line, a
    backslash continuation and imports inside functions are in a kernel's stamp (a pattern
    saw absolute ``from spinstrike.x`` lines only: a kernel module importing a sibling as
    ``from .tuning import SCALE`` kept its stale kernel after an edit of ``tuning.py``)."""
    from spinstrike.physics import cache as kernel_cache

    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    for name in ("a.py", "b.py", "c.py", "sub/__init__.py", "sub/d.py"):
        (pkg / name).write_text("X = 1\n")
    kern = pkg / "kern.py"
    kern.write_text("from .a import X\n"
                    "from . import b\n"
                    "from .sub import d\n"
                    "import numpy as np, spinstrike.physics.layout\n"
                    "from spinstrike import physics\n"
                    "from spinstrike.physics.motion import \\\n    slide\n"
                    "def f():\n    from .c import *\n")
    names = {p.relative_to(p.parents[1]).as_posix()
             for p in kernel_cache._closure(kern.resolve())}
    for want in ("pkg/a.py", "pkg/b.py", "pkg/c.py", "sub/d.py", "sub/__init__.py",
                 "physics/layout.py", "physics/motion.py", "physics/__init__.py"):
        assert want in names, (want, sorted(names))
    before = kernel_cache.module_stamp(kern)
    kernel_cache._stamp.cache_clear()
    kernel_cache._closure.cache_clear()
    (pkg / "c.py").write_text("X = 2\n")  # the import inside a function
    assert kernel_cache.module_stamp(kern) != before


KERNEL = """
from spinstrike.physics.jit import jit


@jit
def plus_one(x):
    return x + 1
"""


def test_a_process_stuck_holding_a_kernels_lock_is_waited_for_a_while_only(tmp_path, monkeypatch):
    """Processes on a cold cache take turns compiling (``cache.take_turns``): a process finding a
    kernel's lock held waits, and loads what the holder saved. One stuck holding it (stopped,
    say) is not waited for past ``LOCK_TIMEOUT``: the kernel compiles here too, with a warning
    naming the lock, and runs."""
    from filelock import FileLock
    from numba import types

    from spinstrike.physics import cache

    monkeypatch.setenv("SPINSTRIKE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "LOCK_TIMEOUT", 0.3)
    (tmp_path / "kern_locked.py").write_text(KERNEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    kernel = importlib.import_module("kern_locked").plus_one
    turn = cache._turn(kernel._cache, (types.int64,))
    assert turn.path.parent == Path(kernel.stats.cache_path)
    turn.path.parent.mkdir(parents=True)
    holder = subprocess.Popen([sys.executable, "-c", (
        f"import sys, time; from filelock import FileLock; lock = FileLock({str(turn.path)!r}); "
        "lock.acquire(); print('held', flush=True); time.sleep(60)")],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.warns(RuntimeWarning, match=r"another process has held .*\.lock for 0.3 s"):
            assert kernel(1) == 2
        assert sum(kernel.stats.cache_misses.values()) == 1
    finally:
        holder.kill()
        holder.wait()
    with FileLock(turn.path, timeout=0):  # this process let go of it
        pass


def test_a_soft_lock_left_by_a_killed_process_is_taken_over_at_once(tmp_path, monkeypatch):
    """On a filesystem without ``flock`` filelock falls back to a soft lock: a lock file whose
    presence is the lock, which a killed holder leaves behind. filelock >= 4.2.1 (the floor in
    pyproject.toml) records the holder and breaks a dead one's lock; with 3.x the next process
    waited ``LOCK_TIMEOUT`` (900 s) for it. Here the soft lock stands in for the fallback."""
    from filelock import SoftFileLock

    from spinstrike.physics import cache

    monkeypatch.setenv("SPINSTRIKE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(cache, "FileLock", SoftFileLock)
    monkeypatch.setattr(cache, "LOCK_TIMEOUT", 120.0)
    (tmp_path / "kern_soft.py").write_text(KERNEL)
    monkeypatch.syspath_prepend(str(tmp_path))
    kernel = importlib.import_module("kern_soft").plus_one
    from numba import types

    path = cache._turn(kernel._cache, (types.int64,)).path
    path.parent.mkdir(parents=True)
    holder = subprocess.Popen([sys.executable, "-c", (
        f"import time; from filelock import SoftFileLock; lock = SoftFileLock({str(path)!r}); "
        "lock.acquire(); "
        "print('held', flush=True); time.sleep(60)")], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    holder.kill()
    holder.wait()
    assert path.exists()  # left behind
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no "held for 120 s; compiling here too"
        assert kernel(1) == 2
    assert time.perf_counter() - start < 60
    assert sum(kernel.stats.cache_misses.values()) == 1
