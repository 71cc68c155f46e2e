"""What a hyperparameter file (rl-zoo3's format, ``configs/agents/*.yml``) says reaches the run,
through ``spinstrike train --config FILE``. The values it refuses are cases of
``test_cli_bad_input.py`` (one ``error:`` line naming the key)."""

import functools

import pytest

from spinstrike.agents.cli import main

ENV = "SpinStrike/RodSpin-v0"
#: a PPO entry that trains in seconds: one rollout of 64 steps
TINY = "  n_timesteps: 64\n  n_envs: 1\n  n_steps: 64\n  batch_size: 64\n"


def _train(tmp_path, entry: str, *extra: str) -> int:
    path = tmp_path / "c.yml"
    path.write_text(f"{ENV}:\n{entry}")
    return main(["train", "--config", str(path), "--out", str(tmp_path / "run"), "--no-eval",
                 "--no-video", "--no-progress", *extra])


def test_a_learning_rate_written_3e_4_trains_at_3e_4(tmp_path, monkeypatch):
    """PyYAML reads ``3e-4`` (no dot) as the string '3e-4'; it was refused ("a number or
    'lin_<number>' expected") while ``gamma: 9e-1`` or ``n_timesteps: 1e6`` were read as
    numbers."""
    monkeypatch.chdir(tmp_path)
    assert _train(tmp_path, TINY + "  learning_rate: 3e-4\n  gamma: 9e-1\n") == 0
    from stable_baselines3 import PPO

    model = PPO.load(tmp_path / "run" / "model.zip", device="cpu")
    assert model.learning_rate == 3e-4 and model.lr_schedule(1.0) == 3e-4
    assert model.gamma == 0.9

def test_rl_zoo3s_string_forms_are_read_without_being_evaluated(tmp_path, monkeypatch):
    """rl-zoo3's files write ``policy_kwargs`` and ``normalize`` as Python strings, which
    rl-zoo3 evaluates; spinstrike refused them ("strings are not evaluated"), so a file taken
    from rl-zoo3 did not train. They are read (not evaluated) and reach the model."""
    from stable_baselines3 import PPO
    from torch import nn

    monkeypatch.chdir(tmp_path)
    entry = (TINY + '  policy_kwargs: "dict(log_std_init=-1.5, ortho_init=False, '
             'activation_fn=nn.ReLU, net_arch=dict(pi=[32], vf=[48]))"\n'
             '  normalize: "dict(norm_obs=True, norm_reward=False)"\n')
    assert _train(tmp_path, entry) == 0
    model = PPO.load(tmp_path / "run" / "model.zip", device="cpu")
    assert model.policy.activation_fn is nn.ReLU and model.policy.ortho_init is False
    assert model.policy.net_arch == {"pi": [32], "vf": [48]}
    assert float(model.policy.log_std.detach()[0]) == pytest.approx(-1.5, abs=0.05)  # 1 update
    assert (tmp_path / "run" / "vecnormalize.pkl").is_file()


def test_normalize_settings_reach_the_learning_curve_evaluation(tmp_path, monkeypatch):
    """``normalize: {norm_obs: false, clip_obs: 0.5}`` reached the training env only: the
    learning curve's evaluation env (evaluations.npz, learning_curve.png) was a default
    VecNormalize (observations normalised, clipped at 10), another observation pipeline."""
    from stable_baselines3.common.vec_env import VecNormalize

    built = []
    init = VecNormalize.__init__

    @functools.wraps(init)  # its signature: the config reads VecNormalize's arguments from it
    def spy(self, *args, **kwargs):
        init(self, *args, **kwargs)
        built.append(self)

    monkeypatch.setattr(VecNormalize, "__init__", spy)
    monkeypatch.chdir(tmp_path)
    assert _train(tmp_path, TINY + "  normalize: {norm_obs: false, clip_obs: 0.5}\n") == 0
    evaluation = [env for env in built if not env.training]
    assert evaluation and any(env.training for env in built), built
    for env in built:
        assert (env.norm_obs, env.clip_obs) == (False, 0.5)
    for env in evaluation:  # rewards as they are, as SB3 and rl-zoo3 evaluate
        assert not env.norm_reward


def test_every_shipped_ppo_entry_fills_its_mini_batches():
    """A shipped PPO entry's rollout (n_steps x n_envs) splits into whole mini-batches, so a
    user training it as shipped gets no truncated mini-batch (SB3's warning). The suite ignores
    that warning (pyproject.toml): its tests shrink n_envs to 2 for speed, where it is true."""
    import yaml

    from spinstrike.agents.config import packaged_config_path

    entries = yaml.safe_load(packaged_config_path("ppo").read_text())
    assert len(entries) >= 4, entries
    for env_id, entry in entries.items():
        # an entry is whole (not merged with 'default'); SB3's defaults where a key is left out
        rollout = entry.get("n_steps", 2048) * entry.get("n_envs", 1)
        batch = entry.get("batch_size", 64)
        assert rollout % batch == 0, (env_id, rollout, batch)


@pytest.mark.parametrize("kind", ["normal", "ornstein-uhlenbeck"])
def test_rl_zoo3s_action_noise_types_reach_the_model(tmp_path, monkeypatch, kind):
    """rl-zoo3's ``noise_type: ornstein-uhlenbeck`` was refused (allowed: ['normal'])."""
    from stable_baselines3 import TD3
    from stable_baselines3.common.noise import (
        NormalActionNoise,
        OrnsteinUhlenbeckActionNoise,
    )

    monkeypatch.chdir(tmp_path)
    entry = ("  n_timesteps: 64\n  n_envs: 1\n  learning_starts: 32\n  batch_size: 16\n"
             f"  noise_type: {kind}\n  noise_std: 0.3\n")
    assert _train(tmp_path, entry, "--algo", "td3") == 0
    noise = TD3.load(tmp_path / "run" / "model.zip", device="cpu").action_noise
    want = {"normal": NormalActionNoise, "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}
    assert type(noise) is want[kind] and noise._sigma.tolist() == [0.3] * 3


def test_a_budget_within_learning_starts_is_warned_of(tmp_path, monkeypatch, capsys):
    """SAC on a budget below its ``learning_starts`` (the control envs' 10000) made no update
    and reported the untrained policy as its agent, with nothing said."""
    monkeypatch.chdir(tmp_path)
    assert _train(tmp_path, "  n_timesteps: 64\n  n_envs: 1\n  learning_starts: 100\n",
                  "--algo", "sac") == 0
    assert "warning: learning_starts is 100 and the budget 64 steps: SAC makes no update" in \
        capsys.readouterr().err
