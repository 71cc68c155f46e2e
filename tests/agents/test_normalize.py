"""A run with rl-zoo3's ``normalize: true`` (VecNormalize), from the user's side: ``spinstrike
train`` saves the statistics, ``spinstrike evaluate`` and the learning-curve evaluation use them
(frozen, rewards unnormalised), and ``--resume`` continues them instead of starting afresh."""

import json
import pickle

import numpy as np
import yaml

from spinstrike.agents.cli import main

ENV = "SpinStrike/PuckSpeedControl-v0"


def _stats(run):
    with open(run / "vecnormalize.pkl", "rb") as f:
        return pickle.load(f)


def test_normalize_arguments_reach_vecnormalize(tmp_path):
    """rl-zoo3's mapping form of ``normalize`` reaches SB3's VecNormalize as written (the string
    form, which rl-zoo3 evaluates, is refused: tests/agents/test_cli_bad_input.py)."""
    cfg = tmp_path / "ppo.yml"
    cfg.write_text(yaml.safe_dump({ENV: {
        "n_timesteps": 256, "policy": "MlpPolicy", "n_envs": 2, "n_steps": 128,
        "batch_size": 64, "n_epochs": 1, "policy_kwargs": {"net_arch": [8]},
        "normalize": {"norm_obs": True, "norm_reward": False, "clip_obs": 5.0}}}))
    run = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--env", ENV, "--config", str(cfg), "--out",
                 str(run), "--no-video", "--no-progress", "--no-eval"]) == 0
    stats = _stats(run)
    assert stats.norm_obs and not stats.norm_reward and stats.clip_obs == 5.0


def test_normalized_run_trains_evaluates_and_resumes(tmp_path, capsys):
    cfg = tmp_path / "ppo.yml"
    cfg.write_text(yaml.safe_dump({ENV: {
        "n_timesteps": 1024, "policy": "MlpPolicy", "normalize": True, "n_envs": 4,
        "n_steps": 128, "batch_size": 256, "n_epochs": 2,
        "policy_kwargs": {"net_arch": [16, 16]}}}))
    run = tmp_path / "run"
    common = ["--algo", "ppo", "--env", ENV, "--config", str(cfg), "--out", str(run),
              "--no-video", "--no-progress", "--eval-episodes", "2"]
    assert main(["train", *common]) == 0
    first = _stats(run)
    # the statistics of the 1024 training steps (+ the 4 first observations), not the defaults
    assert first.obs_rms.count > 1000
    assert not np.allclose(first.obs_rms.var, 1.0)
    assert list((run / "checkpoints").glob("model_vecnormalize_*_steps.pkl"))

    # evaluate: the saved policy sees the observations normalised by the saved statistics
    from stable_baselines3 import PPO

    from spinstrike.agents.evaluate import load_model_policy, run_episodes

    policy, _ = load_model_policy(run)
    model = PPO.load(run / "model.zip", device="cpu")
    import gymnasium as gym

    env = gym.make(ENV)
    obs = np.stack([env.reset(seed=s)[0] for s in range(8)])
    acts = np.stack([policy(env, o) for o in obs])
    # (one observation at a time vs a batch: float32 rounding apart)
    normalized = model.predict(first.normalize_obs(obs), deterministic=True)[0]
    np.testing.assert_allclose(acts, normalized, rtol=1e-5, atol=1e-7)
    raw = model.predict(obs, deterministic=True)[0]
    assert not np.allclose(acts, raw, rtol=1e-3, atol=1e-5)  # the normalisation matters
    manual = run_episodes(lambda env, obs: model.predict(first.normalize_obs(obs),
                                                         deterministic=True)[0], ENV, 2)
    capsys.readouterr()
    assert main(["evaluate", str(run), "--episodes", "2", "--json"]) == 0
    out = capsys.readouterr().out
    agent = json.loads(out.strip().splitlines()[-1])["agent"]
    assert agent["mean"] == manual.mean and agent["std"] == manual.std

    # resume: the statistics carry on from the checkpoint's (they used to restart from zero)
    assert main(["train", *common, "--resume", "--timesteps", "2048"]) == 0
    resumed = _stats(run)
    assert resumed.obs_rms.count > first.obs_rms.count + 1000
