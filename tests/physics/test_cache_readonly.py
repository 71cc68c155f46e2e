"""A kernel cache that is readable but not writable (walk W24b F8).

A team shares a prebuilt cache read-only (NFS, an image layer, a ``ro`` bind mount) through
``SPINSTRIKE_CACHE_DIR``. It was skipped whole: every process recompiled into the fallback under
/tmp (35 s instead of 2) without saying why; ``spinstrike cache`` counted the fallback's files
as the shared folder's; ``--clear`` said it removed files it could not remove, exit 0; and the
fallback was named while the folder was writable again.

Unwritability is simulated through the check the cache makes (``os.access(path, W_OK)``, denied
for the cache folder in the subprocess: the tests run as root, which passes any permission
bits), and, where ``unshare -m`` works, made real with a read-only bind mount.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

#: run first in each subprocess: ``os.access`` says the folder $RO_CACHE is not writable
DENY = """
import os, sys
_ro, _access = os.environ.get("RO_CACHE"), os.access
def _denied(path, mode, *args, **kwargs):
    if _ro and mode & os.W_OK and os.path.abspath(os.fspath(path)).startswith(_ro):
        return False
    return _access(path, mode, *args, **kwargs)
os.access = _denied
"""

PROBE = DENY + """
import json
from spinstrike.physics import contacts, motion
contacts.capsule_capsule(0.0, 0.0, 0.0, 0.1, 0.02, 0.5, 0.0, 0.0, 0.1, 0.02)
motion.slide(0.0, 0.0, 1.0, 0.0, 0.5, 0.1)
print(json.dumps({f.__name__: [sum(f.stats.cache_hits.values()),
                               sum(f.stats.cache_misses.values()), f.stats.cache_path]
                  for f in (contacts.capsule_capsule, motion.slide)}))
"""

CLI = DENY + """
from spinstrike.agents.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _env(tmp_path: Path, cache: Path, read_only: bool) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in ("SPINSTRIKE_QUIET", "RO_CACHE")}
    env.update(SPINSTRIKE_CACHE_DIR=str(cache), TMPDIR=str(tmp_path / "tmp"))
    if read_only:
        env["RO_CACHE"] = str(cache)
    return env


def _run(code: str, tmp_path: Path, cache: Path, *args: str, read_only: bool = False):
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          env=_env(tmp_path, cache, read_only), cwd=tmp_path, timeout=600)


def _probe(tmp_path: Path, cache: Path, read_only: bool = False) -> tuple[dict, str]:
    out = _run(PROBE, tmp_path, cache, read_only=read_only)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


def _files(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.stat().st_mtime_ns for p in root.rglob("*")}


def _shared_cache(tmp_path: Path) -> Path:
    """A cache folder holding ``capsule_capsule``'s kernels, fresh, and not ``slide``'s."""
    cache = tmp_path / "shared"
    _probe(tmp_path, cache)
    for f in cache.rglob("motion.slide-*"):
        f.unlink()
    shutil.rmtree(tmp_path / "tmp")
    return cache


def test_a_read_only_cache_is_loaded_from_and_new_kernels_go_to_the_fallback(tmp_path):
    """The kernels the read-only folder holds load from it; the one it lacks compiles once,
    into the fallback, and the process says why, once, on stderr; the folder is not touched."""
    cache = _shared_cache(tmp_path)
    before = _files(cache)
    fallback = tmp_path / "tmp" / f"spinstrike-kernels-{os.getuid()}"

    first, err = _probe(tmp_path, cache, read_only=True)
    assert first["capsule_capsule"][:2] == [1, 0], f"not loaded from the read-only cache: {first}"
    assert first["slide"][1] == 1 and Path(first["slide"][2]).is_relative_to(fallback), first
    why = f"spinstrike: {cache} is not writable: new kernels go to {fallback}"
    assert err.count(why) == 1, err
    assert err.count("is not writable") == 1, err
    assert _files(cache) == before, "the read-only cache was written to"

    again, err = _probe(tmp_path, cache, read_only=True)
    assert all(hits == 1 and misses == 0 for hits, misses, _ in again.values()), again
    assert "not writable" not in err and "compiling" not in err, err


def test_the_cache_command_counts_each_directory_apart(tmp_path):
    """``spinstrike cache``: the read-only folder's own counts, the fallback's on a line of its
    own, saying it is in use (it counted both as the folder's: 360 files where it held 240)."""
    cache = _shared_cache(tmp_path)
    fallback = tmp_path / "tmp" / f"spinstrike-kernels-{os.getuid()}"
    _probe(tmp_path, cache, read_only=True)  # slide compiles into the fallback
    own = sum(1 for f in cache.rglob("*") if f.is_file() and f.suffix != ".lock")
    extra = sum(1 for f in fallback.rglob("*") if f.is_file() and f.suffix != ".lock")
    assert own and extra

    out = _run(CLI, tmp_path, cache, "cache", read_only=True)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].startswith(f"compiled kernels: {cache} ({own} files, "), out.stdout
    assert "not writable: its kernels load, new ones go to the fallback" in lines[0]
    assert lines[-1].startswith(f"fallback: {fallback} ({extra} files, "), out.stdout
    assert "is not writable" in lines[-1]


