"""An interrupted ``spinstrike train``, from the user's side: ``--resume`` continues the run that
``config.yml`` records and keeps one learning history; running the command again without
``--resume`` does not delete it; Ctrl-C ends like SIGTERM, with the resume hint and no traceback.

The interrupt is Ctrl-C's ``KeyboardInterrupt``, raised by a callback once training has passed a
given step (after a checkpoint), so every test stops at the same place."""

import contextlib
import csv
import sys

import numpy as np
import pytest
import yaml

import spinstrike.envs.sb3 as sb3
from spinstrike.agents.cli import main
from tests.agents.signals import ctrl_c_after, signal_after_checkpoint, with_callback

ENV = "SpinStrike/RodSpin-v0"


def _tiny_config(path, n_timesteps=2048):
    path.write_text(yaml.safe_dump({env: {
        "n_timesteps": n_timesteps, "policy": "MlpPolicy", "n_envs": 4, "n_steps": 64,
        "batch_size": 128, "n_epochs": 1, "policy_kwargs": {"net_arch": [16]}}
        for env in (ENV, "SpinStrike/PuckSpeed-v1")}))
    return path


def _interrupted_run(tmp_path, monkeypatch, args):
    # (the KeyboardInterrupt used to escape main())
    with ctrl_c_after(monkeypatch, 1100), contextlib.suppress(KeyboardInterrupt):
        assert main(args) == 130
    partial = tmp_path / "run.partial"
    assert list((partial / "checkpoints").glob("model_*_steps.zip"))
    return partial


def _progress_steps(path):
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    return [int(float(r["time/total_timesteps"])) for r in rows if r["time/total_timesteps"]]


def _tree(root):
    return {p.relative_to(root): p.stat().st_mtime_ns for p in root.rglob("*")}


def test_resume_keeps_the_learning_history(tmp_path, monkeypatch):
    """After ``--resume``, evaluations.npz (what learning_curve.png and ``spinstrike baselines``
    read) and progress.csv hold the whole run: the points before the interrupt, then the new
    ones, steps increasing (they used to start again at the checkpoint)."""
    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", ENV, "--config", str(_tiny_config(
        tmp_path / "ppo.yml")), "--out", str(run), "--no-eval", "--no-video", "--no-progress"]
    partial = _interrupted_run(tmp_path, monkeypatch, args)
    before = np.load(partial / "evaluations.npz")["timesteps"].tolist()
    rows_before = _progress_steps(partial / "progress.csv")
    ckpt = max(int(p.name.split("_")[1]) for p in (partial / "checkpoints").glob("model_*.zip"))
    assert before and max(before) <= ckpt

    assert main([*args, "--resume"]) == 0
    data = np.load(run / "evaluations.npz")
    steps = data["timesteps"].tolist()
    assert steps[:len(before)] == before, steps  # the first part is kept
    # on the grid of the run left alone (test_checkpoints.py): a mark every 204 steps
    assert steps == list(range(256, 2049, 256)), steps  # after each rollout (4 x 64 steps)
    assert data["results"].shape == (len(steps), 10)
    rows = _progress_steps(run / "progress.csv")
    kept = [s for s in rows_before if s <= ckpt]
    assert rows[:len(kept)] == kept and rows[0] < 1024 and rows[-1] >= 2048, rows
    assert np.all(np.diff(rows) >= 0), rows
    assert (run / "learning_curve.png").is_file()


