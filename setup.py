"""setuptools hook (the project's metadata is in pyproject.toml): a build starts its package
tree afresh.

``pip install .`` builds in the checkout's ``build/lib``, which setuptools reuses and never
empties: a module deleted since an earlier build (``git pull``) was still copied into the new
wheel and installed. ``build_py`` here removes the package's folder from ``build/lib`` before it
copies the sources (test: ``tests/test_install.py``, ``test_a_wheel_leaves_out_modules_...``).
"""

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class FreshBuildPy(build_py):
    """``build_py`` over an empty ``build_lib/spinstrike``."""

    def run(self):
        built = (Path(self.build_lib) / "spinstrike").resolve()
        if built != (Path(__file__).parent / "spinstrike").resolve():  # never the sources
            shutil.rmtree(built, ignore_errors=True)
        super().run()


setup(cmdclass={"build_py": FreshBuildPy})
