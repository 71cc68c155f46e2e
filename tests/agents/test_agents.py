"""Baselines plumbing on tiny budgets: every algorithm on every env trains, saves, loads and
evaluates; the CLI runs end to end; videos have frames; runs resume; bad configs fail cleanly."""

import contextlib
import gc
import json
import os
import re
import subprocess
import sys
import warnings

import gymnasium as gym
import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
import pytest
import yaml

from spinstrike import envs
from spinstrike.agents.cli import main
from spinstrike.agents.config import ALGOS, AgentConfigError, code_version, load_agent_config
from spinstrike.agents.evaluate import evaluate, load_model_policy
from spinstrike.agents.train import train
from tests.agents.signals import ctrl_c_after, signal_after_checkpoint


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("env_id", list(envs.ENV_IDS))
def test_each_algorithm_trains_saves_loads_and_evaluates(algo, env_id, tmp_path):
    over = {"learning_starts": 50} if algo != "ppo" else {"n_steps": 16, "batch_size": 32}
    cfg = load_agent_config(algo, env_id, overrides=over)
    cfg_file = tmp_path / f"{algo}.yml"
    cfg_file.write_text(yaml.safe_dump({env_id: cfg.raw}))
    result = train(algo, env_id, config=cfg_file, timesteps=128, n_envs=2,
                   out=tmp_path / "run", progress=False, evaluate=False, video=False,
                   eval_freq=64, eval_episodes_during=2)
    run = tmp_path / "run"
    assert result["timesteps"] >= 128
    for name in ("model.zip", "config.yml", "command.txt", "progress.csv", "evaluations.npz"):
        assert (run / name).is_file(), name
    assert list((run / "checkpoints").glob("model_*_steps.zip"))
    assert list((run / "tb").rglob("events.out.tfevents.*"))
    policy, meta = load_model_policy(run)
    assert meta["algo"] == algo and meta["env"] == env_id
    [agent] = evaluate(env_id, policy, episodes=2, baselines=False)
    assert agent.episodes == 2 and np.isfinite(agent.mean)


@pytest.mark.parametrize(("kwargs", "policy"), [
    ("{obs_mode: dict}", "MultiInputPolicy"),
    ("{obs_mode: pixels, obs_size: [160, 48]}", "CnnPolicy"),
])
def test_the_cli_trains_on_dict_and_pixel_observations(kwargs, policy, tmp_path, capsys):
    """The shipped entries name MlpPolicy; on dict observations SB3 refused it with a
    traceback, and on pixels it built an MLP over every pixel (a 679 MB model.zip for 128
    steps). The run takes the policy the observations need, says so and records it; its
    evaluations and its summary go through the same observations."""
    run = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "128",
                 "--n-envs", "2", "--env-kwargs", kwargs, "--out", str(run), "--no-video",
                 "--eval-episodes", "2", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert f"policy: {policy} for" in err
    assert "(128 steps, " in out and "rounded up" not in out  # 2 envs x n_steps 64: whole
    meta = yaml.safe_load((run / "config.yml").read_text())
    assert meta["hyperparameters"]["SpinStrike/RodSpin-v0"]["policy"] == policy
    # which SpinStrike trained it (W16: every build is 0.1.0, and the record did not say)
    code = code_version()
    assert meta["versions"]["spinstrike"] == code["spinstrike"] != "unknown"
    assert meta["versions"]["spinstrike_commit"] == code["spinstrike_commit"]
    assert (run / "model.zip").stat().st_size < 20e6
    load_model_policy(run)  # loads
    assert main(["evaluate", str(run), "--episodes", "2", "--no-save"]) == 0


def test_a_short_ppo_run_evaluates_no_policy_more_than_twice(tmp_path):
    """The learning curve's interval came from the budget alone: a 64-step smoke run (one
    rollout of 512 steps on a control env) evaluated the same policy 85 times (50 s)."""
    run = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/RodSpinControl-v0",
                 "--timesteps", "64", "--n-envs", "2", "--out", str(run), "--no-video",
                 "--no-eval", "--no-progress"]) == 0
    steps = np.load(run / "evaluations.npz")["timesteps"]
    assert steps.tolist() == [512]  # n_steps 256 x 2 envs: one rollout, its policy once