def test_resume_continues_the_recorded_run(tmp_path, monkeypatch, capsys):
    """``--resume --out RUN`` (what the interrupt message says) trains the run as config.yml
    records it: its env, env kwargs, hyperparameters and budget, not the command line's
    defaults (it used to train RodSpin-v0 on the packaged config, or end in a traceback); an
    option that contradicts the record is refused on one line; --timesteps sets a new budget,
    recorded."""
    run = tmp_path / "run"
    env = "SpinStrike/PuckSpeed-v1"
    args = ["train", "--algo", "ppo", "--env", env, "--env-kwargs", "{restitution: 0.5}",
            "--config", str(_tiny_config(tmp_path / "ppo.yml")), "--seed", "3",
            "--out", str(run), "--no-eval", "--no-video", "--no-progress"]
    _interrupted_run(tmp_path, monkeypatch, args)
    recorded = yaml.safe_load((tmp_path / "run.partial" / "config.yml").read_text())
    capsys.readouterr()

    for extra, needle in ((["--algo", "sac"], "--algo sac (recorded: ppo)"),
                          (["--env", ENV], f"--env {ENV} (recorded: {env})"),
                          (["--env-kwargs", "{restitution: 0.9}"], "--env-kwargs"),
                          (["--seed", "0"], "--seed 0 (recorded: 3)"),
                          (["--n-envs", "2"], "--n-envs 2 (recorded: 4)"),
                          # (it used to be ignored: the run went on without DAgger)
                          (["--imitate", "chase-and-hit"],
                           "--imitate chase-and-hit (recorded: none)")):
        assert main(["train", "--resume", "--out", str(run), *extra]) == 2, extra
        err = capsys.readouterr().err
        assert err.startswith("error: resume: ") and needle in err, (extra, err)
        assert err.count("\n") == 1

    made = []
    real = sb3.make_sb3_vec_env

    def spy(env_id, **kwargs):
        made.append((env_id, kwargs["n_envs"], kwargs["env_kwargs"]))
        return real(env_id, **kwargs)

    monkeypatch.setattr(sb3, "make_sb3_vec_env", spy)
    assert main(["train", "--resume", "--out", str(run), "--no-eval", "--no-video",
                 "--no-progress"]) == 0
    assert {(e, kw["restitution"]) for e, _, kw in made} == {(env, 0.5)}, made
    assert (env, 4, {"restitution": 0.5}) in made  # the training envs
    meta = yaml.safe_load((run / "config.yml").read_text())
    assert meta["hyperparameters"] == recorded["hyperparameters"]
    # the recorded budget (to PPO's rollouts of 4 x 64), not the packaged 150k
    assert 2048 <= meta["runs"][-1]["timesteps"] < 2048 + 256

    # the same command with --resume (as the README says) is the recorded run too, and a
    # larger --timesteps extends the budget, recorded in config.yml
    assert main([*args, "--resume", "--timesteps", "2560"]) == 0
    meta = yaml.safe_load((run / "config.yml").read_text())
    assert meta["hyperparameters"][env]["n_timesteps"] == 2560
    assert 2560 <= meta["runs"][-1]["timesteps"] < 2560 + 256
    assert np.load(run / "evaluations.npz")["timesteps"].max() >= 2448


def test_same_command_without_resume_keeps_the_interrupted_run(tmp_path, monkeypatch, capsys):
    """Running the command again without --resume refuses, on one line naming --resume and
    --force, and leaves the checkpoints (it used to delete them silently); --force starts
    over."""
    args = ["train", "--algo", "ppo", "--env", ENV, "--config", str(_tiny_config(
        tmp_path / "ppo.yml", 1024)), "--out", str(tmp_path / "run"), "--no-eval",
        "--no-video", "--no-progress"]
    with ctrl_c_after(monkeypatch, 600), contextlib.suppress(KeyboardInterrupt):
        main(args)
    checkpoints = sorted((tmp_path / "run.partial" / "checkpoints").iterdir())
    assert checkpoints
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: out: ") and "--resume" in err and "--force" in err, err
    assert err.count("\n") == 1
    assert sorted((tmp_path / "run.partial" / "checkpoints").iterdir()) == checkpoints
    assert not (tmp_path / "run").exists()
    assert main([*args, "--force"]) == 0
    assert (tmp_path / "run" / "model.zip").is_file()
    assert not (tmp_path / "run.partial").exists()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_ctrl_c_ends_with_the_resume_hint_and_no_traceback(tmp_path):
    """Ctrl-C (SIGINT) on ``spinstrike train`` with its progress bar, after a checkpoint: exit
    code 130 and the resume hint alone, as SIGTERM (it used to print a long traceback and a
    progress-bar error at exit)."""
    import signal

    args = ["train", "--algo", "ppo", "--env", ENV, "--config", str(_tiny_config(
        tmp_path / "ppo.yml", 100_000)), "--no-video", "--no-eval", "--out",
        str(tmp_path / "run")]
    err = signal_after_checkpoint(args, tmp_path, signal.SIGINT, tmp_path / "run")
    assert f"interrupted: continue with --resume --out {tmp_path / 'run'}" in err
    assert "Traceback" not in err and "Exception ignored" not in err, err


