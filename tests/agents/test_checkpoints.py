"""Checkpoints of ``spinstrike train``, from the user's side (the CLI, then ``--resume``):

* a PPO run interrupted and resumed makes the updates, and evaluates on the grid, of the same run
  left alone (checkpoints used to fall inside a rollout: the resumed run redid it, made one
  update fewer, and its evaluations fell off the grid, the first repeating the last);
* an off-policy run keeps one replay buffer, the newest (each checkpoint kept its own: 325 MB a
  SAC run on a control env), and a resume goes on from it (a missing one is refused, not
  replaced by an empty buffer);
* ``spinstrike baselines --quick`` scales the off-policy warm-up with the budget (its SAC and TD3
  on the control envs never reached ``learning_starts`` and never trained).
"""

import contextlib
import csv
import json
import pickle

import numpy as np
import yaml

from spinstrike.agents.cli import main
from spinstrike.agents.config import packaged_config_path
from tests.agents.signals import ctrl_c_after

ENV = "SpinStrike/RodSpin-v0"
ROLLOUT = 4 * 64  # the tiny PPO entry's n_envs x n_steps


def _write(path, entry):
    path.write_text(yaml.safe_dump({ENV: entry}))
    return path


def _ppo_config(path):
    return _write(path, {"n_timesteps": 2048, "policy": "MlpPolicy", "n_envs": 4, "n_steps": 64,
                         "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16]}})


def _sac_config(path):
    return _write(path, {"n_timesteps": 1200, "policy": "MlpPolicy", "n_envs": 1,
                         "learning_starts": 100, "buffer_size": 5000, "batch_size": 32,
                         "gamma": 0.0, "policy_kwargs": {"net_arch": [16]}})


def _interrupt(monkeypatch, args, steps):
    """Run ``spinstrike ARGS`` and Ctrl-C it once training passes ``steps``."""
    with ctrl_c_after(monkeypatch, steps), contextlib.suppress(KeyboardInterrupt):
        assert main(args) == 130


def _steps(folder, pattern):
    return sorted(int(p.name.split("_")[-2]) for p in folder.glob(pattern))


def _progress(run, column):
    with (run / "progress.csv").open(newline="") as f:
        return [float(r[column]) for r in csv.DictReader(f) if r.get(column)]


def test_resumed_ppo_run_updates_and_evaluates_as_the_run_left_alone(tmp_path, monkeypatch):
    config = str(_ppo_config(tmp_path / "ppo.yml"))
    common = ["train", "--algo", "ppo", "--env", ENV, "--config", config, "--no-eval",
              "--no-video", "--no-progress"]
    alone, run = tmp_path / "alone", tmp_path / "run"
    assert main([*common, "--out", str(alone)]) == 0

    _interrupt(monkeypatch, [*common, "--out", str(run)], 1100)
    saved = _steps(run.with_name("run.partial") / "checkpoints", "model_*_steps.zip")
    # between rollouts (after the update), at or after each mark of 204 steps: 256, 512, ...
    assert saved and all(s % ROLLOUT == 0 for s in saved), saved
    assert max(saved) == 1024, saved
    assert main([*common, "--out", str(run), "--resume"]) == 0

    from stable_baselines3 import PPO

    for r in (alone, run):  # one update a rollout (n_epochs 1), none lost or repeated
        model = PPO.load(r / "model.zip")
        assert (model.num_timesteps, model._n_updates) == (2048, 2048 // ROLLOUT), r
    logged = {r: _progress(r, "train/n_updates") for r in (alone, run)}
    assert len(set(logged[run])) == len(logged[run]) and set(logged[run]) <= set(logged[alone])
    grid = {r: np.load(r / "evaluations.npz")["timesteps"].tolist() for r in (alone, run)}
    # each evaluation between rollouts, the first at or after each mark of 204 steps
    assert grid[run] == grid[alone] == list(range(ROLLOUT, 2049, ROLLOUT)), grid


def test_off_policy_run_keeps_the_newest_replay_buffer_and_resumes_from_it(tmp_path,
                                                                           monkeypatch, capsys):
    run = tmp_path / "run"
    args = ["train", "--algo", "sac", "--env", ENV, "--config",
            str(_sac_config(tmp_path / "sac.yml")), "--out", str(run), "--no-eval",
            "--no-video", "--no-progress"]
    _interrupt(monkeypatch, args, 700)
    ckpts = run.with_name("run.partial") / "checkpoints"
    zips = _steps(ckpts, "model_*_steps.zip")
    assert zips == [120, 240, 360, 480, 600], zips
    buffers = list(ckpts.glob("model_replay_buffer_*_steps.pkl"))
    assert [p.name for p in buffers] == ["model_replay_buffer_600_steps.pkl"]

    # without its buffer the run is not resumed with an empty one
    aside = buffers[0].rename(tmp_path / buffers[0].name)
    capsys.readouterr()
    assert main([*args, "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: resume: ") and "no replay buffer" in err, err
    aside.rename(buffers[0])

    assert main([*args, "--resume"]) == 0
    ckpts = run / "checkpoints"
    buffers = list(ckpts.glob("model_replay_buffer_*_steps.pkl"))
    assert [p.name for p in buffers] == ["model_replay_buffer_1200_steps.pkl"], buffers
    with buffers[0].open("rb") as f:
        buffer = pickle.load(f)
    # one transition a step (1 env) since the start: the resumed run filled the saved buffer
    assert buffer.pos == 1200 and not buffer.full, buffer.pos


def test_quick_baselines_scale_the_off_policy_warm_up(tmp_path):
    root = tmp_path / "runs"
    assert main(["baselines", "--quick", "--envs", "SpinStrike/PuckSpeed-v1", "--algos", "sac",
                 "--no-transfer", "--root", str(root)]) == 0
    run = root / "sac-PuckSpeed-v1-s0"
    packaged = yaml.safe_load(packaged_config_path("sac").read_text())["SpinStrike/PuckSpeed-v1"]
    entry = yaml.safe_load((run / "config.yml").read_text())["hyperparameters"][
        "SpinStrike/PuckSpeed-v1"]
    assert entry["learning_starts"] == packaged["learning_starts"] // 10
    assert entry["n_timesteps"] == packaged["n_timesteps"] // 10
    # it trained: gradient steps from the scaled warm-up on
    assert _progress(run, "train/n_updates")[-1] > 0
    assert json.loads((run / "baseline.json").read_text())["timesteps"] >= entry["n_timesteps"]


def test_a_kill_while_a_checkpoint_is_written_leaves_the_run_resumable(tmp_path, monkeypatch,
                                                                       capsys):
    """Ctrl-C (or a scheduler's SIGTERM) that lands while a checkpoint is being written: the
    truncated file is not taken for the newest checkpoint, and ``--resume`` goes on from the one
    before (it used to fail with an EOFError from torch: seen in CI, where the SIGTERM test
    signalled as soon as the first checkpoint's name appeared)."""
    import stable_baselines3.common.base_class as base_class

    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", ENV, "--config",
            str(_ppo_config(tmp_path / "ppo.yml")), "--out", str(run), "--no-eval",
            "--no-video", "--no-progress"]
    real, calls = base_class.save_to_zip_file, []

    def killed_on_the_third(path, **kwargs):
        calls.append(path)
        if len(calls) == 3:  # half a file, then the interrupt
            with open(path, "wb") as f:
                f.write(b"PK\x03\x04 half a checkpoint")
            raise KeyboardInterrupt
        return real(path, **kwargs)

    with monkeypatch.context() as m:
        m.setattr(base_class, "save_to_zip_file", killed_on_the_third)
        with contextlib.suppress(KeyboardInterrupt):
            assert main(args) == 130
    assert len(calls) == 3
    assert _steps(run.with_name("run.partial") / "checkpoints", "model_*_steps.zip") == [
        256, 512]
    capsys.readouterr()
    assert main([*args, "--resume"]) == 0, capsys.readouterr().err
    assert np.load(run / "evaluations.npz")["timesteps"].tolist() == list(
        range(ROLLOUT, 2049, ROLLOUT))


def _curve_score(model_path, algo):
    """A model scored as the learning curve's evaluations score it (``EVAL_SEED``'s 10
    episodes, deterministic actions)."""
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.evaluation import evaluate_policy

    from spinstrike.agents.train import EVAL_SEED
    from spinstrike.envs.sb3 import make_sb3_vec_env

    model = {"ppo": PPO, "sac": SAC}[algo].load(model_path, device="cpu")
    env = make_sb3_vec_env(ENV, n_envs=1, seed=EVAL_SEED)
    env.seed(EVAL_SEED)
    returns, _ = evaluate_policy(model, env, n_eval_episodes=10, deterministic=True,
                                 return_episode_rewards=True)
    return float(np.mean(returns))


def test_each_learning_curve_point_scores_the_model_trained_on_its_steps(tmp_path):
    """W17: SB3's ``EvalCallback`` scores PPO's policy at the step that completes a mark,
    inside the rollout, before its update: every point of the learning curve
    (``evaluations.npz``, ``learning_curve.png``, TensorBoard's ``eval/mean_reward``, the
    baselines' IQM curves) was the previous rollout's policy, and the last point was not the
    saved model (0.313 where it scored 0.483). Each point now scores the checkpoint of its own
    steps, and the last one ``model.zip``."""
    run = tmp_path / "run"
    # the shipped entry (rollouts of 1024 steps), which learns within 5,000 steps
    assert main(["train", "--algo", "ppo", "--env", ENV, "--timesteps", "5000", "--out",
                 str(run), "--no-eval", "--no-video", "--no-progress"]) == 0
    data = np.load(run / "evaluations.npz")
    curve = dict(zip(data["timesteps"].tolist(), data["results"].mean(1).tolist(),
                     strict=True))
    assert list(curve) == list(range(1024, 5121, 1024)), curve  # a point a rollout
    checkpoints = {t: run / "checkpoints" / f"model_{t}_steps.zip" for t in curve}
    scores = {t: _curve_score(path, "ppo") for t, path in checkpoints.items() if path.exists()}
    assert len(scores) == 5 and all(scores[t] == curve[t] for t in scores), (scores, curve)
    assert _curve_score(run / "model.zip", "ppo") == curve[5120]
    assert len(set(curve.values())) > 2, curve  # the policy changed: the points tell it
