"""Per-element random streams for batched envs, bit-identical to single envs.

Element ``i`` of a vector env seeded ``s`` draws exactly what a single env seeded ``s + i`` draws
(Gymnasium's convention): each element owns a ``numpy.random.Generator`` made by
``gymnasium.utils.seeding.np_random``, and every episode consumes one row of uniforms from it.
Rows are drawn in blocks, so the Python loop over elements runs once per ``BLOCK`` resets of an
element, not at every reset; a single env draws its row from ``np_random`` at each reset (the
same numbers: a block is the rows drawn one after another).
"""

from __future__ import annotations

import numbers

import numpy as np
from gymnasium.utils import seeding

__all__ = ["BLOCK", "UniformStream"]

#: episodes' worth of uniforms drawn at once per element
BLOCK = 64


class UniformStream:
    """``width`` uniforms in [0, 1) per element per episode."""

    def __init__(self, batch_size: int, width: int) -> None:
        self.batch_size = batch_size
        self.width = width
        self.generators: list[np.random.Generator] = [None] * batch_size  # type: ignore
        #: each element's seed: the one given, else the one its generator was drawn from (as a
        #: single env's ``np_random_seed``: reseeding with it replays an unseeded run)
        self.seeds: list[int] = [0] * batch_size
        self._buffer = np.zeros((batch_size, BLOCK, width))
        self._next = np.full(batch_size, BLOCK)
        self.seed([None] * batch_size)  # unseeded: generators from fresh entropy

    def seed(self, seeds, env: np.ndarray | None = None) -> None:
        """Reseed elements (all, or ``env``) with the given seeds (one per element, or None)."""
        idx = np.arange(self.batch_size) if env is None else np.asarray(env)
        for i, s in zip(idx, seeds, strict=True):
            # numpy's integers too (exact); anything else (1.5 was truncated to 1) raises
            # Gymnasium's own error, as a single env's and SyncVectorEnv's reset does
            if isinstance(s, numbers.Integral):
                s = int(s)
            self.generators[i], seed = seeding.np_random(s)
            self.seeds[i] = int(seed)
            self._next[i] = BLOCK

    def draw(self, env: np.ndarray) -> np.ndarray:
        """One row of uniforms for each element in ``env``: ``[len(env), width]``."""
        env = np.asarray(env, dtype=np.int64)
        for i in env[self._next[env] >= BLOCK]:
            self._buffer[i] = self.generators[i].random((BLOCK, self.width))
            self._next[i] = 0
        rows = self._buffer[env, self._next[env]]
        self._next[env] += 1
        return rows