@pytest.mark.parametrize("signals", [1, 2])
def test_a_signal_ends_training_at_the_next_step_and_is_raised_after_it(tmp_path, monkeypatch,
                                                                         capsys, signals):
    """Ctrl-C raised inside ``model.learn`` could land in TensorBoard's writer queue, and
    closing the logger then waited for its thread for ever (twice in CI, the child's stacks
    showed it). The first SIGINT is noted and ends training at its env step; SB3's
    ``learn`` returns (``on_training_end``), the logger closes, and then it is raised: exit 130
    with the resume hint. A second one is raised at once, inside ``learn``, as before."""
    import os
    import signal

    from stable_baselines3.common.callbacks import BaseCallback


    seen = {"steps": [], "ended": False}

    class _Signal(BaseCallback):
        def _on_step(self) -> bool:
            seen["steps"].append(self.num_timesteps)
            if self.num_timesteps == 1280:
                for _ in range(signals):
                    os.kill(os.getpid(), signal.SIGINT)
            return True

        def _on_training_end(self) -> None:
            seen["ended"] = True

    run = tmp_path / "run"
    # as in a terminal's foreground job (pytest run in the background has SIGINT ignored, and
    # an ignored signal stays ignored: the next test)
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with contextlib.suppress(KeyboardInterrupt), with_callback(monkeypatch, _Signal()):
            assert main(["train", "--algo", "ppo", "--env", ENV, "--config",
                         str(_tiny_config(tmp_path / "ppo.yml", 4096)), "--no-video",
                         "--no-eval", "--no-progress", "--out", str(run)]) == 130
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, outer)
    assert f"interrupted: continue with --resume --out {run}" in capsys.readouterr().err
    assert seen["ended"] is (signals == 1)  # learn returned, or the second raised within
    assert seen["steps"][-1] == 1280  # no step after it (the stop is read in the same step)
    [stretch] = yaml.safe_load((tmp_path / "run.partial" / "config.yml").read_text())["runs"]
    assert stretch["interrupted"] is True


def test_a_run_that_ignores_sigint_goes_on_through_one(tmp_path, monkeypatch):
    """A run started with SIGINT ignored (in the background, by ``nohup ... &`` or a scheduler)
    is not stopped by a SIGINT during training: the noting handler was installed over
    ``SIG_IGN`` and turned it into a stop (ci38: pytest in the background). It trains its
    budget and SIGINT is still ignored after it."""
    import os
    import signal

    from stable_baselines3.common.callbacks import BaseCallback


    class _Signal(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps == 1280:
                os.kill(os.getpid(), signal.SIGINT)
            return True

    outer = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with with_callback(monkeypatch, _Signal()):
            assert main(["train", "--algo", "ppo", "--env", ENV, "--config",
                         str(_tiny_config(tmp_path / "ppo.yml", 4096)), "--no-video",
                         "--no-eval", "--no-progress", "--out", str(tmp_path / "run")]) == 0
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, outer)
    [stretch] = yaml.safe_load((tmp_path / "run" / "config.yml").read_text())["runs"]
    assert stretch["timesteps"] == 4096 and not stretch.get("interrupted")


def test_a_resumed_run_finishes_as_its_first_command_asked_and_counts_all_its_time(
        tmp_path, monkeypatch, capsys):
    """``--resume`` dropped the first command's ``--no-video`` and ``--eval-episodes`` (it filmed
    and evaluated 50 episodes), its summary showed the last stretch's time only, and a budget
    below the steps already trained was taken (and nothing trained)."""
    import json

    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "1024",
            "--n-envs", "2", "--no-progress", "--no-video", "--eval-episodes", "3", "--out",
            str(run)]
    with ctrl_c_after(monkeypatch, 600), contextlib.suppress(KeyboardInterrupt):
        assert main(args) == 130
    meta = yaml.safe_load((tmp_path / "run.partial" / "config.yml").read_text())
    assert meta["finish"] == {"evaluate": True, "eval_episodes": 3, "video": False}
    [stopped] = meta["runs"]
    assert stopped["interrupted"] is True and stopped["wall_time_s"] > 0
    capsys.readouterr()
    assert main(["train", "--resume", "--out", str(run), "--timesteps", "256"]) == 2
    assert "has trained 512 steps; a new budget must exceed them" in capsys.readouterr().err
    assert main(["train", "--resume", "--out", str(run), "--no-progress"]) == 0
    assert not list(run.glob("*.mp4"))
    assert [r["episodes"] for r in json.loads((run / "summary.json").read_text())] == [3] * 3
    runs = yaml.safe_load((run / "config.yml").read_text())["runs"]
    total = sum(r["wall_time_s"] for r in runs)
    assert len(runs) == 2 and f"{total:.0f} s in 2 sessions" in (run / "summary.md").read_text()
    # a finish of its own was taken as a one-off: the files of the recorded finish (a video of
    # the model before, a summary of other episodes) stayed beside the new model. Refused, as
    # the README says; a flag that repeats the record is fine
    capsys.readouterr()
    before = _tree(run)
    assert main(["train", "--resume", "--out", str(run), "--timesteps", "2048", "--no-eval",
                 "--eval-episodes", "5", "--no-video"]) == 2
    err = capsys.readouterr().err
    assert "--no-eval (recorded: evaluate True)" in err
    assert "--eval-episodes (recorded: eval_episodes 3)" in err and "--no-video" not in err
    assert _tree(run) == before


