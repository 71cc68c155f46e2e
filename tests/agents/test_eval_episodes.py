"""Learning-curve evaluations see the same episodes at every point and in every run (issue 16:
'evaluation episodes fixed by seed so every policy sees the same tasks'), through ``train``."""

import numpy as np
import pytest
from stable_baselines3.common.vec_env import VecEnvWrapper

from spinstrike.agents import train as train_module
from spinstrike.envs import sb3


class _Recorder(VecEnvWrapper):
    """Keeps every observation the evaluation env hands out, one list per evaluation."""

    def __init__(self, venv, log):
        super().__init__(venv)
        self.log = log

    def reset(self):
        obs = self.venv.reset()
        self.log.append([obs.copy()])
        return obs

    def step_wait(self):
        obs, reward, done, info = self.venv.step_wait()
        self.log[-1].append(obs.copy())
        return obs, reward, done, info


def _evaluations(monkeypatch, tmp_path, seed):
    log = []
    make = sb3.make_sb3_vec_env

    def recording(env_id, n_envs, seed=None, env_kwargs=None):
        env = make(env_id, n_envs, seed=seed, env_kwargs=env_kwargs)
        return _Recorder(env, log) if seed == train_module.EVAL_SEED else env

    monkeypatch.setattr(sb3, "make_sb3_vec_env", recording)
    train_module.train("ppo", "SpinStrike/RodSpin-v0", seed=seed, timesteps=4096,
                       eval_freq=1024, eval_episodes_during=4, out=tmp_path / f"s{seed}",
                       progress=False, evaluate=False, video=False)
    return log


@pytest.mark.filterwarnings("ignore:Training and eval env are not of the same type")
def test_every_evaluation_of_every_run_sees_the_same_episodes(monkeypatch, tmp_path):
    runs = [_evaluations(monkeypatch, tmp_path, seed) for seed in (0, 1)]
    for log in runs:
        assert len(log) >= 2, "expected several evaluations along the learning curve"
    # RodSpin's episodes last one step, so what an evaluation observes is its episodes' starts,
    # whatever the policy does: the same at every evaluation of both runs
    first = np.concatenate(runs[0][0])
    assert len(first) >= 4 and len(np.unique(first, axis=0)) >= 2  # distinct episodes
    for log in runs:
        for evaluation in log:
            np.testing.assert_array_equal(np.concatenate(evaluation)[:len(first)], first)
