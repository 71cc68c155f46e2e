"""An RLlib run that stops before its budget, from the user's side (walk W26a F1-F3): its env
runners lost (it trained on no data and was booked as finished, exit 0), Ctrl-C or a
scheduler's SIGTERM (the run folder was deleted; SIGTERM aborted the driver) and ``spinstrike
train --resume --out RUN`` of an RLlib run (it said the run had no checkpoint). Marker ``rllib``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

ray = pytest.importorskip("ray")

pytestmark = pytest.mark.rllib

STRIKE = "SpinStrike/RodSpin-v0"
ENV = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")


def _train(*args: str) -> list[str]:
    return [sys.executable, "-m", "spinstrike.agents.cli", "train", *args]


def _rows(path: Path) -> list[list[str]]:
    return [line.split(",") for line in path.read_text().splitlines()[1:]]


def test_lost_env_runners_stop_the_run_short_of_its_budget_with_an_error(
        tmp_path, monkeypatch, capsys):
    """Both runners killed after the second iteration and not restarted (as Ray's memory
    monitor or a lost node leaves them): the run trained the rest of its iterations on no data,
    wrote a finished-looking run and exited 0. Now: exit 1, an error naming the steps trained
    of the budget and why, the ``.partial`` folder kept with its checkpoint and the stretch
    booked as interrupted; no run folder that reads as finished."""
    from spinstrike.agents import rllib_train
    from spinstrike.agents.cli import main

    if ray.is_initialized():
        ray.shutdown()
    monkeypatch.setattr(rllib_train, "STALL_ITERATIONS", 2, raising=False)
    monkeypatch.setattr(rllib_train, "STALL_SECONDS", 0.0, raising=False)
    original = rllib_train.ppo_config

    def kill_runners(algorithm, **kwargs):
        if algorithm.iteration == 2:
            algorithm.env_runner_group.foreach_env_runner(
                lambda runner: os._exit(1), local_env_runner=False)

    def ppo_config(*args, **kwargs):  # no restarts: the runners stay lost
        return original(*args, **kwargs).fault_tolerance(
            restart_failed_env_runners=True, max_num_env_runner_restarts=0).callbacks(
            on_train_result=kill_runners)

    monkeypatch.setattr(rllib_train, "ppo_config", ppo_config)
    monkeypatch.chdir(tmp_path)
    code = main(["train", "--backend", "rllib", "--env", STRIKE, "--num-env-runners", "2",
                 "--n-envs", "4", "--timesteps", "2560", "--no-video", "--eval-episodes", "2",
                 "--out", "run"])
    err = capsys.readouterr().err
    assert code == 1, err[-3000:]
    [line] = [x for x in err.splitlines() if x.startswith("error:")]
    assert "training stopped at 512 of the budget's 2560 steps" in line, line
    assert "sampled no env steps" in line and "0 of 2 env runners healthy" in line
    assert "spinstrike train --resume --out run" in line
    assert not (tmp_path / "run").exists()
    partial = tmp_path / "run.partial"
    assert (partial / "checkpoint" / "rllib_checkpoint.json").is_file()
    meta = yaml.safe_load((partial / "config.yml").read_text())
    assert meta["runs"][-1]["timesteps"] == 512 and meta["runs"][-1]["interrupted"]
    assert [int(r[1]) for r in _rows(partial / "progress.csv")] == [256, 512]
    assert not ray.is_initialized()


def _start(out: Path, runners: str):
    """``spinstrike train --backend rllib`` as a terminal starts it (its own process group,
    SIGINT at its default), 100 iterations asked; returns once 2 have been checkpointed (a row
    of progress.csv is written before its iteration's checkpoint: a signal between the two
    keeps the one before, ci38's failure when this waited for the rows)."""
    def reset():
        os.setsid()
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    cmd = _train("--backend", "rllib", "--env", STRIKE, "--num-env-runners", runners,
                 "--n-envs", "4", "--timesteps", "25600", "--eval-episodes", "2", "--no-video",
                 "--out", str(out))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=ENV, preexec_fn=reset)
    steps = Path(str(out) + ".partial") / "checkpoint" / "spinstrike_steps.json"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if json.loads(steps.read_text())["iteration"] >= 2:
                break
        except (OSError, ValueError, KeyError):  # not yet written, or between the renames
            pass
        time.sleep(0.2)
    assert proc.poll() is None, proc.communicate()[1][-3000:]
    return proc


