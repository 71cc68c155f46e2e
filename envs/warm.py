"""Compile an env's kernels in a background process, while the caller does other work.

A first run compiles the physics kernels (40 s to a minute on 2 cores). Work that does
not need them yet — importing PyTorch and Stable-Baselines3, building a model — can run on the
other core meanwhile: :func:`warm_up` starts a process that builds the env as it will be used
(the native vector env with the same arguments), resets and steps it once, which compiles its
kernels into the per-user cache; :meth:`WarmUp.wait` then lets the caller build its own env, which
loads them from the cache. With a filled cache the process finds nothing to compile. If the
process fails, the caller compiles as it would have anyway.

    python -m spinstrike.envs.warm SpinStrike/RodSpin-v0 16 '{"restitution": 0.9}'
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

__all__ = ["WarmUp", "warm_up"]


class WarmUp:
    """A background compilation (see :func:`warm_up`)."""

    def __init__(self, process: subprocess.Popen | None) -> None:
        self.process = process

    def wait(self, timeout: float = 600.0) -> bool:
        """Wait for the compilation; True if it finished and succeeded."""
        if self.process is None:
            return False
        try:
            return self.process.wait(timeout) == 0
        except subprocess.TimeoutExpired:
            self.process.kill()
            return False


def warm_up(env_id: str, num_envs: int = 1, env_kwargs: dict | None = None) -> WarmUp:
    """Start compiling the kernels of ``env_id`` (native vector env of ``num_envs``) in a
    background process; returns at once."""
    import spinstrike
    from spinstrike import envs

    if env_id.rpartition(":")[2] not in envs.ENV_IDS:
        # a variant, registered in this process or by a module the process below may not
        # find: its shipped env with its registered arguments (if they do not fit, the process
        # fails and the caller compiles as it would have anyway)
        env_kwargs = {**envs.variant_kwargs(env_id), **(env_kwargs or {})}
        env_id = envs.base_id(env_id)
    try:
        args = [sys.executable, "-m", "spinstrike.envs.warm", env_id, str(int(num_envs)),
                json.dumps(env_kwargs or {})]
    except TypeError:  # arguments JSON cannot carry: no warm-up, the caller compiles
        return WarmUp(None)

    # run beside the package this process imported: `python -m` puts the working directory
    # first on sys.path, and from the root of a checkout it compiled the checkout's kernels
    # (the repository's spinstrike/__init__.py), not the installed package's this run uses
    here = Path(spinstrike.__file__).resolve().parent.parent
    try:
        process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                   cwd=here)
    except OSError:
        process = None
    return WarmUp(process)


def _main(argv: list[str]) -> int:
    import gymnasium as gym
    import numpy as np

    import spinstrike  # noqa: F401  (registers the ids)

    env_id, num_envs, kwargs = argv[0], int(argv[1]), json.loads(argv[2])
    vec = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point",
                       **kwargs)
    vec.reset(seed=0)
    vec.step(np.zeros(vec.action_space.shape, vec.action_space.dtype))
    vec.close()
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
