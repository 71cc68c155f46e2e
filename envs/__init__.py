"""SpinStrike Gymnasium environments. Importing this package registers them.

    import gymnasium as gym
    import spinstrike  # registers the ids (or use "spinstrike:SpinStrike/RodSpin-v0" unimported)

    env = gym.make("SpinStrike/RodSpin-v0")
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", num_envs=1024)   # one batched world

=================================  ==========================================================
id                                 task
=================================  ==========================================================
``SpinStrike/RodSpin-v0``          one strike on a free rod; reward for reaching a target spin
``SpinStrike/PuckSpeed-v1``        one strike on a puck; reward for a target velocity
``SpinStrike/PuckSpeed-v0``        PuckSpeed with the strike heading as an angle (kept; use v1)
``SpinStrike/RodSpinControl-v0``   push a mallet on a walled table; reward for spin its hits add
``SpinStrike/PuckSpeedControl-v0`` push a mallet on a walled table; reward for speed its hits add
=================================  ==========================================================
"""

from __future__ import annotations

import gymnasium as gym

from spinstrike.envs.config import ConfigError

__all__ = ["ENV_IDS", "ConfigError", "describe"]

#: registered ids and a one-line description each
ENV_IDS: dict[str, str] = {
    "SpinStrike/RodSpin-v0": "one strike on a free rod; reward for reaching a target spin",
    "SpinStrike/PuckSpeed-v1": "one strike on a puck; reward for reaching a target velocity",
    "SpinStrike/PuckSpeed-v0":
        "PuckSpeed-v1 with the strike's heading as an angle (wraps at +-pi; kept, use v1)",
    "SpinStrike/RodSpinControl-v0":
        "push a mallet around a walled table; reward for the spin its hits give a rod",
    "SpinStrike/PuckSpeedControl-v0":
        "push a mallet around a walled table; reward for the speed its hits give a puck",
}

#: entry points (single env, native vector env, in ``spinstrike.envs``) and episode step limits
#: (each the vector env's ``MAX_EPISODE_STEPS``: a test checks; kept here so that registering
#: imports no env module)
_ENTRY = {
    "SpinStrike/RodSpin-v0": ("strike:RodSpinEnv", "strike:RodSpinVectorEnv", None),
    "SpinStrike/PuckSpeed-v0": ("strike:PuckSpeedEnv", "strike:PuckSpeedVectorEnv", None),
    "SpinStrike/PuckSpeed-v1": ("strike:PuckSpeedV1Env", "strike:PuckSpeedV1VectorEnv", None),
    "SpinStrike/RodSpinControl-v0": ("control:RodSpinControlEnv",
                                     "control:RodSpinControlVectorEnv", 250),
    "SpinStrike/PuckSpeedControl-v0": ("control:PuckSpeedControlEnv",
                                       "control:PuckSpeedControlVectorEnv", 250),
}


def _register() -> None:
    for env_id, (entry, vector_entry, steps) in _ENTRY.items():
        if env_id in gym.registry:
            continue
        gym.register(id=env_id, entry_point=f"spinstrike.envs.{entry}",
                     vector_entry_point=f"spinstrike.envs.{vector_entry}",
                     max_episode_steps=steps, disable_env_checker=False)


def describe() -> str:
    """One line per registered id."""
    return "\n".join(f"{k:34s} {v}" for k, v in ENV_IDS.items())


_register()
