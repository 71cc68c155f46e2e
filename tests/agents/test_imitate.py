"""DAgger (``agents/imitate.py``): PPO's policy started from a teacher's behaviour.

The teacher here is the scripted chase-and-hit (cheap and deterministic); one test runs the
planner for a single short round so that its path is crossed too. The seam tested from the
user's side: ``spinstrike train --imitate`` writes the rounds, starts PPO from the fitted
policy, and the saved model acts as the teacher.
"""

import csv
import os
import signal
import subprocess
import sys
import time

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml
from stable_baselines3 import PPO

from spinstrike.agents.cli import main
from spinstrike.agents.evaluate import run_episodes
from spinstrike.agents.imitate import _discounted, dagger
from spinstrike.agents.oracle import ChaseAndHit
from spinstrike.envs.sb3 import make_sb3_vec_env

ENV = "SpinStrike/PuckSpeedControl-v0"


def _model(seed=0):
    env = make_sb3_vec_env(ENV, n_envs=2, seed=seed)
    return PPO("MlpPolicy", env, seed=seed, n_steps=64, batch_size=64,
               policy_kwargs={"net_arch": [64, 64]}, device="cpu")


def _policy(model):
    def act(env, obs):
        return model.predict(obs, deterministic=True)[0]
    return act


@pytest.fixture(scope="module")
def imitated():
    model = _model()
    result = dagger(model, ENV, "chase-and-hit", rounds=3, episodes=12, seed=0, workers=2,
                    epochs=30, progress=False)
    return model, result


def test_dagger_student_acts_like_the_teacher(imitated):
    """On evaluation episodes it never saw, the fitted policy's deterministic actions are the
    teacher's to a small error, and its return is the teacher's; an unfitted policy is far
    from both (so the test can fail)."""
    model, result = imitated
    assert [r["acted"] for r in result.rounds] == ["chase-and-hit", "student", "student"]
    assert [r["states"] for r in result.rounds] == [3000, 6000, 9000]
    teacher = ChaseAndHit()
    env = gym.make(ENV)
    errors, fresh_errors = [], []
    fresh = _model(seed=1)
    obs, _ = env.reset(seed=1000)
    for _ in range(150):
        want = teacher(env, obs)
        got = model.predict(obs, deterministic=True)[0]
        errors.append(((got - want) ** 2).mean())
        fresh_errors.append(((fresh.predict(obs, deterministic=True)[0] - want) ** 2).mean())
        obs, *_ = env.step(got)
    env.close()
    assert np.mean(errors) < 0.05 < np.mean(fresh_errors)
    ref = run_episodes(ChaseAndHit(), ENV, 5, 1000)
    student = run_episodes(_policy(model), ENV, 5, 1000)
    untrained = run_episodes(_policy(fresh), ENV, 5, 1000)
    assert student.mean > 0.7 * ref.mean
    assert untrained.mean < 0.5 * ref.mean


def test_dagger_sets_the_gaussian_width_and_the_critic(imitated):
    """log_std is the log of the RMS residual (a narrow Gaussian around a good fit, not SB3's
    std of 1), and the critic is fitted to the student's discounted returns."""
    model, result = imitated
    log_std = model.policy.log_std.detach().numpy()
    assert np.allclose(log_std, result.log_std)
    assert np.all(log_std < np.log(0.3))
    assert result.critic_mse < 0.7 * result.critic_var  # measured: 0.23 against 0.44


def test_discounted_returns_restart_at_episode_ends():
    rows = np.array([(1.0, 0, 0), (1.0, 0, 1), (2.0, 0, 0), (0.0, 1, 1)])
    np.testing.assert_allclose(_discounted(rows, 0.5), [1.5, 1.0, 2.0, 0.0])


def test_dagger_is_deterministic_for_a_seed_whatever_the_workers():
    weights = []
    for workers in (0, 0, 2):
        model = _model()
        dagger(model, ENV, "chase-and-hit", rounds=2, episodes=3, seed=3, workers=workers,
               epochs=2, env_kwargs={"max_episode_steps": 60}, progress=False)
        weights.append(torch.cat([p.detach().flatten() for p in model.policy.parameters()]))
    assert torch.equal(weights[0], weights[1])
    assert torch.equal(weights[0], weights[2])
    model = _model()
    dagger(model, ENV, "chase-and-hit", rounds=2, episodes=3, seed=4, workers=0, epochs=2,
           env_kwargs={"max_episode_steps": 60}, progress=False)
    assert not torch.equal(weights[0], torch.cat([p.detach().flatten()
                                                  for p in model.policy.parameters()]))


def test_dagger_from_the_planner_one_short_round():
    """The planner as teacher labels (and in round 0 acts) on an episode cut to 30 steps."""
    model = _model()
    before = model.policy.log_std.detach().clone()
    result = dagger(model, ENV, "planner", rounds=1, episodes=1, seed=0, workers=0, epochs=5,
                    env_kwargs={"max_episode_steps": 30}, progress=False)
    assert result.rounds[0]["acted"] == "planner" and result.rounds[0]["states"] == 30
    assert result.rounds[0]["return_mean"] > 0  # the planner hits within 0.6 s
    assert not torch.equal(before, model.policy.log_std.detach())


