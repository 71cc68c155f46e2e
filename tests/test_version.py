"""``spinstrike --version`` and the commit a run records where git gives none (walk W24b F9).

It said "commit unknown", which the help explained as an installed wheel, for a source copy
without ``.git`` and for a checkout git refuses ("dubious ownership": another user's, on a
shared lab machine), and for a wheel, whose build could have stamped the commit. Each case runs
``python -m spinstrike --version`` from a copy of the package (``spinstrike/{agents,...}``, as
installed) in a fresh process, and compares it with what a run records (``code_version``).
"""

from __future__ import annotations

import importlib
import os
import shutil
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

import spinstrike

REPO = Path(__file__).resolve().parent.parent

#: what a run's config.yml records as its versions (agents/train.py), beside --version's line
RECORDED = ("import sys; from spinstrike.agents.config import code_version; "
            "print(code_version()['spinstrike_commit'])")


def _copy_package(dest: Path) -> Path:
    """A runnable copy of the package tree: ``dest/spinstrike/{physics,agents,...}``."""
    root = dest / "spinstrike"
    root.mkdir(parents=True)
    for name in ("__init__.py", "__main__.py"):
        shutil.copy(Path(spinstrike.__file__).with_name(name), root / name)
    for name in ("physics", "envs", "agents", "benchmarks", "configs"):
        src = Path(importlib.import_module(f"spinstrike.{name}").__path__[0])
        shutil.copytree(src, root / name, ignore=shutil.ignore_patterns("__pycache__"))
    return root


def _version(tree: Path) -> str:
    """``spinstrike --version``'s commit, checked against what a run records."""
    env = dict(os.environ, PYTHONPATH=str(tree), SPINSTRIKE_QUIET="1")
    env.pop("GIT_DIR", None)
    out = subprocess.run([sys.executable, "-m", "spinstrike", "--version"], env=env, cwd=tree,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    prefix = f"spinstrike {version('spinstrike')} (commit "
    assert out.stdout.startswith(prefix) and out.stdout.endswith(")\n"), out.stdout
    commit = out.stdout[len(prefix):-2]
    recorded = subprocess.run([sys.executable, "-c", RECORDED], env=env, cwd=tree,
                              capture_output=True, text=True, timeout=300)
    assert recorded.returncode == 0, recorded.stderr
    assert recorded.stdout.strip() == commit, "config.yml and --version disagree"
    return commit


def _git(repo: Path, *args: str) -> str:
    out = subprocess.run(["git", "-c", f"safe.directory={repo}", "-C", str(repo), *args],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def _commit_all(repo: Path) -> str:
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    _git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "x")
    return _git(repo, "rev-parse", "--short=7", "HEAD")


needs_git = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
needs_root = pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                                reason="hands the checkout to another uid: needs root")


def test_a_copy_without_git_says_why_the_commit_is_unknown(tmp_path):
    """A source copy (``git archive``, a copied folder) is not a wheel: it says so."""
    tree = tmp_path / "tree"
    _copy_package(tree)
    assert _version(tree) == "unknown: not a git checkout"


def test_a_wheel_reads_the_commit_its_build_stamped(tmp_path):
    """An installed package without ``.git``: the commit ``setup.py``'s ``build_py`` wrote."""
    tree = tmp_path / "tree"
    root = _copy_package(tree)
    (root / "_build_commit.txt").write_text("0123abc+dirty\n")
    assert _version(tree) == "0123abc+dirty"


@needs_git
def test_the_build_stamps_the_commit_of_its_checkout(tmp_path):
    """``setup.py build_py`` (what ``pip install .`` and ``pip wheel`` run) writes the commit
    of the checkout it builds into the built package, and nothing into the sources; a build
    from a folder that is not a checkout of its own (an unpacked sdist) stamps nothing."""
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", "--no-hardlinks", str(REPO), str(clone)], check=True,
                   capture_output=True, timeout=300)
    shutil.copy(REPO / "setup.py", clone / "setup.py")  # this checkout's, edited or not
    _git(clone, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "--allow-empty",
         "-am", "setup.py as checked")
    head = _git(clone, "rev-parse", "--short", "HEAD")
    out = subprocess.run([sys.executable, "setup.py", "-q", "build_py", "--build-lib",
                          str(tmp_path / "lib")], cwd=clone, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert (tmp_path / "lib" / "spinstrike" / "_build_commit.txt").read_text() == f"{head}\n"
    assert not (clone / "spinstrike" / "_build_commit.txt").exists()

    shutil.rmtree(clone / ".git")  # an unpacked sdist
    out = subprocess.run([sys.executable, "setup.py", "-q", "build_py", "--build-lib",
                          str(tmp_path / "lib2")], cwd=clone, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    assert not (tmp_path / "lib2" / "spinstrike" / "_build_commit.txt").exists()


@needs_git
@needs_root
@pytest.mark.parametrize("refs", ["loose", "packed", "detached"])
def test_a_checkout_git_refuses_reads_the_commit_from_dot_git(tmp_path, refs):
    """A checkout owned by another uid (a colleague's, on a shared machine): git refuses it
    ("dubious ownership"), so the commit is read from ``.git`` (its ``HEAD`` and the ref, loose
    or packed, or a detached ``HEAD``), and whether files are edited is said to be unchecked;
    with ``.git`` unreadable too, it says git refused, not that it is a wheel."""
    tree = tmp_path / "tree"
    root = _copy_package(tree)
    head = _commit_all(root)
    if refs == "packed":
        _git(root, "pack-refs", "--all")
        assert not list((root / ".git" / "refs" / "heads").iterdir())
    elif refs == "detached":
        _git(root, "checkout", "-q", "--detach")
    assert _version(tree) == head, "owned by this user: git answers"

    subprocess.run(["chown", "-R", "12345:12345", str(root)], check=True)
    refused = subprocess.run(["git", "-C", str(root / "agents"), "rev-parse", "HEAD"],
                             capture_output=True, text=True)
    assert "dubious ownership" in refused.stderr, refused.stderr
    assert _version(tree) == f"{head} (edits unchecked: git refused (safe.directory))"

    (root / ".git" / "HEAD").write_text("ref: refs/heads/nowhere\n")  # an unborn branch
    assert _version(tree) == "unknown: git refused (safe.directory)"


def test_the_help_explains_unknown_as_it_is():
    out = subprocess.run([sys.executable, "-m", "spinstrike", "--help"], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())
    assert "unknown: an installed wheel" not in text
    assert "read from .git where git refuses the checkout" in text
    assert "stamped into a wheel at build" in text and "'unknown: <why>'" in text
