"""setuptools hook (the project's metadata is in pyproject.toml): a build starts its package
tree afresh.

``pip install .`` builds in the checkout's ``build/lib``, which setuptools reuses and never
empties: a module deleted since an earlier build (``git pull``) was still copied into the new
wheel and installed. ``build_py`` here removes the package's folder from ``build/lib`` before it
copies the sources (test: ``tests/test_install.py``, ``test_a_wheel_leaves_out_modules_...``).

It also stamps the commit the package is built from (``git rev-parse --short HEAD``,
``+dirty`` where tracked files are edited) into ``spinstrike/_build_commit.txt``, which
``spinstrike --version`` and a run's ``config.yml`` read where there is no checkout to ask: a
wheel said "commit unknown", so runs trained from one had no provenance (walk W24b F9;
``spinstrike.agents.config.commit``, test: ``tests/test_version.py``). A build from a folder
that is not a git checkout of its own (an sdist, a copy) stamps nothing.
"""

import shutil
import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

#: what ``spinstrike.agents.config.BUILD_COMMIT_FILE`` reads
BUILD_COMMIT_FILE = "_build_commit.txt"


def _commit(root: Path) -> str | None:
    """The commit of checkout ``root`` (``+dirty`` if edited); None where ``root`` is not the
    top of a git checkout (an unpacked sdist inside some other repository has that one's)."""
    def git(*args):
        return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                              check=True).stdout.strip()

    try:
        if Path(git("rev-parse", "--show-toplevel")).resolve() != root.resolve():
            return None
        edited = git("status", "--porcelain", "--untracked-files=no")
        return git("rev-parse", "--short", "HEAD") + ("+dirty" if edited else "")
    except (OSError, subprocess.CalledProcessError):
        return None


class FreshBuildPy(build_py):
    """``build_py`` over an empty ``build_lib/spinstrike``, with the commit stamped in it."""

    def run(self):
        built = (Path(self.build_lib) / "spinstrike").resolve()
        sources = (Path(__file__).parent / "spinstrike").resolve()
        if built != sources:  # never the sources
            shutil.rmtree(built, ignore_errors=True)
        super().run()
        commit = _commit(Path(__file__).parent)
        if commit and built != sources and not getattr(self, "editable_mode", False):
            (built / BUILD_COMMIT_FILE).write_text(commit + "\n")


setup(cmdclass={"build_py": FreshBuildPy})