def test_a_run_closes_its_logs_finished_or_interrupted(tmp_path, monkeypatch):
    """``spinstrike train`` closes progress.csv and the TensorBoard events itself, when the run
    finishes and when Ctrl-C stops it. SB3 leaves its logger's files to the garbage collector:
    ``python -X dev -m spinstrike.agents.cli train ...`` ended with "ResourceWarning: unclosed
    file <... name='runs.partial/progress.csv'>", the file opened under the run's temporary
    name."""
    args = ["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "512",
            "--n-envs", "2", "--no-progress", "--no-video", "--no-eval"]
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always", ResourceWarning)
        assert main([*args, "--out", str(tmp_path / "done")]) == 0
        gc.collect()
        with ctrl_c_after(monkeypatch, 300), contextlib.suppress(KeyboardInterrupt):
            assert main([*args, "--out", str(tmp_path / "stopped")]) == 130
        gc.collect()
    unclosed = [str(w.message) for w in seen if issubclass(w.category, ResourceWarning)]
    assert unclosed == []
    assert (tmp_path / "done" / "progress.csv").read_text().count("\n") >= 2
    assert (tmp_path / "stopped.partial" / "progress.csv").read_text().count("\n") >= 2


def test_ctrl_c_while_a_run_films_says_what_is_missing_and_leaves_no_broken_video(
        tmp_path, monkeypatch, capsys):
    """Training done, a signal during the final evaluation or the video exited silently and
    left a 48-byte rollout.mp4 no player could open."""
    from spinstrike.envs import recording

    real = recording.VideoWriter.write

    def write(self, frame):
        if self.frames == 20:
            raise KeyboardInterrupt
        real(self, frame)

    run = tmp_path / "run"
    with monkeypatch.context() as m, contextlib.suppress(KeyboardInterrupt):
        m.setattr(recording.VideoWriter, "write", write)
        assert main(["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps",
                     "64", "--n-envs", "2", "--out", str(run), "--eval-episodes", "2",
                     "--no-progress"]) == 130
    err = capsys.readouterr().err
    assert f"interrupted after training: the model is saved in {run}" in err
    assert f"`spinstrike record {run}` writes what is missing" in err
    assert (run / "model.zip").is_file() and (run / "summary.md").is_file()
    assert not list(run.glob("*.mp4")), "a truncated video was left"
    assert main(["record", str(run)]) == 0
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(run / "rollout.mp4"))
    assert frames > 20
    assert "replaces" not in capsys.readouterr().out
    # filmed again: the video is replaced, and the line says so
    assert main(["record", str(run), "--episodes", "1"]) == 0
    assert "; it replaces the file that was there" in capsys.readouterr().out
    assert imageio_ffmpeg.count_frames_and_secs(str(run / "rollout.mp4"))[0] < frames


def test_a_run_on_a_scene_file_records_the_scene_and_evaluates_from_anywhere(
        tmp_path, monkeypatch):
    """``--env-kwargs '{scene: scn/table.yaml}'`` was recorded as that relative path: the run
    could not be evaluated from another folder, and an edit of the file after training changed
    what ``evaluate`` measured, silently. An env pickled with such a path (a Ray or
    SubprocVecEnv worker starting elsewhere) could not be rebuilt either."""
    import pickle

    import gymnasium as gym

    scene = envs.config.load_packaged_scene("rod_spin")
    scene["bodies"][0]["length"] = 0.3
    (tmp_path / "scn").mkdir()
    (tmp_path / "scn" / "rod.yaml").write_text(yaml.safe_dump(scene))
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps",
                 "64", "--n-envs", "2", "--env-kwargs", "{scene: scn/rod.yaml}", "--out", "run",
                 "--no-video", "--no-eval", "--no-progress"]) == 0
    env = gym.make("SpinStrike/RodSpin-v0", scene="scn/rod.yaml")
    env.reset(seed=0)
    blob = pickle.dumps(env)
    meta = yaml.safe_load((tmp_path / "run" / "config.yml").read_text())
    kwargs = meta["hyperparameters"]["SpinStrike/RodSpin-v0"]["env_kwargs"]
    assert kwargs["scene"] == scene  # the scene itself
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    (tmp_path / "scn" / "rod.yaml").unlink()
    assert main(["evaluate", str(tmp_path / "run"), "--episodes", "2", "--no-save"]) == 0
    clone = pickle.loads(blob)
    assert clone.unwrapped.world.half_length[0, 0] == 0.15