@pytest.mark.parametrize("how", ["SIGTERM", "Ctrl-C"])
def test_an_interrupted_rllib_run_keeps_its_partial_folder_and_says_how_to_go_on(tmp_path, how):
    """SIGTERM aborted the driver (Ray's handler, exit -6) and Ctrl-C deleted the run folder;
    README promises ``--resume``. Now: exit 143 / 130, ``run.partial`` kept with an RLlib
    checkpoint at a logged iteration and the stretch booked as interrupted, and the line to go
    on."""
    out = tmp_path / "run"
    proc = _start(out, "1" if how == "SIGTERM" else "0")
    if how == "SIGTERM":
        proc.send_signal(signal.SIGTERM)
    else:
        os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == (143 if how == "SIGTERM" else 130), err[-3000:]
    assert f"continue with spinstrike train --resume --out {out}" in err
    assert "SIGTERM received" not in err and "Traceback" not in err
    partial = Path(str(out) + ".partial")
    assert (partial / "checkpoint" / "rllib_checkpoint.json").is_file()
    meta = yaml.safe_load((partial / "config.yml").read_text())
    [stretch] = meta["runs"]
    assert stretch["interrupted"] and 512 <= stretch["timesteps"] < 25600
    assert stretch["timesteps"] in [int(r[1]) for r in _rows(partial / "progress.csv")]