def test_a_resumed_run_draws_the_tasks_that_come_next(tmp_path, monkeypatch):
    """The training env of ``--resume`` was rebuilt from the run's seed, so the resumed stretch
    replayed the run's first tasks (every observation of it equal to the first stretch's; SAC's
    buffer held each early transition twice). A checkpoint keeps the env's random streams: the
    resumed stretch sees the tasks the run left alone goes on to (each element's from the
    episode after the one in flight at the checkpoint), none of the first stretch's."""
    seen = []
    real = sb3.SB3VecEnv.step_wait

    def step_wait(self):
        out = real(self)
        if self.num_envs == 4:  # the training envs (the evaluation env has 1)
            seen.append(out[0].copy())
        return out

    monkeypatch.setattr(sb3.SB3VecEnv, "step_wait", step_wait)
    def tasks(upto=None):  # RodSpin's episodes are one step: an observation is a task
        return {tuple(row) for obs in seen[:upto] for row in obs}

    config = str(_tiny_config(tmp_path / "ppo.yml"))
    common = ["--algo", "ppo", "--env", ENV, "--config", config, "--no-eval", "--no-video",
              "--no-progress"]
    assert main(["train", *common, "--out", str(tmp_path / "alone")]) == 0
    alone = tasks()
    seen.clear()
    partial = _interrupted_run(tmp_path, monkeypatch,
                               ["train", *common, "--out", str(tmp_path / "run")])
    ckpt = max(int(p.name.split("_")[1]) for p in (partial / "checkpoints").glob("model_*.zip"))
    first = tasks(ckpt // 4)  # to the checkpoint (the steps after it are trained again)
    assert len(first) > 500
    seen.clear()
    assert main(["train", "--resume", "--out", str(tmp_path / "run"), "--no-eval", "--no-video",
                 "--no-progress"]) == 0
    resumed = tasks()
    assert len(resumed) > 500 and not resumed & first
    assert len(resumed - alone) <= 4, len(resumed - alone)  # the last episode of each element


def test_a_runs_record_trains_it_again(tmp_path, capsys):
    """A run's command.txt kept only its first command (a resume with a new --timesteps left it
    naming the old budget), and its config.yml was refused as --config ("unknown env id
    'algo'"): neither re-ran the run. Now command.txt lists each command, and the record is a
    hyperparameter file for its own algorithm."""
    run = tmp_path / "run"
    first = ["train", "--algo", "ppo", "--env", ENV, "--config",
             str(_tiny_config(tmp_path / "ppo.yml", 1024)), "--env-kwargs",
             "{restitution: 0.5}", "--out", str(run), "--no-eval", "--no-video", "--no-progress"]
    assert main(first) == 0
    again = ["train", "--resume", "--out", str(run), "--timesteps", "1536", "--no-eval",
             "--no-video", "--no-progress"]
    assert main(again) == 0
    import shlex

    lines = (run / "command.txt").read_text().splitlines()
    assert lines == ["spinstrike " + shlex.join(first), "spinstrike " + shlex.join(again)]
    record = yaml.safe_load((run / "config.yml").read_text())
    assert record["hyperparameters"][ENV]["n_timesteps"] == 1536

    copy = tmp_path / "copy"
    assert main(["train", "--algo", "ppo", "--env", ENV, "--config", str(run / "config.yml"),
                 "--out", str(copy), "--no-eval", "--no-video", "--no-progress"]) == 0
    redone = yaml.safe_load((copy / "config.yml").read_text())
    assert redone["hyperparameters"] == record["hyperparameters"]  # budget and env kwargs too
    assert redone["hyperparameters"][ENV]["env_kwargs"] == {"restitution": 0.5}
    capsys.readouterr()
    assert main(["train", "--algo", "sac", "--env", ENV, "--config", str(run / "config.yml"),
                 "--out", str(tmp_path / "x")]) == 2
    assert "is the record of a ppo run" in capsys.readouterr().err


def test_a_runs_record_given_as_config_brings_its_algo_and_env(tmp_path):
    """``spinstrike train --config RUN/config.yml`` with neither --algo nor --env took the
    defaults (ppo, RodSpin-v0) and refused a SAC run of PuckSpeed-v1's record for having no
    entry for RodSpin-v0 (found by a new user); now the record's algo and env."""
    env_id = "SpinStrike/PuckSpeed-v1"
    from spinstrike.agents.config import load_agent_config

    entry = load_agent_config("sac", env_id).raw | {"n_timesteps": 64, "learning_starts": 32}
    record = tmp_path / "config.yml"
    record.write_text(yaml.safe_dump({"algo": "sac", "env": env_id, "seed": 0,
                                      "hyperparameters": {env_id: entry}}))
    assert main(["train", "--config", str(record), "--out", str(tmp_path / "run"), "--no-eval",
                 "--no-video", "--no-progress"]) == 0
    made = yaml.safe_load((tmp_path / "run" / "config.yml").read_text())
    assert (made["algo"], made["env"]) == ("sac", env_id)


def test_the_same_command_with_resume_continues_the_recorded_budget(tmp_path, monkeypatch,
                                                                     capsys):
    """The README: "The same command with ``--resume`` works too". Where the run had trained
    its budget (rounded up to whole rollouts by SB3, or stopped in its final evaluation), the
    recorded budget given again was refused as a new one "must exceed" the steps trained."""
    config = _tiny_config(tmp_path / "tiny.yml")
    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", ENV, "--config", str(config), "--timesteps", "100",
            "--no-progress", "--no-video", "--eval-episodes", "2", "--out", str(run)]
    assert main(args) == 0
    steps = yaml.safe_load((run / "config.yml").read_text())["runs"][-1]["timesteps"]
    assert steps == 256  # one rollout of 4 envs x 64 steps
    capsys.readouterr()
    before = _tree(run)
    assert main([*args, "--resume"]) == 0, capsys.readouterr().err
    # a run that has trained its budget trains nothing and re-writes nothing (it re-saved its
    # checkpoint as a new session, and evaluated and filmed again)
    assert f"run: {run} has trained its budget (256 steps): nothing to do; --timesteps N " \
           "above it trains further" in capsys.readouterr().out
    assert _tree(run) == before
    record = yaml.safe_load((run / "config.yml").read_text())
    assert record["hyperparameters"][ENV]["n_timesteps"] == 100
    assert [r["timesteps"] for r in record["runs"]] == [256]
    # stopped during its final evaluation: it writes what is missing, and only that
    (run / "summary.md").unlink()
    (run / "summary.json").unlink()
    before = _tree(run)
    assert main([*args, "--resume"]) == 0
    assert "wrote its missing summary;" in capsys.readouterr().out
    assert {path for path in _tree(run) if path not in before} == {
        run.joinpath(name).relative_to(run) for name in ("summary.md", "summary.json")}
    assert all(_tree(run)[path] == mtime for path, mtime in before.items())
    assert "(seed 0, 256 steps, " in (run / "summary.md").read_text().splitlines()[0]
    # a new budget still has to exceed what was trained, and the message names the recorded one
    assert main([*args[:-2], "--timesteps", "200", "--out", str(run), "--resume"]) == 2
    err = capsys.readouterr().err
    assert "has trained 256 steps; a new budget must exceed them (got 200; the recorded " \
           "budget, 100, continues the run as recorded)" in err