def test_cli_train_evaluate_record_envs(tmp_path, capsys):
    run = tmp_path / "ppo"
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/PuckSpeed-v0", "--timesteps",
                 "200", "--n-envs", "4", "--out", str(run), "--eval-episodes", "3",
                 "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "oracle: 1.0000" in out and "video:" in out and "chase-and-hit" not in out
    # 4 envs x n_steps 64: SB3 trains whole rollouts, and the run line says why 256, not 200
    assert (f"({4 * 64} steps, " in out and
            "; the budget of 200 rounded up to whole rollouts, as SB3 trains them" in out)
    summary = (run / "summary.md").read_text()
    assert "| agent |" in summary and "| random |" in summary and "| oracle |" in summary
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(run / "rollout.mp4"))
    assert frames > 3 * 15 and seconds > 0
    title = summary.splitlines()[0]
    assert main(["evaluate", str(run), "--episodes", "3", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)  # stdout is the JSON alone (a pipe reads it)
    assert list(report) == ["agent", "random", "oracle"] and report["oracle"]["episodes"] == 3
    again = (run / "summary.md").read_text()  # the run's title stays; the new scores replace
    assert again.splitlines()[0] == title and "Re-evaluated by `spinstrike evaluate`: 3" in again
    video = tmp_path / "oracle.mp4"
    assert main(["record", "--oracle", "--env", "SpinStrike/RodSpinControl-v0", "--out",
                 str(video), "--episodes", "1"]) == 0
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(video))
    assert frames == 251 + 25  # reset + 250 steps, the last held 0.5 s at 50 fps
    assert main(["envs"]) == 0
    assert "SpinStrike/RodSpinControl-v0" in capsys.readouterr().out


def test_cli_evaluates_and_films_the_baselines_on_the_env_asked(tmp_path, capsys):
    """``--env`` takes the README's ``spinstrike:`` id, ``record`` takes ``--random`` (its own
    error named it, the parser refused it), and ``--env-kwargs`` varies the env of
    ``--oracle``/``--random``/``--planner`` as ``train``'s does (a variant could be trained
    but not evaluated or filmed)."""
    ask = ["--env", "spinstrike:SpinStrike/RodSpin-v0", "--episodes", "4", "--json"]
    assert main(["evaluate", "--random", *ask]) == 0
    plain = json.loads(capsys.readouterr().out)["random"]["mean"]
    kwargs = "{restitution: 0.3, striker_mass: 0.05}"
    assert main(["evaluate", "--random", *ask, "--env-kwargs", kwargs]) == 0
    varied = json.loads(capsys.readouterr().out)["random"]["mean"]
    direct = evaluate("SpinStrike/RodSpin-v0", None, 4, 1000,
                      {"restitution": 0.3, "striker_mass": 0.05})
    assert varied == next(r.mean for r in direct if r.policy == "random") != plain
    video = tmp_path / "random.mp4"
    assert main(["record", "--random", "--env", "spinstrike:SpinStrike/RodSpin-v0",
                 "--env-kwargs", kwargs, "--out", str(video), "--episodes", "1"]) == 0
    assert imageio_ffmpeg.count_frames_and_secs(str(video))[0] > 15
    capsys.readouterr()
    assert main(["evaluate", "--oracle", *ask, "--env-kwargs", "{nope: 1}"]) == 2
    assert "nope" in capsys.readouterr().err
    assert main(["record", str(tmp_path), "--env-kwargs", kwargs]) == 2
    assert "a run is evaluated and filmed on the env it was trained on" in \
        capsys.readouterr().err


def test_an_odd_size_is_filmed_and_reported_as_written(tmp_path, capsys):
    """H.264 (yuv420p) needs even sizes: the frames are padded by one row or column. ``record``
    printed the asked size, not the file's; the writer's ``size`` is now the file's and the line
    says it was rounded up. A GIF keeps the asked size."""
    for argv, asked, written in (
            (["--random", "--env", "SpinStrike/RodSpin-v0", "--episodes", "1"], (33, 17), (34, 18)),
            (["--scene", "break", "--seconds", "0.1"], (41, 30), (42, 30))):
        for suffix in (".mp4", ".gif"):
            video = tmp_path / f"v{suffix}"
            size = "x".join(map(str, asked))
            assert main(["record", *argv, "--size", size, "--out", str(video)]) == 0
            line = capsys.readouterr().out
            w, h = written if suffix == ".mp4" else asked
            frame = iio.imread(video, index=0)
            assert frame.shape[:2] == (h, w)
            assert f"{w}x{h}" in line
            assert (f"--size {size} rounded up to even sizes" in line) == (suffix == ".mp4")


def test_installed_entry_point_lists_envs():
    out = subprocess.run(["spinstrike", "envs"], capture_output=True, text=True, check=True)
    for env_id in envs.ENV_IDS:
        assert env_id in out.stdout