def test_the_fallback_is_named_only_while_in_use_or_holding_kernels(tmp_path):
    """With the folder writable again, an empty fallback is not mentioned (it was, as "the
    directory above was not writable", while the folder was writable); one that still holds
    kernels is, with its own counts, as not in use (a folder with only the marker and locks a
    process leaves there while loading its kernels from the cache folder is not)."""
    cache = _shared_cache(tmp_path)
    fallback = tmp_path / "tmp" / f"spinstrike-kernels-{os.getuid()}"
    _probe(tmp_path, cache, read_only=True)

    out = _run(CLI, tmp_path, cache, "cache")
    assert out.returncode == 0, out.stderr
    assert "not writable: its kernels load" not in out.stdout
    assert f"fallback: {fallback} (" in out.stdout and "not used while it is" in out.stdout

    for folder in fallback.iterdir():  # its kernels removed; a process's marker and lock left
        for f in folder.iterdir():
            if f.name != "SOURCE" and f.suffix != ".lock":
                f.unlink()
    out = _run(CLI, tmp_path, cache, "cache")
    assert out.returncode == 0, out.stderr
    assert len(out.stdout.splitlines()) == 1 and "fallback:" not in out.stdout, out.stdout


def _unshare_works() -> bool:
    if shutil.which("unshare") is None:
        return False
    try:
        return subprocess.run(["unshare", "-m", "true"], capture_output=True,
                              timeout=30).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


@pytest.mark.skipif(not _unshare_works(), reason="needs unshare -m (a private mount namespace)")
def test_clear_and_prune_on_a_read_only_mount_say_what_stays(tmp_path):
    """Under a real read-only bind mount: a run loads from it; ``--clear`` removes the
    fallback's files, says on stderr how many of the folder's it could not remove and why, and
    exits 1 (it said "removed 360 cached kernel files", exit 0, and all 240 stayed);
    ``--prune`` likewise for the folder of a deleted checkout."""
    cache = _shared_cache(tmp_path)
    gone = cache / "physics_gone"
    gone.mkdir()
    (gone / "k.nbc").write_bytes(b"x")
    (gone / "SOURCE").write_text(f"{tmp_path / 'deleted-clone'}\n")
    own = sum(1 for f in cache.rglob("*") if f.is_file() and f.suffix != ".lock")
    before = _files(cache)
    script = Path(sys.executable).with_name("spinstrike")
    probe = tmp_path / "probe.py"
    probe.write_text(PROBE)
    inner = (f'mount --bind -o ro "{cache}" "{cache}" || exit 99; '
             f'"{sys.executable}" "{probe}" >&2 || exit 98; '
             f'"{script}" cache --prune; echo "prune rc=$?"; '
             f'"{script}" cache --clear; echo "clear rc=$?"')
    (tmp_path / "tmp").mkdir()
    out = subprocess.run(["unshare", "-m", "sh", "-c", inner], capture_output=True, text=True,
                         env=_env(tmp_path, cache, False), cwd=tmp_path, timeout=600)
    if out.returncode == 99:
        pytest.skip(f"mount --bind -o ro refused: {out.stderr}")
    assert out.returncode == 0, out.stderr
    assert f"{cache} is not writable: new kernels go to" in out.stderr, out.stderr
    assert "prune rc=1" in out.stdout and "clear rc=1" in out.stdout, out.stdout + out.stderr
    assert (f"could not remove 1 folders of sources that are gone in {cache} "
            "(Read-only file system)") in out.stderr, out.stderr
    assert f"could not remove {own} kernel files in {cache} (Read-only file system)" \
        in out.stderr, out.stderr
    cleared = out.stdout.split("clear rc")[0].splitlines()[-1]
    fallback_files = 3  # slide's index, data and the folder's SOURCE marker
    assert cleared.startswith(f"removed {fallback_files} cached kernel files"), out.stdout
    assert _files(cache) == before


@pytest.mark.parametrize("made_by", ["another user", "anyone may write"])
def test_a_fallback_made_by_someone_else_is_not_used(tmp_path, made_by):
    """Walk W25 F6: the fallback's name in the shared temporary directory is predictable
    (``spinstrike-kernels-<uid>``); one made beforehand by another user, or writable by all, was
    used without a word, and numba unpickles the kernels it loads: files planted there ran in
    this process. Such a folder is refused, said once on stderr, and nothing is written to or
    loaded from it (the kernels compile uncached)."""
    cache = _shared_cache(tmp_path)
    fallback = tmp_path / "tmp" / f"spinstrike-kernels-{os.getuid()}"
    (tmp_path / "tmp").mkdir(exist_ok=True)
    fallback.mkdir()
    if made_by == "another user":
        if os.getuid() != 0:
            pytest.skip("needs root to give the folder to another user")
        os.chown(fallback, 65534, 65534)
    else:
        fallback.chmod(0o777)
    out = _run(PROBE, tmp_path, cache, read_only=True)
    assert out.returncode == 0, out.stderr
    assert out.stderr.count(f"spinstrike: {fallback} is not this user's own folder") == 1, \
        out.stderr
    assert "kernels are not cached" in out.stderr
    assert list(fallback.iterdir()) == []


def test_the_fallback_is_made_private(tmp_path):
    """A fallback this process makes is its user's alone (mode 0o700), not the umask's."""
    cache = _shared_cache(tmp_path)
    _probe(tmp_path, cache, read_only=True)
    fallback = tmp_path / "tmp" / f"spinstrike-kernels-{os.getuid()}"
    assert fallback.stat().st_mode & 0o777 == 0o700