def test_cli_train_imitate_writes_the_rounds_and_starts_ppo_from_the_student(tmp_path,
                                                                             monkeypatch):
    """``spinstrike train --imitate chase-and-hit``: imitation.csv has every round, config.yml
    records the imitation, and the model PPO saved (after a short fine-tune at the student's
    narrow width) still plays like the teacher."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--env", ENV, "--imitate", "chase-and-hit",
                 "--imitate-rounds", "3", "--imitate-episodes", "4", "--timesteps", "2048",
                 "--no-video", "--no-progress", "--eval-episodes", "5", "--out",
                 str(out)]) == 0
    rows = list(csv.DictReader(open(out / "imitation.csv")))
    assert (out / "imitation.png").read_bytes()[:4] == b"\x89PNG"
    assert [r["acted"] for r in rows] == ["chase-and-hit", "student", "student"]
    meta = yaml.safe_load((out / "config.yml").read_text())
    assert meta["imitation"]["teacher"] == "chase-and-hit"
    assert meta["imitation"]["rounds"] == 3 and meta["imitation"]["states"] == 3000
    summary = (out / "summary.md").read_text()
    agent = float(summary.split("| agent |")[1].split("|")[0])
    oracle = float(summary.split("| oracle (chase-and-hit) |")[1].split("|")[0])
    assert agent > 0.7 * oracle, summary


def _children(pid: int) -> set[int]:
    try:
        text = open(f"/proc/{pid}/task/{pid}/children").read()
    except OSError:
        return set()
    return {int(p) for p in text.split()}


def _alive(pid: int) -> bool:
    try:  # a zombie (exited, not yet reaped by its parent) counts as gone
        return open(f"/proc/{pid}/stat").read().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.exists(f"/proc/{os.getpid()}/task/{os.getpid()}/children"),
                    reason="needs Linux's /proc/PID/task/PID/children")
def test_sigterm_on_an_imitate_run_stops_its_workers(tmp_path):
    """``kill PID`` (SIGTERM) on ``spinstrike train --imitate`` in the middle of a round ends
    it with exit code 143 and takes the spawned DAgger workers with it (by default SIGTERM ends
    the process at once and leaves its workers to finish their round: seconds to minutes)."""
    out = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", ENV, "--imitate", "chase-and-hit",
            "--imitate-rounds", "50", "--imitate-episodes", "64", "--timesteps", "2048",
            "--no-video", "--no-progress", "--out", str(out)]
    proc = subprocess.Popen([sys.executable, "-m", "spinstrike.agents.cli", *args],
                            cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.time() + 240
        # training writes into run.partial; imitation.csv appears when round 0 is done
        while not (tmp_path / "run.partial" / "imitation.csv").exists():
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.time() < deadline, "round 0 did not finish in 240 s"
            time.sleep(0.2)
        time.sleep(1.0)
        workers = _children(proc.pid)
        assert len(workers) >= 2  # the pool (and multiprocessing's resource tracker)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=60) == 128 + signal.SIGTERM
        # as after Ctrl-C: the rounds' log is kept, and the message says there is no resuming
        assert (tmp_path / "run.partial" / "imitation.csv").exists()
        assert "nothing to resume" in proc.stderr.read().decode()
        deadline = time.time() + 3  # a student's round of 64 episodes takes far longer
        while any(_alive(p) for p in workers) and time.time() < deadline:
            time.sleep(0.1)
        assert not [p for p in workers if _alive(p)]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_ctrl_c_during_dagger_says_there_is_nothing_to_resume(tmp_path, monkeypatch, capsys):
    """Ctrl-C in the DAgger rounds (before PPO's first checkpoint): the message does not send the
    user to --resume (which would refuse: no checkpoint) and the same command, run again,
    starts over without --force."""
    import spinstrike.agents.imitate as imitate

    real = imitate.dagger

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(imitate, "dagger", interrupted)
    args = ["train", "--algo", "ppo", "--env", ENV, "--imitate", "chase-and-hit",
            "--imitate-rounds", "1", "--imitate-episodes", "1", "--timesteps", "1024",
            "--no-video", "--no-eval", "--no-progress", "--out", str(tmp_path / "run")]
    assert main(args) == 130  # 128 + SIGINT, after the message (no traceback)
    err = capsys.readouterr().err
    assert "nothing to resume" in err and "--resume" not in err
    assert main(args[:-2] + ["--resume", "--out", str(tmp_path / "run")]) == 2
    assert capsys.readouterr().err.startswith("error: resume: ")  # a clear refusal
    monkeypatch.setattr(imitate, "dagger", real)
    assert main(args) == 0
    assert (tmp_path / "run" / "model.zip").exists()
