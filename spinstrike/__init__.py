"""SpinStrike: Gymnasium environments for striking a free rod or a puck on a 2D table, with exact
rotating-body impulse physics.

The repository's top-level folders are installed under this one namespace::

    spinstrike.physics      the engine (scene schema, impulse law, solvers, world)
    spinstrike.envs         the Gymnasium envs, native vector envs, SB3 adapter, rendering
    spinstrike.agents       SB3 baselines, oracles and the ``spinstrike`` command line
    spinstrike.benchmarks   accuracy against time, speed (``python -m spinstrike.benchmarks.speed``)
    spinstrike.configs      packaged scenes and rl-zoo3 hyperparameter files

Importing ``spinstrike`` registers the env ids, so ``gym.make("spinstrike:SpinStrike/RodSpin-v0")``
works in a fresh process (and ``--gym-packages spinstrike`` in rl-zoo3).
"""

from importlib.metadata import PackageNotFoundError, version
from pathlib import Path as _Path

# In a source checkout this folder holds only this file; the subpackages are the repository's
# top-level folders. Python puts the current folder first on sys.path, so a `python -c` or
# `python -m` run from the repository root imports this file even when the package is installed
# as a wheel, and `spinstrike.envs` would not be found: point the subpackages at the checkout
# (an installed package has them beside this file and is left alone).
_root = _Path(__file__).resolve().parent.parent
if not (_Path(__file__).resolve().parent / "envs").is_dir() and (
        _root / "pyproject.toml").is_file() and (_root / "envs" / "__init__.py").is_file():
    __path__.append(str(_root))  # noqa: F821  (the package's own __path__)
del _root

from spinstrike.envs import ENV_IDS  # noqa: E402  (registers the ids)

try:
    __version__ = version("spinstrike")
except PackageNotFoundError:  # pragma: no cover - running from an uninstalled tree
    __version__ = "0+unknown"

__all__ = ["ENV_IDS", "__version__"]