def test_resumed_run_continues_from_its_checkpoint(tmp_path):
    run = tmp_path / "run"
    train("ppo", "SpinStrike/RodSpin-v0", timesteps=256, n_envs=4, out=run, progress=False,
          evaluate=False, video=False, eval_freq=128)
    first = np.load(run / "evaluations.npz")["timesteps"]
    result = train("ppo", "SpinStrike/RodSpin-v0", timesteps=512, n_envs=4, out=run,
                   resume=True, progress=False, evaluate=False, video=False, eval_freq=128)
    assert result["timesteps"] >= 512
    meta = yaml.safe_load((run / "config.yml").read_text())
    assert len(meta["runs"]) == 2
    steps = np.loadtxt(run / "progress.csv", delimiter=",", skiprows=1, usecols=None,
                       dtype=str)
    assert len(steps) > 0
    assert np.load(run / "evaluations.npz")["timesteps"].max() > first.max()


def test_bad_inputs_fail_before_anything_is_written(tmp_path, capsys):
    bad = tmp_path / "bad.yml"
    bad.write_text("SpinStrike/RodSpin-v0:\n  n_timesteps: 100\n  learning_rat: 0.1\n")
    with pytest.raises(AgentConfigError, match=r"learning_rat: unknown key"):
        load_agent_config("ppo", "SpinStrike/RodSpin-v0", bad)
    out = tmp_path / "run"
    cases = [
        (["train", "--config", str(bad), "--out", str(out)], "learning_rat: unknown key"),
        (["train", "--env", "SpinStrike/Nope-v0", "--out", str(out)], "unknown id"),
        (["train", "--config", str(tmp_path / "missing.yml"), "--out", str(out)],
         "does not exist"),
        (["train", "--env-kwargs", "{restitution: 3}", "--out", str(out)], "restitution"),
        (["train", "--env-kwargs", "[1, 2]", "--out", str(out)], "must be a mapping"),
        (["evaluate", str(tmp_path)], "not a run"),
        (["record"], "run directory"),
    ]
    for argv, needle in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("error:") and needle in err, (argv, err)
        assert not out.exists() and not out.with_name("run.partial").exists()
    bad.write_text("SpinStrike/RodSpin-v0:\n  n_timesteps: 100\n  policy_kwargs: 'dict(a=1)'\n")
    with pytest.raises(AgentConfigError, match="policy_kwargs.a: unknown"):
        load_agent_config("ppo", "SpinStrike/RodSpin-v0", bad)
    bad.write_text("SpinStrike/Other-v0:\n  n_timesteps: 100\n")
    with pytest.raises(AgentConfigError, match="unknown env id 'SpinStrike/Other-v0'"):
        load_agent_config("ppo", "SpinStrike/RodSpin-v0", bad)


