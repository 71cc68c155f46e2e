"""Real training through RLlib (marker ``slow``, in a venv with the ``rllib`` extra:
``pytest -m slow tests/rllib/test_rllib_slow.py``; not marked ``rllib``, so ``pytest -m rllib``
stays quick).

PPO through RLlib (``spinstrike train --backend rllib``'s code, the packaged PPO entry: 150k
env steps, 2 env runners) on ``RodSpin-v0`` reaches at least 0.9 of the oracle's mean return
over 50 evaluation episodes. docs/rllib.md has the measured run.
"""

from __future__ import annotations

import pytest

ray = pytest.importorskip("ray")

pytestmark = pytest.mark.slow


def test_ppo_through_rllib_reaches_090_of_the_oracle_on_rodspin(tmp_path):
    from spinstrike.agents.rllib_train import train_rllib

    if ray.is_initialized():
        ray.shutdown()
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        result = train_rllib("SpinStrike/RodSpin-v0", seed=0, out=tmp_path / "run",
                             num_env_runners=2, eval_episodes=50, video=False)
    finally:
        ray.shutdown()
    agent = result["evaluations"]["agent"][0]
    oracle = result["evaluations"]["oracle"][0]
    print(f"agent {agent:.4f}, oracle {oracle:.4f}, ratio {agent / oracle:.3f}, "
          f"{result['timesteps']} steps, {result['wall_time']:.0f} s")
    assert agent >= 0.9 * oracle
