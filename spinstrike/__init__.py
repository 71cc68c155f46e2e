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

from spinstrike.envs import ENV_IDS  # registers the ids

try:
    __version__ = version("spinstrike")
except PackageNotFoundError:  # pragma: no cover - running from an uninstalled tree
    __version__ = "0+unknown"

__all__ = ["ENV_IDS", "__version__"]