def test_existing_run_is_not_overwritten(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    (run / "model.zip").write_text("precious")
    with pytest.raises(AgentConfigError, match="exists"):
        train("ppo", "SpinStrike/RodSpin-v0", timesteps=64, out=run, progress=False,
              evaluate=False, video=False)
    assert (run / "model.zip").read_text() == "precious"


def test_packaged_configs_cover_every_env_and_algorithm():
    for algo in ALGOS:
        for env_id in envs.ENV_IDS:
            cfg = load_agent_config(algo, env_id)
            assert cfg.env_id == env_id and cfg.n_timesteps > 0
            assert "policy_kwargs" in cfg.model_kwargs


def test_rl_zoo3_trains_from_our_config_and_its_run_record_trains_here(tmp_path, capsys):
    """rl-zoo3 trains from the packaged file; its run's ``config.yml`` (the hyperparameters it
    used, ``-params`` among them, written as a Python OrderedDict) and ``args.yml`` (its command
    line's ``--env-kwargs``) train again with ``spinstrike train --config`` (W18a: refused as
    "not valid YAML"), and another algorithm or env is refused naming the record's."""
    from spinstrike.agents.config import packaged_config_path

    conf = packaged_config_path("ppo")
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env",
           "SpinStrike/RodSpin-v0", "--gym-packages", "spinstrike", "-conf", str(conf),
           "-n", "1024", "-params", "learning_rate:0.001", "--env-kwargs", "restitution:0.5",
           "-f", str(tmp_path), "--eval-freq", "-1", "--seed", "0"]
    subprocess.run(cmd, check=True, capture_output=True, text=True, cwd=tmp_path, timeout=600)
    assert list(tmp_path.rglob("SpinStrike-RodSpin-v0.zip"))
    (record,) = tmp_path.rglob("SpinStrike-RodSpin-v0/config.yml")
    assert record.read_text().startswith("!!python/object/apply:collections.OrderedDict")
    run = tmp_path / "again"
    assert main(["train", "--config", str(record), "--env", "SpinStrike/RodSpin-v0",
                 "--timesteps", "256", "--no-video", "--no-eval", "--no-progress",
                 "--out", str(run)]) == 0
    entry = yaml.safe_load((run / "config.yml").read_text())["hyperparameters"][
        "SpinStrike/RodSpin-v0"]
    zoo = yaml.safe_load(conf.read_text())["SpinStrike/RodSpin-v0"]
    assert entry["learning_rate"] == 0.001 and entry["env_kwargs"] == {"restitution": 0.5}
    assert entry["n_steps"] == zoo["n_steps"] and entry["n_envs"] == zoo["n_envs"]
    capsys.readouterr()
    for wrong, words in ((["--algo", "sac", "--env", "SpinStrike/RodSpin-v0"],
                          "record of a ppo run.*give --algo ppo"),
                         (["--env", "SpinStrike/PuckSpeed-v1"],
                          "record of a run on 'SpinStrike/RodSpin-v0', not "
                          "'SpinStrike/PuckSpeed-v1'")):
        assert main(["train", "--config", str(record), *wrong, "--timesteps", "256",
                     "--no-video", "--no-eval", "--out", str(tmp_path / "x")]) == 2
        assert re.search(words, capsys.readouterr().err)
    # and `spinstrike evaluate` of rl-zoo3's run folder scores its model on its env (with
    # its --env-kwargs) beside random and the oracle (it was "not a run")
    (folder,) = tmp_path.glob("ppo/SpinStrike-RodSpin-v0_*")
    assert main(["evaluate", str(folder), "--episodes", "4", "--json", "--no-save"]) == 0
    scores = json.loads(capsys.readouterr().out)
    assert set(scores) == {"agent", "random", "oracle"}
    from stable_baselines3 import PPO

    model = PPO.load(folder / "SpinStrike-RodSpin-v0.zip", device="cpu")
    agent = lambda env, obs: model.predict(obs, deterministic=True)[0]  # noqa: E731
    on = {kw: evaluate("SpinStrike/RodSpin-v0", agent, 4, 1000, {"restitution": kw},
                       baselines=False)[0].mean for kw in (0.5, 1.0)}
    assert scores["agent"]["mean"] == on[0.5] != on[1.0]


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_during_training_says_resume_and_the_run_resumes(tmp_path):
    """``kill PID`` (SIGTERM, as a cluster's scheduler stops a job) on ``spinstrike train`` after
    a checkpoint: exit code 143, the resume hint, the learning-curve log flushed, and
    ``--resume`` finishes the run (by default SIGTERM ended the process with none of that)."""
    import signal

    args = ["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "100000",
            "--no-video", "--no-progress", "--no-eval", "--out", str(tmp_path / "run")]
    err = signal_after_checkpoint(args, tmp_path, signal.SIGTERM, tmp_path / "run")
    assert "continue with --resume" in err
    assert (tmp_path / "run.partial" / "progress.csv").read_text().count("\n") >= 2
    done = subprocess.run([sys.executable, "-m", "spinstrike.agents.cli", *args, "--resume"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "run" / "model.zip").exists()
    assert yaml.safe_load((tmp_path / "run" / "config.yml").read_text())["runs"][-1][
        "timesteps"] >= 100000


def test_sigterm_between_training_and_the_summary_says_resume(tmp_path):
    """Walk W24b F10: a SIGTERM after training, before the final evaluation began (the run's
    folder renamed, its config.yml being written), ended ``spinstrike train`` with SIGTERM's
    default action: no message, a finished-looking run without its summary. Now: exit 143, the
    command that writes what is missing, and that command writes it. (The signal is sent from
    within the step that books the training, in a new process: the window is milliseconds.)"""
    args = ["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "256",
            "--no-video", "--no-progress", "--eval-episodes", "3", "--out", str(tmp_path / "run")]
    code = ("import os, signal, sys\n"
            "from spinstrike.agents import train\n"
            "real = train._record_segment\n"
            "def booked(*a, **k):\n"
            "    train._record_segment = real\n"
            "    os.kill(os.getpid(), signal.SIGTERM)\n"
            "    return real(*a, **k)\n"
            "train._record_segment = booked\n"
            "from spinstrike.agents.cli import main\n"
            "sys.exit(main(sys.argv[1:]))\n")
    cut = subprocess.run([sys.executable, "-c", code, *args], cwd=tmp_path, capture_output=True,
                         text=True, timeout=600)
    assert cut.returncode == 143, cut.stderr
    assert f"train --resume --out {tmp_path / 'run'}" in cut.stderr
    assert (tmp_path / "run" / "model.zip").exists()
    assert not (tmp_path / "run" / "summary.md").exists()
    # the stretch trained is booked all the same (walk W25 F2: the summary read "0 steps, 0 s")
    runs = yaml.safe_load((tmp_path / "run" / "config.yml").read_text())["runs"]
    assert len(runs) == 1 and runs[0]["timesteps"] >= 256 and runs[0]["wall_time_s"] > 0
    done = subprocess.run([sys.executable, "-m", "spinstrike.agents.cli", *args, "--resume"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    title = (tmp_path / "run" / "summary.md").read_text().splitlines()[0]
    assert title.startswith(f"## PPO on SpinStrike/RodSpin-v0 (seed 0, {runs[0]['timesteps']} "
                            f"steps, "), title


def _record_cli(episodes: int) -> list[str]:
    return [sys.executable, "-m", "spinstrike.agents.cli", "record", "--random", "--env",
            "SpinStrike/RodSpinControl-v0", "--episodes", str(episodes), "--out", "v.mp4"]


def _signal_a_recording(folder, signum: int, episodes: int, settle: float = 0.0):
    """(exit code, stderr) of ``spinstrike record`` into ``folder/v.mp4``, sent ``signum``
    ``settle`` seconds after its partial video appeared."""
    import signal
    import time

    proc = subprocess.Popen(_record_cli(episodes), cwd=folder, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.time() + 240
        while not list(folder.glob("v.*.partial.mp4")):
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.time() < deadline, "no video started in 240 s"
            time.sleep(0.05)
        time.sleep(settle)
        proc.send_signal(signum)
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    return code, proc.stderr.read().decode()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_stopped_recording_leaves_no_video_and_no_traceback(tmp_path, signame):
    """Ctrl-C on ``spinstrike record`` printed a KeyboardInterrupt traceback, and SIGTERM left
    ``NAME.partial.mp4`` behind (found by a new user). Now: exit 128 + the signal, one line,
    no file (SIGTERM's line was missing: walk W20b)."""
    import signal

    signum = getattr(signal, signame)
    code, err = _signal_a_recording(tmp_path, signum, episodes=30, settle=0.5)
    assert code == 128 + signum, err
    assert "Traceback" not in err, err
    said = "interrupted" + (" (SIGTERM)" if signame == "SIGTERM" else "")
    assert err.strip().splitlines()[-1] == f"spinstrike record: {said}", err
    assert sorted(p.name for p in tmp_path.iterdir()) == [], err


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_a_killed_recording_s_partial_video_goes_with_the_next_recording(tmp_path):
    """``spinstrike record`` killed outright (SIGKILL: no handler runs) leaves its partial
    video; it stayed for good, and every kill added one, beside the next recording's video
    (walk W20b). The next recording to the same path removes it; a live process's partial and
    one of another host stay."""
    import signal

    from spinstrike.envs.recording import _HOST

    code, err = _signal_a_recording(tmp_path, signal.SIGKILL, episodes=1)
    assert code == -signal.SIGKILL, err
    [killed] = tmp_path.glob("v.*.partial.mp4")
    live = tmp_path / f"v.{_HOST}-{os.getpid()}-0123abcd.partial.mp4"  # this test's own
    other = tmp_path / "v.elsewhere-1-0123abcd.partial.mp4"  # another host's: unknown
    live.write_bytes(b"")
    other.write_bytes(b"")
    again = subprocess.run(_record_cli(1), cwd=tmp_path, capture_output=True, timeout=300)
    assert again.returncode == 0, again.stderr.decode()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["v.mp4", live.name,
                                                                 other.name]), killed


def test_every_command_helps(capsys):
    """``--help`` of the CLI and of each command exits 0 and says what each command and
    argument is (the baselines description was once cut mid-sentence, ``bench``'s arguments
    had none, the command list at the top showed no usage)."""
    for argv in (["--help"], ["train", "--help"], ["evaluate", "--help"], ["record", "--help"],
                 ["envs", "--help"], ["cache", "--help"], ["bench", "--help"],
                 ["baselines", "--help"]):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 0, argv
        out = capsys.readouterr().out
        assert out.startswith("usage: spinstrike"), argv
    main_help = subprocess.run([sys.executable, "-m", "spinstrike.agents.cli", "--help"],
                               capture_output=True, text=True).stdout
    assert "spinstrike evaluate RUN_DIR | --oracle/--random/--planner" in main_help
    with pytest.raises(SystemExit):
        main(["baselines", "--help"])
    assert "learning-curve plots." in " ".join(capsys.readouterr().out.split())
    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert "the benchmark's own options" in capsys.readouterr().out


def test_cli_train_names_the_control_envs_reference(tmp_path, capsys):
    """On a control env the reference is the scripted chase-and-hit, as evaluate and the docs
    call it (train printed 'oracle', as if it were the strike envs' closed-form optimum)."""
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/PuckSpeedControl-v0",
                 "--timesteps", "64", "--n-envs", "2", "--out", str(tmp_path / "run"),
                 "--eval-episodes", "1", "--no-progress", "--no-video"]) == 0
    assert "oracle (chase-and-hit): " in capsys.readouterr().out


def test_one_rod_oracle_serves_envs_of_different_configs():
    """The oracle's what-if copy is the env's own: used on an env with another speed range
    after a first env, it planned with the first's (its copy was rebuilt only when the number
    of candidate strikes changed), and scored 0 on some episodes a fresh oracle solved."""
    from spinstrike.agents.oracle import RodSpinOracle

    first = gym.make("SpinStrike/RodSpin-v0")
    second = gym.make("SpinStrike/RodSpin-v0", speed_range=[0.25, 2.0], approach_max=40.0,
                      target_spin=[1.0, 10.0])
    shared = RodSpinOracle()
    for seed in range(40):  # alternating, as an evaluation of two variants would
        shared(first, first.reset(seed=seed)[0])
        obs, _ = second.reset(seed=2000 + seed)
        np.testing.assert_array_equal(shared(second, obs), RodSpinOracle()(second, obs))


@pytest.mark.parametrize("kwargs", [
    {"goal": "max"},  # the closed forms' w_max square on: the rod comes round
    {"target_spin": (20, 40)},  # targets beyond w_max: the most spin one impact gives
])
def test_rod_oracle_strikes_the_most_spin_one_impact_gives(kwargs):
    """The rod oracle's closed-form family missed the best lever sqrt(I K) and dropped every
    strike a target beyond w_max needs clipped: it struck 0.983 of w_max every episode (a
    search finds 0.9995; with targets above w_max, reward 0.118 where best_reward is 0.154)."""
    from spinstrike.agents.oracle import RodSpinOracle
    env = gym.make("SpinStrike/RodSpin-v0", **kwargs)
    oracle = RodSpinOracle()
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        info = env.step(oracle(env, obs))[-1]
        assert abs(info["spin"]) >= 0.99 * info["analytic_max_spin"]


@pytest.mark.parametrize("env_id", ["SpinStrike/PuckSpeed-v0", "SpinStrike/PuckSpeed-v1"])
@pytest.mark.parametrize("friction", [None, 0.3])
def test_puck_targets_slower_than_a_centred_strike_are_reached_off_centre(env_id, friction):
    """A 0.5 kg striker's slowest centred strike sends a 0.05 kg puck at 0.864 m/s; targets of
    0.75-0.8 m/s are reached by an off-centre strike (cos(theta) of it). best_reward and the
    oracle took the centred strike for the best (0.34-0.62)."""
    from spinstrike.agents.oracle import PuckSpeedOracle
    kwargs = {"striker_mass": 0.5, "target_speed": (0.75, 0.8)}
    if friction is not None:
        kwargs["friction"] = friction
    env = gym.make(env_id, **kwargs)
    oracle = PuckSpeedOracle()
    for seed in range(4):
        obs, info = env.reset(seed=seed)
        _, reward, _, _, info = env.step(oracle(env, obs))
        assert info["best_reward"] == 1.0
        assert reward == pytest.approx(1.0, abs=1e-6)


def test_evaluate_of_a_no_eval_run_titles_the_summary_with_the_run(tmp_path, capsys):
    """``spinstrike evaluate RUN`` of a run trained with ``--no-eval`` wrote a summary headed by
    the env alone: the run's algorithm, seed, steps and time came from the old summary only."""
    run = tmp_path / "run"
    assert main(["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--timesteps",
                 "256", "--n-envs", "2", "--seed", "3", "--no-eval", "--no-video",
                 "--no-progress", "--out", str(run)]) == 0
    assert not (run / "summary.md").exists()
    assert main(["evaluate", str(run), "--episodes", "2"]) == 0
    lines = (run / "summary.md").read_text().splitlines()
    assert lines[0].startswith("## PPO on SpinStrike/RodSpin-v0 (seed 3, 256 steps, "), lines
    from spinstrike.agents.config import commit

    assert lines[2] == (f"Evaluated by `spinstrike evaluate`: 2 episodes from seed 1000, at "
                        f"commit {commit()}.")


def test_a_run_scored_or_resumed_with_other_versions_says_so(tmp_path, capsys):
    """Walk W24b F5: a run evaluated, filmed or resumed at another commit or with other
    libraries said nothing, its summary re-written with no word of the code that scored it,
    and a resumed run kept only its first session's commit. The record is edited as a
    teammate's older run would read."""
    run = tmp_path / "run"
    args = ["train", "--algo", "ppo", "--env", "SpinStrike/RodSpin-v0", "--n-envs", "2",
            "--no-eval", "--no-video", "--no-progress", "--out", str(run)]
    assert main([*args, "--timesteps", "128"]) == 0
    meta = yaml.safe_load((run / "config.yml").read_text())
    from spinstrike.agents.config import commit

    assert meta["runs"][0]["commit"] == commit()
    meta["versions"] |= {"spinstrike_commit": "0123abc", "numpy": "1.0.0"}
    (run / "config.yml").write_text(yaml.safe_dump(meta, sort_keys=False))
    capsys.readouterr()
    assert main(["evaluate", str(run), "--episodes", "2"]) == 0
    err = capsys.readouterr().err
    assert "was trained with other versions than these: spinstrike_commit 0123abc (now " in err
    assert f"numpy 1.0.0 (now {np.__version__})" in err
    summary = (run / "summary.md").read_text()
    assert f"at commit {commit()} (the run trained with spinstrike_commit 0123abc" in summary
    assert main([*args, "--timesteps", "256", "--resume"]) == 0
    assert "note: resume:" in capsys.readouterr().err
    runs = yaml.safe_load((run / "config.yml").read_text())["runs"]
    assert [r["commit"] for r in runs] == [commit(), commit()]


def test_spinstrike_version_names_the_commit_of_the_code_that_runs(tmp_path):
    """``spinstrike --version`` (it was a usage error): the version, and the commit where the
    code runs from a git checkout, as a run records."""
    import subprocess
    import sys
    from importlib.metadata import version
    from pathlib import Path

    import spinstrike.agents

    out = subprocess.run([sys.executable, "-m", "spinstrike", "--version"], capture_output=True,
                         text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    here = Path(spinstrike.agents.__file__).parent
    git = subprocess.run(["git", "-C", str(here), "rev-parse", "--short", "HEAD"],
                         capture_output=True, text=True)
    tracked = subprocess.run(["git", "-C", str(here), "ls-files", "--error-unmatch",
                              "config.py"], capture_output=True).returncode == 0
    edited = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                             "--untracked-files=no"], capture_output=True, text=True).stdout
    if git.returncode == 0 and tracked:
        commit = git.stdout.strip() + ("+dirty" if edited.strip() else "")
        assert out.stdout == f"spinstrike {version('spinstrike')} (commit {commit})\n"
    else:  # the other cases (a build's stamp, why unknown): tests/test_version.py
        assert out.stdout.startswith(f"spinstrike {version('spinstrike')} (commit ")
        assert "(commit unknown)" not in out.stdout, "unknown says why (walk W24b F9)"