def test_a_run_stopped_while_it_writes_its_evaluations_resumes(tmp_path, monkeypatch):
    """Ctrl-C or SIGTERM right after a checkpoint lands in the evaluation that follows it, and
    SB3 wrote evaluations.npz in place: a stop during the write left a broken file, and
    ``--resume`` failed reading it (the default suite's SIGTERM test failed so once, a
    TypeError in ``_earlier_evaluations``). The file is written beside it and moved over it:
    a stop inside the write leaves the previous one whole, and the run resumes."""
    import stable_baselines3.common.callbacks as callbacks

    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", ENV, "--config", str(_tiny_config(
        tmp_path / "ppo.yml")), "--out", str(run), "--no-eval", "--no-video", "--no-progress"]
    real = np.savez
    calls = []

    def savez_stopped_in_the_third(file, *arrays, **named):
        calls.append(file)
        if len(calls) < 3:
            return real(file, *arrays, **named)
        path = str(file) if str(file).endswith(".npz") else f"{file}.npz"
        with open(path, "wb") as f:  # a zip cut short: its first bytes, then the stop
            f.write(b"PK\x03\x04" + b"\x00" * 40)
        raise KeyboardInterrupt

    monkeypatch.setattr(callbacks.np, "savez", savez_stopped_in_the_third)
    with contextlib.suppress(KeyboardInterrupt):
        assert main(args) == 130
    monkeypatch.setattr(callbacks.np, "savez", real)
    partial = tmp_path / "run.partial"
    assert np.load(partial / "evaluations.npz")["timesteps"].tolist() == [256, 512]
    assert main([*args, "--resume"]) == 0
    assert np.load(run / "evaluations.npz")["timesteps"].tolist() == list(range(256, 2049, 256))