def test_resume_of_an_interrupted_rllib_run_trains_on_to_the_budget(tmp_path, capsys,
                                                                    monkeypatch):
    """``spinstrike train --resume --out RUN`` (no --backend: the record's) continues an RLlib
    run stopped by Ctrl-C (here in the third iteration's evaluation, after two checkpoints) to
    its budget (it said "has no checkpoint to resume from"): the rows logged after the
    checkpoint are done again, not twice, and config.yml books both stretches."""
    from spinstrike.agents import evaluate
    from spinstrike.agents.cli import main

    if ray.is_initialized():
        ray.shutdown()
    monkeypatch.chdir(tmp_path)
    original, calls = evaluate.run_episodes, []

    def ctrl_c_in_the_third(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(evaluate, "run_episodes", ctrl_c_in_the_third)
    args = ["--env", STRIKE, "--num-env-runners", "0", "--n-envs", "4", "--timesteps", "1280",
            "--no-video", "--eval-episodes", "2", "--out", "run"]
    assert main(["train", "--backend", "rllib", *args]) == 130
    assert "continue with spinstrike train --resume --out run" in capsys.readouterr().err
    monkeypatch.setattr(evaluate, "run_episodes", original)
    # a new run into the same --out, SB3's or RLlib's, keeps the interrupted one (an SB3 run
    # deleted its .partial, looking for SB3's checkpoints only: walk W26a)
    sb3 = ["--algo", "ppo", "--env", STRIKE, "--timesteps", "1280", "--out", "run"]
    for command in (sb3, ["--backend", "rllib", *args]):
        assert main(["train", *command]) == 2
        assert "run.partial holds an interrupted RLlib run (checkpoint at 512 steps); pass " \
               "--resume" in capsys.readouterr().err
        assert (tmp_path / "run.partial" / "checkpoint" / "rllib_checkpoint.json").is_file()
    assert main(["train", "--resume", "--out", "run"]) == 0, capsys.readouterr().err[-3000:]
    out = capsys.readouterr().out
    assert "run: run  (1280 steps" in out and "in 2 sessions" in out, out
    run = tmp_path / "run"
    assert not (tmp_path / "run.partial").exists()
    meta = yaml.safe_load((run / "config.yml").read_text())
    assert [(r["timesteps"], r.get("interrupted", False)) for r in meta["runs"]] == \
        [(512, True), (1280, False)]
    assert all("commit" in r for r in meta["runs"])
    import numba  # (walk W26a F8: the record left out the physics' compiler)

    assert meta["versions"]["numba"] == numba.__version__
    # what RLlib's PPO does not take is listed as such (walk W26a F10)
    assert meta["not_used"] == ["policy_kwargs.log_std_init"]
    rows = _rows(run / "progress.csv")
    assert [int(r[0]) for r in rows] == [1, 2, 3, 4, 5]
    assert [int(r[1]) for r in rows] == [256, 512, 768, 1024, 1280]
    assert (run / "summary.md").is_file()
    assert (run / "command.txt").read_text().splitlines()[-1] == \
        "spinstrike train --resume --out run"
    # its checkpoint folder given to evaluate is the run (walk W26a: a summary titled by the
    # env id alone was written inside checkpoint/)
    title = (run / "summary.md").read_text().splitlines()[0]
    assert main(["evaluate", "run/checkpoint", "--episodes", "2"]) == 0
    assert "note: run/checkpoint is the RLlib checkpoint of the run run" in capsys.readouterr().err
    assert not (run / "checkpoint" / "summary.md").exists()
    summary = (run / "summary.md").read_text()
    assert summary.startswith(title + "\n") and "Re-evaluated by `spinstrike evaluate`: 2 " \
        "episodes" in summary
    # resumed again with its budget trained: nothing to do; a contradiction is refused
    assert main(["train", "--resume", "--out", "run"]) == 0
    assert "has trained its budget (1280 steps): nothing to do" in capsys.readouterr().out
    assert main(["train", "--resume", "--out", "run", "--seed", "4"]) == 2
    assert "--seed 4 (recorded: 0)" in capsys.readouterr().err


def test_sb3_resume_of_an_rllib_run_names_the_backend(tmp_path):
    """``train(resume=True)`` (the SB3 backend) of an RLlib run said it had no checkpoint."""
    from spinstrike.agents.config import AgentConfigError
    from spinstrike.agents.train import train

    run = tmp_path / "run"
    (run / "checkpoint").mkdir(parents=True)
    (run / "config.yml").write_text(yaml.safe_dump(
        {"algo": "ppo", "backend": "rllib", "env": STRIKE, "seed": 0, "hyperparameters": {}}))
    with pytest.raises(AgentConfigError,
                       match="is an RLlib run .*`spinstrike train --resume --out "):
        train(None, None, out=run, resume=True)


def test_ctrl_c_while_ray_shuts_down_after_training_says_how_to_finish(tmp_path, capsys,
                                                                       monkeypatch):
    """Walk W26a F7: a Ctrl-C while Ray shut down after the run had trained its budget left the
    run without its summary and video, and nothing said so. It says the run is saved and which
    command writes what is missing; that command (``--resume`` of a run that trained its
    budget) writes the summary."""
    from spinstrike.agents.cli import main

    if ray.is_initialized():
        ray.shutdown()
    monkeypatch.chdir(tmp_path)
    real = ray.shutdown

    def interrupted(*args, **kwargs):
        real(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(ray, "shutdown", interrupted)
    args = ["--env", STRIKE, "--num-env-runners", "0", "--n-envs", "4", "--timesteps", "512",
            "--no-video", "--eval-episodes", "2", "--out", "run"]
    assert main(["train", "--backend", "rllib", *args]) == 130
    err = " ".join(capsys.readouterr().err.split())
    assert "interrupted after training: the run and its RLlib checkpoint are saved in run; " \
           "`spinstrike train --resume --out run` writes what is missing" in err, err
    monkeypatch.setattr(ray, "shutdown", real)
    assert not (tmp_path / "run" / "summary.md").exists()
    assert main(["train", "--resume", "--out", "run"]) == 0, capsys.readouterr().err[-2000:]
    assert (tmp_path / "run" / "summary.md").is_file()