def test_training_an_rllib_record_again_trains_with_rllib(tmp_path, monkeypatch):
    """Walk W26a F4: ``spinstrike train --config RLLIB_RUN/config.yml`` (the README's way to
    train a run again) trained SB3's PPO, silently, the record's ``backend: rllib`` unread. The
    record's backend is the one left out on the command line; an SB3 record and a
    hyperparameter file stay SB3's. (RLlib itself is stubbed: the backend chosen is the test.)"""
    import spinstrike.agents.cli as cli

    chosen = []

    class Chosen(Exception):
        pass

    def stub(args):
        chosen.append(args.backend)
        raise Chosen

    monkeypatch.setattr(cli, "_require_extra", lambda *a, **k: None)
    monkeypatch.setattr(cli, "_train_rllib", stub)
    record = {"algo": "ppo", "env": "SpinStrike/RodSpin-v0", "backend": "rllib", "seed": 3,
              "hyperparameters": {"n_steps": 64}}
    path = tmp_path / "config.yml"
    path.write_text(yaml.safe_dump(record))
    with pytest.raises(Chosen):
        main(["train", "--config", str(path), "--out", str(tmp_path / "again")])
    assert chosen == ["rllib"]
    path.write_text(yaml.safe_dump({**record, "backend": "sb3"}))
    monkeypatch.setattr(cli, "_train_rllib", None)  # (never called)
    import spinstrike.agents.train as train_module

    def sb3(*args, **kwargs):
        chosen.append("sb3")
        raise Chosen

    monkeypatch.setattr(train_module, "train", sb3)
    with pytest.raises(Chosen):
        main(["train", "--config", str(path), "--out", str(tmp_path / "again2")])
    assert chosen == ["rllib", "sb3"]
