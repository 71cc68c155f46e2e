"""The CLI refuses bad input cleanly: exit status 2, one ``error:`` line on stderr naming the
argument, file or field, no traceback, and nothing created or changed on disk (no run directory,
no ``.partial``). Complements ``test_agents.py::test_bad_inputs_fail_before_anything_is_written``.

Nothing here trains: where a run directory is needed its files are written by hand.
"""

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch
import yaml

from spinstrike.agents.cli import main
from spinstrike.agents.config import AgentConfigError, load_agent_config

ENV = "SpinStrike/RodSpin-v0"


def _tree(root: Path) -> dict[str, str]:
    """Every path under ``root`` with a digest of its content (directories: "dir")."""
    return {str(p.relative_to(root)): "dir" if p.is_dir()
            else hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*"))}


def _config(tmp: Path, name: str, entry: dict, env_id: str = ENV) -> str:
    path = tmp / name
    path.write_text(yaml.safe_dump({env_id: entry}))
    return str(path)


def _text(tmp: Path, name: str, text: str) -> str:
    (tmp / name).parent.mkdir(parents=True, exist_ok=True)
    (tmp / name).write_text(text)
    return str(tmp / name)


def _dir(tmp: Path, name: str) -> str:
    (tmp / name).mkdir()
    return str(tmp / name)


def _fake_run(tmp: Path, name: str, config_text: str | None = None,
              model: bytes = b"not a zip") -> str:
    """A run directory written by hand (no training): config.yml and model.zip."""
    run = tmp / name
    run.mkdir()
    if config_text is None:
        config_text = yaml.safe_dump({"algo": "ppo", "env": ENV, "seed": 0,
                                      "hyperparameters": {ENV: {"n_timesteps": 64}}})
    (run / "config.yml").write_text(config_text)
    (run / "model.zip").write_bytes(model)
    return str(run)


def _interrupted(tmp: Path) -> str:
    """What an interrupted ``spinstrike train`` leaves (in ``RUN.partial``): config.yml and
    checkpoints but no model.zip (written by hand)."""
    run = Path(_fake_run(tmp, "stopped"))
    (run / "model.zip").unlink()
    (run / "checkpoints").mkdir()
    (run / "checkpoints" / "model_256_steps.zip").write_bytes(b"not a zip")
    return str(run)


# each case: (id, build(tmp) -> argv, words the error line must contain)
CASES = [
    # a run's agent on its own env: another env or policy asked for was dropped without a word
    ("evaluate-run-with-env",
     lambda t: ["evaluate", _fake_run(t, "done"), "--env", "SpinStrike/PuckSpeed-v1"],
     ["--env:", "its own agent on the env it was trained on", "without a run directory"]),
    ("evaluate-run-with-oracle-and-env",  # (--oracle --random: argparse's, below)
     lambda t: ["evaluate", _fake_run(t, "done"), "--oracle", "--env", ENV],
     ["--env, --oracle:", "--env and --oracle go without a run directory"]),
    ("record-run-with-planner",
     lambda t: ["record", _fake_run(t, "done"), "--planner"],
     ["--planner:", "its own agent"]),
    ("config-is-a-directory",
     lambda t: ["train", "--config", _dir(t, "conf.d")],
     ["config:", "conf.d", "is a directory"]),
    ("config-without-env-or-default",
     lambda t: ["train", "--config", _config(t, "other.yml", {"n_timesteps": 100},
                                             "SpinStrike/PuckSpeed-v0")],
     ["config:", "other.yml", f"no entry for '{ENV}'", "no 'default'"]),
    ("n_timesteps-not-a-number",
     lambda t: ["train", "--config", _config(t, "abc.yml", {"n_timesteps": "abc"})],
     ["abc.yml", "n_timesteps: must be a number", "'abc'"]),
    ("n_timesteps-negative",
     lambda t: ["train", "--config", _config(t, "neg.yml", {"n_timesteps": -1000})],
     ["neg.yml", "n_timesteps: must be >= 1", "-1000"]),
    ("n_envs-zero",
     lambda t: ["train", "--config", _config(t, "zero.yml", {"n_timesteps": 100, "n_envs": 0})],
     ["zero.yml", "n_envs: must be an integer >= 1", "(got 0)"]),
    ("n_envs-negative",
     lambda t: ["train", "--config", _config(t, "m2.yml", {"n_timesteps": 100, "n_envs": -2})],
     ["m2.yml", "n_envs: must be an integer >= 1", "(got -2)"]),
    ("normalize-string-evaluated",  # rl-zoo3 evaluates it; it was taken for plain true
     lambda t: ["train", "--config", _config(t, "ns.yml", {
         "n_timesteps": 100, "normalize": "dict(norm_obs=__import__('os').getpid())"})],
     ["ns.yml", "normalize: \"__import__('os').getpid()\"", "without evaluating them"]),
    ("policy-kwargs-string-unknown-class",
     lambda t: ["train", "--config", _config(t, "pk.yml", {
         "n_timesteps": 100, "policy_kwargs": "dict(activation_fn=nn.Softmax)"})],
     ["pk.yml", "policy_kwargs: 'nn.Softmax'", "not a value or an activation"]),
    ("normalize-unknown-argument",
     lambda t: ["train", "--config", _config(t, "nu.yml", {
         "n_timesteps": 100, "normalize": {"norm_obs": True, "norm_rewards": False}})],
     ["nu.yml", "normalize.norm_rewards: unknown", "norm_reward"]),
    ("replay-buffer-class",  # rl-zoo3's way to ask for HER: was a TypeError traceback
     lambda t: ["train", "--algo", "sac", "--config", _config(t, "her.yml", {
         "n_timesteps": 100, "replay_buffer_class": "HerReplayBuffer"})],
     ["her.yml", "replay_buffer_class: not supported by spinstrike train", "HerReplayBuffer"]),
    ("env-kwargs-unknown",
     lambda t: ["train", "--env-kwargs", "{bogus_kwarg: 1}"],
     ["bogus_kwarg", "unknown argument", "restitution"]),
    # a key given twice: PyYAML kept the last silently
    ("env-kwargs-no-space-after-colon",  # was "max_forse:1: unknown argument (got None)"
     lambda t: ["train", "--env-kwargs", "{restitution:0.5}"],
     ["--env-kwargs", "'restitution:0.5' reads as one key", "'{restitution: 0.5}'"]),
    ("env-kwargs-duplicate-key",
     lambda t: ["train", "--env-kwargs", "{restitution: 0.5, restitution: 0.7}"],
     ["--env-kwargs", "found the key 'restitution' twice"]),
    ("config-duplicate-key",
     lambda t: ["train", "--config", _text(t, "dup.yml", f"{ENV}:\n  n_timesteps: 100\n"
                                                      f"  n_envs: 2\n  n_envs: 4\n")],
     ["dup.yml", "found the key 'n_envs' twice", "line 3"]),
    ("scene-file-duplicate-key",
     lambda t: ["train", "--env-kwargs", "{scene: " + _text(
         t, "dup.yaml", "effects: [rotation]\neffects: [rotation, walls]\n") + "}"],
     ["scene", "found the key 'effects' twice", "line 1"]),
    # rl-zoo3's own values that passed the checks and crashed inside SB3 with a traceback
    ("ppo-ent-coef-auto",  # 'auto' is SAC's: a TypeError in learn(), after the rollouts
     lambda t: ["train", "--config", _config(t, "ent.yml", {"n_timesteps": 100,
                                                           "ent_coef": "auto"})],
     ["ent.yml", ".ent_coef: a number >= 0 for PPO; 'auto' is SAC's"]),
    ("policy-kwargs-net-arch-string",  # torch's TypeError building the network
     lambda t: ["train", "--config", _config(t, "arch.yml", {
         "n_timesteps": 100, "policy_kwargs": {"net_arch": "64,64"}})],
     ["hyperparameters (", "arch.yml", "stable-baselines3's PPO refused them"]),
    ("rollout-buffer-kwargs-unknown",  # RolloutBuffer's TypeError
     lambda t: ["train", "--config", _config(t, "buf.yml", {
         "n_timesteps": 100, "rollout_buffer_kwargs": {"foo": 1}})],
     ["buf.yml", "stable-baselines3's PPO refused them", "'foo'"]),
    ("eval-episodes-zero",
     lambda t: ["train", "--eval-episodes", "0"],
     ["--eval-episodes: must be >= 1"]),
    ("out-exists-without-force",
     lambda t: ["train", "--out", _fake_run(t, "done")],
     ["out:", "done exists", "--force"]),
    # --force deleted whatever --out named: a folder of a user's files (or of runs) went
    ("force-on-a-folder-that-is-no-run",
     lambda t: ["train", "--force", "--out", _text(t, "mine/notes.txt", "precious") and
                str(t / "mine")],
     ["out:", "mine is not a run directory (no config.yml recording a run's algo and env) and "
              "not empty", "--force replaces a run only"]),
    # a project folder with a config.yml of its own was replaced, results and all
    ("force-on-a-project-with-a-config-yml",
     lambda t: ["train", "--force", "--out", _text(t, "proj/config.yml", "name: mylab\n") and
                _text(t, "proj/results.csv", "1,2") and str(t / "proj")],
     ["out:", "proj is not a run directory (no config.yml recording a run's algo and env)"]),
    ("imitate-rounds-without-imitate",  # accepted and ignored
     lambda t: ["train", "--imitate-rounds", "3"],
     ["--imitate-rounds: --imitate's, not given (got 3)"]),
    ("num-env-runners-on-sb3",
     lambda t: ["train", "--num-env-runners", "5", "--address", "1.2.3.4:6379"],
     ["--num-env-runners: --backend rllib's, not given (got 5)"]),
    ("eval-episodes-with-no-eval",
     lambda t: ["train", "--no-eval", "--eval-episodes", "3"],
     ["--eval-episodes: the final evaluation's, which --no-eval leaves out"]),
    ("train-freq-per-episode-with-many-envs",  # SB3's AssertionError inside learn(), before
     lambda t: ["train", "--algo", "sac", "--n-envs", "2", "--config",
                _config(t, "ep.yml", {"n_timesteps": 100, "train_freq": [1, "episode"]})],
     ["train_freq: [1, 'episode'] trains once per episode", "one env only (n_envs is 2)",
      "--n-envs 1"]),
    ("learning-rate-diverges",  # torch's hundred-line traceback about a Normal's scale
     lambda t: ["train", "--no-progress", "--config", _config(t, "div.yml", {
         "n_timesteps": 512, "n_envs": 2, "n_steps": 64, "batch_size": 64,
         "learning_rate": 1e30})],
     ["training diverged by step", "lower the learning_rate", "div.yml"]),
    ("record-scene-dt-beyond-seconds",  # simulated and filmed 5 s
     lambda t: ["record", "--scene", "break", "--dt", "5", "--seconds", "3"],
     ["--dt: a frame per step of 5 s is longer than the --seconds 3 to film"]),
    ("out-exists-and-is-no-run",  # said "pass --force to replace it", which then refused
     lambda t: ["train", "--out", _text(t, "notes/a.txt", "x") and str(t / "notes")],
     ["out:", "notes exists and is not a run directory", "choose another --out"]),
    ("record-under-a-file",  # FileExistsError, a traceback
     lambda t: ["record", "--random", "--env", ENV, "--episodes", "1", "--out",
                _text(t, "afile", "x") + "/x.mp4"],
     ["afile: File exists (a file, where the path needs a folder)"]),
    ("record-where-nothing-can-be-written",  # ffmpeg's broken pipe at the first frame
     lambda t: ["record", "--random", "--env", ENV, "--episodes", "1", "--out",
                "/proc/spinstrike-nope.mp4"],
     ["/proc/spinstrike-nope.mp4:"]),
    ("record-grid-beyond-4096",  # an 8192 x 8192 H.264 that players refuse, written
     lambda t: ["record", "--random", "--env", ENV, "--episodes", "4", "--grid", "--size",
                "2100x300", "--out", str(t / "g.mp4")],
     ["grid: 4 episodes of 2100x300 tile to 4200x600, beyond 4096 pixels a side"]),
    ("record-onto-a-folder",  # filmed whole, then failed, leaving NAME.partial.mp4 behind
     lambda t: ["record", "--random", "--env", ENV, "--episodes", "1", "--out",
                _dir(t, "videos.mp4")],
     ["--out:", "videos.mp4 is a folder; the video needs a file name ending in .mp4 or .gif"]),
    # a file: failed after training, and the trained model was deleted with the .partial
    ("force-on-a-file",
     lambda t: ["train", "--force", "--out", _text(t, "afile", "x")],
     ["out:", "afile is a file, not a run directory"]),
    ("out-dot",  # was "ValueError: PosixPath('.') has an empty name"
     lambda t: ["train", "--out", "."],
     ["out: '.' names a folder by its place, not a run directory", "runs/my-run"]),
    ("max-episode-steps-zero",  # was gymnasium's bare AssertionError, a traceback
     lambda t: ["train", "--env-kwargs", "{max_episode_steps: 0}"],
     ["max_episode_steps: must be an int >= 1", "(got 0)"]),
    ("render-mode-in-env-kwargs",  # was a TypeError when the video was written, after training
     lambda t: ["train", "--env-kwargs", "{render_mode: rgb_array}"],
     ["env_kwargs: render_mode is not an env argument of a training run", "'rgb_array'"]),
    ("bad-env-kwarg-and-out-exists",  # the argument's error first (it said "out ... exists")
     lambda t: ["train", "--out", _fake_run(t, "done"), "--env-kwargs", "{restitution: 2}"],
     ["restitution", "less than or equal to 1"]),
    ("resume-without-checkpoint",
     lambda t: ["train", "--resume", "--out", _fake_run(t, "nockpt")],
     ["resume:", "nockpt", "no checkpoint"]),
    ("resume-not-a-run",
     lambda t: ["train", "--resume", "--out", _dir(t, "empty")],
     ["resume:", "empty", "not a run directory"]),
    ("imitate-unknown-teacher",
     lambda t: ["train", "--env", "SpinStrike/PuckSpeedControl-v0", "--imitate", "oracle"],
     ["--imitate: unknown teacher 'oracle'", "planner", "chase-and-hit"]),
    ("imitate-not-ppo",
     lambda t: ["train", "--algo", "sac", "--env", "SpinStrike/PuckSpeedControl-v0",
                "--imitate", "planner"],
     ["--imitate: starts PPO only", "--algo sac"]),
    ("imitate-planner-on-a-strike-env",
     lambda t: ["train", "--imitate", "planner"],
     ["--imitate planner", "control envs only", ENV]),
    ("imitate-rounds-zero",
     lambda t: ["train", "--env", "SpinStrike/PuckSpeedControl-v0", "--imitate", "planner",
                "--imitate-rounds", "0"],
     ["--imitate-rounds: must be an integer >= 1", "(got 0)"]),
    ("learning-rate-negative",  # raised in torch's optimiser, deep in a traceback, before
     lambda t: ["train", "--config", _config(t, "lr.yml", {"n_timesteps": 100,
                                                          "learning_rate": -1.0})],
     ["lr.yml", ".learning_rate: must be a number > 0", "(got -1.0)"]),
    ("n-steps-not-a-number",  # a TypeError in SB3's own comparison, before
     lambda t: ["train", "--config", _config(t, "steps.yml", {"n_timesteps": 100,
                                                             "n_steps": "many"})],
     ["steps.yml", ".n_steps: must be an integer >= 1", "(got 'many')"]),
    ("gamma-above-one",  # accepted silently, before
     lambda t: ["train", "--config", _config(t, "gamma.yml", {"n_timesteps": 100,
                                                             "gamma": 1.5})],
     ["gamma.yml", ".gamma: must be a number in [0, 1]", "(got 1.5)"]),
    ("batch-size-fractional",
     lambda t: ["train", "--config", _config(t, "batch.yml", {"n_timesteps": 100,
                                                             "batch_size": 64.5})],
     [".batch_size: must be an integer >= 1", "(got 64.5)"]),
    ("learning-rate-schedule-negative",
     lambda t: ["train", "--config", _config(t, "lin.yml", {"n_timesteps": 100,
                                                           "learning_rate": "lin_-0.001"})],
     [".learning_rate: 'lin_<number>' needs a number > 0"]),
    ("imitate-with-normalize",
     lambda t: ["train", "--env", "SpinStrike/PuckSpeedControl-v0", "--imitate", "planner",
                "--config", _config(t, "norm.yml", {"n_timesteps": 100, "normalize": True},
                                    "SpinStrike/PuckSpeedControl-v0")],
     ["--imitate: not with 'normalize: true'"]),
    ("imitate-rllib",
     lambda t: ["train", "--backend", "rllib", "--imitate", "planner"],
     ["--imitate: starts SB3's PPO only", "rllib"]),
    ("evaluate-corrupt-config-yml",
     lambda t: ["evaluate", _fake_run(t, "corrupt", "algo: [ppo\nenv: :\n")],
     ["config.yml", "corrupt", "not valid YAML", "line 2"]),
    ("evaluate-unknown-algo",
     lambda t: ["evaluate", _fake_run(t, "dqn", yaml.safe_dump(
         {"algo": "dqn", "env": ENV, "hyperparameters": {ENV: {}}}))],
     ["config.yml", "dqn", "algo: unknown algorithm 'dqn'", "ppo"]),
    ("evaluate-unknown-env",
     lambda t: ["evaluate", _fake_run(t, "noenv", yaml.safe_dump(
         {"algo": "ppo", "env": "SpinStrike/Nope-v0", "hyperparameters": {}}))],
     ["config.yml", "env: unknown id 'SpinStrike/Nope-v0'"]),
    ("evaluate-model-not-a-zip",
     lambda t: ["evaluate", _fake_run(t, "junk")],
     ["model.zip", "junk", "could not be loaded"]),
    ("evaluate-episodes-zero",
     lambda t: ["evaluate", "--oracle", "--env", ENV, "--episodes", "0"],
     ["--episodes: must be >= 1", "(got 0)"]),
    ("evaluate-episodes-negative",
     lambda t: ["evaluate", "--random", "--env", ENV, "--episodes", "-3"],
     ["--episodes: must be >= 1", "(got -3)"]),
    ("evaluate-run-episodes-zero",  # a run directory gets no summary.md either
     lambda t: ["evaluate", _fake_run(t, "run0"), "--episodes", "0"],
     ["--episodes: must be >= 1"]),
    ("record-oracle-without-env",
     lambda t: ["record", "--oracle"],
     ["--oracle", "needs --env"]),
    ("record-episodes-zero",
     lambda t: ["record", "--oracle", "--env", ENV, "--episodes", "0", "--out",
                str(t / "v.mp4")],
     ["--episodes: must be >= 1"]),
    ("record-out-not-a-video",
     lambda t: ["record", "--oracle", "--env", ENV, "--out", str(t / "v.avi")],
     ["--out: must end in .mp4 or .gif", "v.avi"]),
    ("record-size-not-w-x-h",
     lambda t: ["record", "--oracle", "--env", ENV, "--size", "big", "--out",
                str(t / "sub" / "v.mp4")],
     ["--size: must be WIDTHxHEIGHT", "'big'"]),
    ("record-scene-with-a-policy",
     lambda t: ["record", "--scene", "break", "--oracle", "--env", ENV],
     ["--scene: films a physics scene with no policy", "--env, --oracle"]),
    ("record-scene-seconds-zero",
     lambda t: ["record", "--scene", "break", "--seconds", "0", "--out", str(t / "v.mp4")],
     ["--seconds: must be a number > 0", "(got 0.0)"]),
    ("record-scene-unknown",
     lambda t: ["record", "--scene", "nosuch", "--out", str(t / "v.mp4")],
     ["scene: 'nosuch' is neither a file nor a packaged scene"]),
    ("policy-that-cannot-take-the-observations",
     lambda t: ["train", "--config", _config(t, "cnn.yml", {"policy": "CnnPolicy",
                                                            "n_timesteps": 64})],
     ["policy: CnnPolicy cannot take vector observations", "use MlpPolicy"]),
    ("multi-input-policy-on-pixels",
     lambda t: ["train", "--config", _config(t, "mi.yml", {"policy": "MultiInputPolicy",
                                                           "n_timesteps": 64}),
                "--env-kwargs", "{obs_mode: pixels}"],
     ["policy: MultiInputPolicy cannot take pixels observations", "use CnnPolicy"]),
    ("evaluate-an-interrupted-run",
     lambda t: ["evaluate", _interrupted(t)],
     ["is an interrupted run", "spinstrike train --resume --out", "/stopped`"]),
    # hyperparameter-file keys that crashed SB3 with a traceback, or were dropped or changed
    # silently (tests/agents/test_hyperparameter_files.py: the values now accepted)
    ("td3-noise-std-without-noise-type",  # was dropped: TD3 trained with no exploration noise
     lambda t: ["train", "--algo", "td3", "--config", _config(t, "ns.yml", {
         "n_timesteps": 100, "noise_std": 0.5})],
     ["ns.yml", ".noise_std: needs noise_type: normal beside it"]),
    ("sac-noise-type-without-noise-std",  # was a std of 0.1, said nowhere
     lambda t: ["train", "--algo", "sac", "--config", _config(t, "nt.yml", {
         "n_timesteps": 100, "noise_type": "normal"})],
     ["nt.yml", ".noise_type: needs noise_std: <std> beside it"]),
    ("td3-noise-std-negative",  # numpy's ValueError 'scale < 0', a traceback
     lambda t: ["train", "--algo", "td3", "--config", _config(t, "neg.yml", {
         "n_timesteps": 100, "noise_type": "normal", "noise_std": -0.3})],
     ["neg.yml", ".noise_std: must be a number >= 0", "(got -0.3)"]),
    ("ppo-noise",  # PPO() got an unexpected keyword argument 'action_noise', a traceback
     lambda t: ["train", "--config", _config(t, "pn.yml", {
         "n_timesteps": 100, "noise_type": "normal", "noise_std": 0.2})],
     ["pn.yml", ": PPO takes no action noise", "SAC's and TD3's", "log_std_init"]),
    ("seed-in-the-file",  # PPO() got multiple values for keyword argument 'seed'
     lambda t: ["train", "--config", _config(t, "seed.yml", {"n_timesteps": 100, "seed": 3})],
     ["seed.yml", ".seed: not set by a hyperparameter file", "(got 3)", "use --seed"]),
    ("device-in-the-file",  # likewise
     lambda t: ["train", "--config", _config(t, "dev.yml", {"n_timesteps": 100,
                                                           "device": "cpu"})],
     ["dev.yml", ".device: not set by a hyperparameter file", "use --device"]),
    ("verbose-in-the-file",  # likewise
     lambda t: ["train", "--config", _config(t, "verb.yml", {"n_timesteps": 100,
                                                            "verbose": 1})],
     ["verb.yml", ".verbose: not set by a hyperparameter file", "RUN/progress.csv"]),
    ("init-setup-model-in-the-file",  # an AttributeError later, a traceback
     lambda t: ["train", "--config", _config(t, "init.yml", {"n_timesteps": 100,
                                                            "_init_setup_model": False})],
     ["init.yml", "._init_setup_model: not set by a hyperparameter file"]),
    ("tensorboard-log-in-the-file",  # accepted, and the logs went to RUN/tb all the same
     lambda t: ["train", "--config", _config(t, "tb.yml", {"n_timesteps": 100,
                                                          "tensorboard_log": "/tmp/tbx"})],
     ["tb.yml", ".tensorboard_log: not set by a hyperparameter file", "'/tmp/tbx'",
      "RUN/tb"]),
    ("action-noise-in-the-file",  # SB3 needs an object: a traceback in the first step
     lambda t: ["train", "--algo", "td3", "--config", _config(t, "an.yml", {
         "n_timesteps": 100, "action_noise": 0.1})],
     ["an.yml", ".action_noise: not set by a hyperparameter file", "noise_std"]),
    ("n-timesteps-fractional",  # was truncated to 512 (--timesteps 512.7 is refused)
     lambda t: ["train", "--config", _config(t, "frac.yml", {"n_timesteps": 512.7})],
     ["frac.yml", ".n_timesteps: must be a whole number of steps", "(got 512.7)"]),
    ("record-scene-with-options-it-ignores",  # they were ignored: the same video, exit 0
     lambda t: ["record", "--scene", "break", "--seconds", "0.5", "--out", str(t / "v.mp4"),
                "--env-kwargs", "{restitution: 0.1}", "--random", "--episodes", "9",
                "--seed", "5"],
     ["--scene: films a physics scene with no policy", "--random, --env-kwargs, --episodes, "
      "--seed", "it takes --out, --seconds, --dt and --size"]),
    ("record-seconds-without-scene",  # likewise ignored
     lambda t: ["record", "--oracle", "--env", ENV, "--seconds", "5", "--dt", "0.1", "--out",
                str(t / "v.mp4")],
     ["--seconds, --dt: only with --scene"]),
    ("evaluate-render-mode-in-env-kwargs",  # said "not an env argument of a training run"
     lambda t: ["evaluate", "--random", "--env", ENV, "--env-kwargs", "{render_mode: human}"],
     ["--env-kwargs: render_mode is not taken by spinstrike evaluate", "'human'"]),
    ("record-render-mode-in-env-kwargs",
     lambda t: ["record", "--random", "--env", ENV, "--env-kwargs", "{render_mode: human}",
                "--out", str(t / "v.mp4")],
     ["--env-kwargs: render_mode is not taken by spinstrike record", "'human'"]),
    ("record-size-too-small",
     lambda t: ["record", "--oracle", "--env", ENV, "--size", "8x8", "--out",
                str(t / "sub" / "v.gif")],
     ["--size: must be two sizes in [16, 4096] pixels", "(got (8, 8))"]),
    ("record-scene-size-too-large",  # was taken, and a 5000x5000 frame was drawn
     lambda t: ["record", "--scene", "break", "--size", "5000x100", "--out", str(t / "v.mp4")],
     ["--size: must be two sizes in [16, 4096] pixels", "(got (5000, 100))"]),
]


@pytest.fixture
def sandbox(tmp_path, monkeypatch):
    """An empty working directory (a default ``runs/`` or ``*.mp4`` would land here). Without
    the one-line notice of a first compilation, which a cold or stale kernel cache adds to the
    error line where this test is the first in its process to build an env."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SPINSTRIKE_QUIET", "1")
    return tmp_path


@pytest.mark.parametrize(("build", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_input_is_one_error_line_and_writes_nothing(build, words, sandbox, capsys):
    argv = build(sandbox)
    if argv[0] == "train" and "--out" not in argv:
        argv += ["--out", str(sandbox / "run")]
    before = _tree(sandbox)
    capsys.readouterr()
    assert main(argv) == 2, argv
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), captured.err
    assert "Traceback" not in captured.err + captured.out
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert _tree(sandbox) == before, "the CLI created or changed files"
    assert not list(sandbox.rglob("*.partial"))


@pytest.mark.parametrize(("argv", "argument", "value"), [
    (["train", "--algo", "dqn"], "--algo", "'dqn'"),
    (["bench", "nope"], "which", "'nope'"),
    (["evaluate", "--episodes", "many"], "--episodes", "'many'"),
    (["train", "--timesteps", "100.5"], "--timesteps", "'100.5'"),
    # named the hyperparameter file's n_timesteps and n_envs, not the flags
    (["train", "--timesteps", "0"], "--timesteps", "must be >= 1 step (got '0')"),
    (["train", "--timesteps", "-5"], "--timesteps", "must be >= 1 step (got '-5')"),
    (["train", "--n-envs", "0"], "--n-envs", "must be an integer >= 1 (got '0')"),
    # --clear --prune cleared the cache and ignored --prune
    (["cache", "--clear", "--prune"], "--prune", "not allowed with argument --clear"),
    # were tracebacks (torch's, numpy's, Gymnasium's) after the arguments were taken
    (["train", "--device", "gpu"], "--device", "not a PyTorch device (got 'gpu')"),
    (["train", "--torch-threads", "-2"], "--torch-threads", "must be an integer >= 0"),
    # SB3 trained on the CPU without a word when no CUDA device was there
    pytest.param(["train", "--device", "cuda"], "--device", "sees no cuda device here",
                 marks=pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is here")),
    (["train", "--seed", "-1"], "--seed", "must be an integer from 0 to 4294967295"),
    (["evaluate", "--oracle", "--env", ENV, "--seed", "-1"], "--seed", "(got '-1')"),
    (["record", "--oracle", "--env", ENV, "--seed", "-3"], "--seed", "(got '-3')"),
    # --oracle --random filmed the random policy silently
    (["record", "--oracle", "--random", "--env", ENV], "--random",
     "not allowed with argument --oracle"),
    (["evaluate", "--planner", "--oracle", "--env", ENV], "--oracle",
     "not allowed with argument --planner"),
    # beyond SB3's 32-bit seeds: blamed the hyperparameter file; baselines left an empty folder
    (["train", "--seed", str(2**32)], "--seed", "from 0 to 4294967295"),
    (["baselines", "--quick", "--seeds", "0", str(2**40)], "--seeds", "from 0 to 4294967295"),
    (["baselines", "--quick", "--planner-episodes", "-2"], "--planner-episodes",
     "'-2'"),  # read as 0
], ids=["algo-not-in-list", "bench-unknown", "episodes-not-an-int", "timesteps-not-whole",
        "timesteps-zero", "timesteps-negative", "n-envs-zero",
        "cache-clear-and-prune", "device-unknown", "torch-threads-negative",
        "device-cuda-not-here", "train-seed-negative",
        "evaluate-seed-negative", "record-seed-negative", "record-oracle-and-random",
        "evaluate-planner-and-oracle", "train-seed-beyond-32-bits",
        "baselines-seed-beyond-32-bits", "baselines-planner-episodes-negative"])
def test_argparse_rejects_choices_with_status_2(argv, argument, value, sandbox, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    [line] = [x for x in err.splitlines() if "error:" in x]
    assert f"argument {argument}:" in line and value in line, err
    assert "Traceback" not in err
    assert not any(sandbox.iterdir())


def test_device_auto_is_sb3s_and_trains(sandbox, capsys):
    """``auto`` (SB3's own choice: cuda where there is one) was refused as not a PyTorch
    device; it trains."""
    assert main(["train", "--device", "auto", "--timesteps", "64", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run"]) == 0
    assert (sandbox / "run" / "model.zip").is_file()


def test_the_command_line_takes_a_budget_as_the_hyperparameter_files_write_it():
    """``--timesteps 1e3`` was refused on the command line while a file's ``1e6`` is read."""
    from spinstrike.agents.cli import build_parser

    for text, steps in (("1e3", 1000), ("2.5e4", 25000), ("512", 512)):
        args = build_parser().parse_args(["train", "--algo", "ppo", "--env", ENV,
                                          "--timesteps", text])
        assert args.timesteps == steps and isinstance(args.timesteps, int)


def test_yaml_1e6_is_accepted_as_an_integer_budget(tmp_path):
    """PyYAML reads ``1e6`` (no dot) as a string; the config reads it as 1000000 steps."""
    assert yaml.safe_load("n: 1e6")["n"] == "1e6"
    path = tmp_path / "big.yml"
    path.write_text(f"{ENV}:\n  n_timesteps: 1e6\n  n_envs: 4\n")
    cfg = load_agent_config("ppo", ENV, path)
    assert cfg.n_timesteps == 1_000_000 and isinstance(cfg.n_timesteps, int)
    assert cfg.n_envs == 4
    path.write_text(f"{ENV}:\n  n_timesteps: 1e6x\n")
    with pytest.raises(AgentConfigError, match=r"n_timesteps: must be a number \(got '1e6x'\)"):
        load_agent_config("ppo", ENV, path)


@pytest.mark.parametrize("hidden,extras", [(["rliable"], "stats"),
                                           (["stable_baselines3"], "train"),
                                           (["stable_baselines3", "rliable"], "train,stats")])
def test_baselines_without_its_extras_says_so_before_training(sandbox, capsys, monkeypatch,
                                                              hidden, extras):
    """Without the stats extra, ``spinstrike baselines`` trained a whole env's seeds, then died
    with an ImportError traceback; then it named the stats extra only, and a user who installed
    it learned next that it needs the train extra too. Now one error line names every extra
    missing, and nothing is written."""
    for module in hidden:
        monkeypatch.setitem(sys.modules, module, None)  # importing it raises ImportError
    assert main(["baselines", "--quick", "--envs", ENV, "--algos", "ppo"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: spinstrike baselines trains with stable-baselines3 ('train' "
                          "extra) and reports confidence intervals with rliable ('stats' "
                          f"extra); missing: {extras.split(',')}: pip install "
                          f'"spinstrike[{extras}]"') and len(err.splitlines()) == 1
    assert ("download.pytorch.org/whl/cpu" in err) == ("train" in extras)
    assert list(sandbox.iterdir()) == []


@pytest.mark.parametrize("module,argv,extra", [
    ("stable_baselines3", ["train", "--timesteps", "64", "--no-video"], "train"),
    ("mpmath", ["bench", "accuracy", "--quick", "--cases", "seed"], "bench"),
    # rendering's own ImportError was not a ModuleNotFoundError naming pygame: a traceback
    ("pygame", ["record", "--scene", "break", "--out", "b.gif", "--seconds", "0.1"], "render"),
    ("pygame", ["record", "--oracle", "--env", "SpinStrike/RodSpin-v0", "--episodes", "1",
                "--out", "o.mp4"], "render"),
])
def test_a_missing_optional_dependency_names_its_extra(monkeypatch, tmp_path, capsys, module,
                                                       argv, extra):
    """On a base install ``spinstrike train`` died in a ModuleNotFoundError traceback (and the
    accuracy benchmark needed mpmath, which no extra declared)."""
    from spinstrike.agents.cli import main

    monkeypatch.chdir(tmp_path)
    # the benchmark modules import mpmath at their top: forgotten, the next import meets it
    _uninstalled(monkeypatch, module, *(("spinstrike.benchmarks.cases",
                                         "spinstrike.benchmarks.accuracy")
                                        if module == "mpmath" else ()))
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f'pip install "spinstrike[{extra}]"' in err and "Traceback" not in err


def _uninstalled(monkeypatch, module: str, *importers: str) -> None:
    """Make ``import module`` raise ModuleNotFoundError, and forget ``importers`` (modules that
    imported it already) so the next import of them meets the missing module."""
    for name in [m for m in sys.modules if m == module or m.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)
    for name in importers:
        monkeypatch.delitem(sys.modules, name, raising=False)


def test_the_sb3_adapter_without_sb3_names_the_extra(monkeypatch):
    """``import spinstrike.envs.sb3`` on a base install was a bare ModuleNotFoundError."""
    import importlib

    _uninstalled(monkeypatch, "stable_baselines3", "spinstrike.envs.sb3")
    with pytest.raises(ModuleNotFoundError, match=r'pip install "spinstrike\[train\]"') as exc:
        importlib.import_module("spinstrike.envs.sb3")
    assert exc.value.name.split(".")[0] == "stable_baselines3"  # what the CLI maps to the extra


def test_record_every_frame_without_moviepy_names_the_extra(monkeypatch, tmp_path):
    """Gymnasium's own message said ``pip install "gymnasium[other]"``, which leaves pygame out."""
    import gymnasium as gym

    from spinstrike.envs.recording import RecordEveryFrame

    _uninstalled(monkeypatch, "moviepy", "gymnasium.utils.save_video")
    env = gym.make(ENV, render_mode="rgb_array_list")
    with pytest.raises(gym.error.DependencyNotInstalled, match=r"spinstrike\[render\]"):
        RecordEveryFrame(env, str(tmp_path / "videos"))
    env.close()


def test_rl_zoo3_values_read_as_rl_zoo3_reads_them(tmp_path):
    """``train_freq: [1, episode]`` (a list in YAML; rl-zoo3 makes it a tuple) and
    ``clip_range_vf: lin_0.2`` (one of rl-zoo3's schedule keys) were passed to SB3 as written
    and crashed there."""
    sac = load_agent_config("sac", ENV, _config(tmp_path, "sac.yml", {
        "n_timesteps": 100, "train_freq": [1, "episode"]}))
    assert sac.model_kwargs["train_freq"] == (1, "episode")
    ppo = load_agent_config("ppo", ENV, _config(tmp_path, "ppo.yml", {
        "n_timesteps": 100, "clip_range_vf": "lin_0.2"}))
    schedule = ppo.model_kwargs["clip_range_vf"]
    assert callable(schedule) and schedule(1.0) == pytest.approx(0.2)


def test_a_run_whose_env_changed_since_training_is_refused_on_evaluation(sandbox, capsys):
    """A run trained on one env, its config.yml then naming another (or a variant re-registered
    with other observations): ``evaluate`` failed deep in SB3's predict with an IndexError or a
    shape error. Now one line naming the run and the model's observation space."""
    assert main(["train", "--timesteps", "64", "--n-envs", "1", "--out", "run", "--no-eval",
                 "--no-video", "--no-progress"]) == 0
    config = sandbox / "run" / "config.yml"
    meta = yaml.safe_load(config.read_text())
    meta["env"] = "SpinStrike/PuckSpeed-v1"
    meta["hyperparameters"] = {"SpinStrike/PuckSpeed-v1": meta["hyperparameters"][ENV]}
    config.write_text(yaml.safe_dump(meta))
    capsys.readouterr()
    assert main(["evaluate", "run", "--episodes", "1", "--no-save"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    [line] = [x for x in err.splitlines() if "error:" in x]
    assert "run_dir: run's model does not take SpinStrike/PuckSpeed-v1's observations" in line


def test_a_folder_named_like_a_runs_work_folder_is_not_deleted(sandbox, capsys):
    """``train --out backup`` deleted a folder ``backup.partial`` of the user's (no run's:
    neither a run's record nor its command) without ``--force``; refused, and kept."""
    _text(sandbox, "backup.partial/data.txt", "precious")
    for force in ([], ["--force"]):
        assert main(["train", "--out", "backup", "--timesteps", "64", *force]) == 2
        line = capsys.readouterr().err.strip()
        assert line.startswith("error: out: backup.partial exists and holds no run"), line
        assert (sandbox / "backup.partial" / "data.txt").read_text() == "precious"


def test_force_does_not_replace_the_folder_you_are_in(sandbox, capsys, monkeypatch):
    """``train --force --out "$PWD"`` in a run directory deleted the working folder."""
    run = Path(_fake_run(sandbox, "done"))
    monkeypatch.chdir(run)
    for out in (".", str(run), str(sandbox)):
        before = _tree(sandbox)
        assert main(["train", "--force", "--out", out, "--timesteps", "64"]) == 2
        line = capsys.readouterr().err.strip()
        assert line.startswith("error: out:"), line
        assert _tree(sandbox) == before
    assert main(["train", "--force", "--out", str(run), "--timesteps", "64"]) == 2
    assert "holds the working folder; --force would delete the folder you are in" in \
        capsys.readouterr().err


def test_evaluating_a_run_that_is_still_partial_says_how_to_finish_it(sandbox, capsys):
    """``evaluate runs/x`` where only ``runs/x.partial`` (an interrupted run) exists said
    "has no model.zip or config.yml (not a run)"."""
    Path(_interrupted(sandbox)).rename(sandbox / "run.partial")
    for command in ("evaluate", "record"):
        assert main([command, "run"]) == 2
        line = capsys.readouterr().err.strip()
        assert line == ("error: run_dir: run does not exist, but run.partial does: an "
                        "interrupted run; `spinstrike train --resume --out run` finishes it"), line


@pytest.mark.parametrize("algo", ["td3", "sac"])
def test_a_model_of_another_algorithm_is_one_error_line(sandbox, capsys, algo):
    """A run whose model.zip is another algorithm's than its config.yml records (a PPO model
    under a TD3 record): an AttributeError or TypeError deep in SB3's load."""
    import gymnasium as gym
    from stable_baselines3 import PPO

    import spinstrike  # noqa: F401

    run = Path(_fake_run(sandbox, "mixed", yaml.safe_dump(
        {"algo": algo, "env": ENV, "seed": 0, "hyperparameters": {ENV: {"n_timesteps": 64}}})))
    PPO("MlpPolicy", gym.make(ENV), n_steps=64, batch_size=64).save(run / "model.zip")
    for command in ("evaluate", "record"):
        assert main([command, str(run)]) == 2
        line = capsys.readouterr().err.strip()
        assert line.startswith(f"error: model.zip: {run / 'model.zip'} could not be loaded as "
                               f"a {algo} model"), line


def test_train_without_the_train_extra_names_the_extra(tmp_path):
    """Installed without ``[train]``, ``spinstrike train`` was torch's traceback: ``--device``'s
    default was checked with ``import torch`` while the arguments were parsed, before the
    command could name the extra (found installing the wheel alone in a fresh venv)."""
    code = ("import sys; sys.modules['torch'] = None; from spinstrike.agents.cli import main; "
            "sys.exit(main(['train', '--algo', 'ppo', '--env', 'SpinStrike/RodSpin-v0', "
            "'--timesteps', '256', '--out', 'run']))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, timeout=600)
    assert out.returncode == 2, out.stderr
    assert "Traceback" not in out.stderr
    assert "comes with the 'train' extra: pip install \"spinstrike[train]\"" in out.stderr
    assert not (tmp_path / "run").exists() and not (tmp_path / "run.partial").exists()


@pytest.mark.parametrize("argv,missing", [
    (["record", "--scene", "break", "--seconds", "0.1"], "pygame"),
    # a folder --out names is not made either (W16: it was, then the error came)
    (["record", "--scene", "break", "--seconds", "0.1", "--out", "new/b.gif"], "PIL"),
    (["record", "--oracle", "--env", "SpinStrike/PuckSpeed-v1", "--episodes", "1"],
     "imageio_ffmpeg"),
])
def test_record_without_the_render_extra_says_so_before_compiling(tmp_path, argv, missing):
    """Installed without ``[render]`` (the wheel alone), ``spinstrike record --scene break``
    compiled the scene's kernels (up to a minute on a cold cache) and only then named the
    render extra. Now the error line comes first, on an empty kernel cache, and nothing is
    compiled or written."""
    code = (f"import sys; sys.modules[{missing!r}] = None; "
            "from spinstrike.agents.cli import main; "
            f"sys.exit(main({argv!r}))")
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(tmp_path / "cache"))
    (tmp_path / "work").mkdir()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path / "work", env=env, timeout=600)
    assert out.returncode == 2, out.stderr
    assert out.stderr == (f"error: spinstrike record needs {missing}, which comes with the "
                          "'render' extra: pip install \"spinstrike[render]\"\n")
    assert not list((tmp_path / "work").iterdir())
    assert not (tmp_path / "cache").exists() or not any((tmp_path / "cache").rglob("*.nbi"))


def test_train_checks_every_module_it_uses_before_training(monkeypatch, tmp_path, capsys):
    """The zoo extra brings SB3 and not the rest of the train extra: ``spinstrike train`` died
    in SB3's "tensorboard is not installed" assertion (a traceback, an empty runs/), and with
    tensorboard installed it trained the whole budget, then lost the run to the missing
    matplotlib of the learning-curve plot. Every missing module is named at once, before
    anything trains or is written."""
    from spinstrike.agents.cli import main

    monkeypatch.chdir(tmp_path)
    for module in ("tensorboard", "matplotlib", "moviepy"):
        _uninstalled(monkeypatch, module)
    assert main(["train", "--timesteps", "64", "--out", "run"]) == 2
    err = capsys.readouterr().err
    assert err == ("error: spinstrike train needs tensorboard, matplotlib, moviepy, which come "
                   "with the 'train' extra: pip install \"spinstrike[train]\"\n")
    assert list(tmp_path.iterdir()) == []


def test_a_bad_env_kwarg_in_a_hyperparameter_file_names_the_file(sandbox, capsys):
    """An argument the env refuses, from the file's entry: ``error: max_forse: unknown
    argument`` named neither the file nor its entry, as the file's other errors do."""
    path = sandbox / "hp.yml"
    shipped = load_agent_config("ppo", ENV).raw
    path.write_text(yaml.safe_dump({ENV: dict(shipped, env_kwargs={"max_forse": 3.0})}))
    assert main(["train", "--env", ENV, "--config", str(path), "--timesteps", "64",
                 "--out", str(sandbox / "run")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: hp.yml[{ENV}].env_kwargs.max_forse: unknown argument"), err
    # the same argument from the command line is the command line's
    assert main(["train", "--env", ENV, "--timesteps", "64", "--out", str(sandbox / "run"),
                 "--env-kwargs", "{max_forse: 3.0}"]) == 2
    assert capsys.readouterr().err.startswith("error: max_forse: unknown argument")
    assert not (sandbox / "run").exists()
