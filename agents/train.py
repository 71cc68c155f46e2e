"""Train SB3 baselines from rl-zoo3 hyperparameter files.

A run directory holds everything needed to reproduce and resume a run::

    runs/<name>/
        model.zip            final model            config.yml     resolved entry + metadata
        command.txt          the command lines      checkpoints/   periodic model (+ buffer)
        tb/                  TensorBoard logs       progress.csv   SB3's training log
        evaluations.npz      periodic evaluations   learning_curve.png
        summary.md/.json     final evaluation vs random and oracle      rollout.mp4

Training goes into ``<name>.partial`` and is renamed at the end, so an unfinished run never looks
complete and an existing run is never overwritten (unless ``force``). A run that fails with an
error leaves nothing behind; an interrupted one (Ctrl-C, or SIGTERM while it trains) keeps its
``.partial`` directory with its checkpoints, and ``resume`` continues it (or a finished run, to a
larger budget) from the newest checkpoint; interrupted before the first checkpoint, it has
nothing to resume and the same command starts over. Without ``resume``, an interrupted run with
a checkpoint is never deleted (unless ``force``).

A resumed run is the run its ``config.yml`` records (algorithm, env, env kwargs,
hyperparameters, seed, budget); only the budget (``timesteps``) may be changed, and the new one is
recorded. Its learning history goes on: the evaluations and ``progress.csv`` rows up to the
checkpoint are kept and the new ones appended, so ``learning_curve.png`` shows the whole run.
"""

from __future__ import annotations

import contextlib
import csv
import os
import pickle
import re
import shlex
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from spinstrike.agents.config import (
    AgentConfigError,
    RunConfig,
    algo_class,
    env_file_name,
    is_run_record,
    load_agent_config,
    recorded_agent_config,
    run_record,
    short_value,
)

__all__ = ["TrainResult", "finish_run", "plot_learning_curve", "train"]

OFF_POLICY = ("sac", "td3")


class TrainResult(dict):
    """``run_dir``, ``env``, ``timesteps``, ``wall_time`` (this session's), ``sessions`` and
    ``total_wall_time`` (every stretch of training, interrupted ones too) and (if evaluated)
    ``evaluations``; ``complete``, for a ``resume`` of a run that had trained its budget (it
    trained nothing): what it wrote of its finish (``"evaluate"``, ``"video"``), if anything."""


def _versions() -> dict[str, str]:
    import gymnasium
    import numba
    import stable_baselines3
    import torch

    versions = {"python": sys.version.split()[0], "numpy": np.__version__,
                "numba": numba.__version__, "gymnasium": gymnasium.__version__,
                "stable_baselines3": stable_baselines3.__version__, "torch": torch.__version__}
    from spinstrike.agents.config import code_version

    return {**code_version(), **{k: str(v) for k, v in versions.items()}}


def _make_env(cfg: RunConfig, seed: int, n_envs: int):
    from spinstrike.envs.sb3 import make_sb3_vec_env

    env = make_sb3_vec_env(cfg.env_id, n_envs=n_envs, seed=seed, env_kwargs=cfg.env_kwargs)
    return _normalized(env, cfg)


def _normalized(env, cfg: RunConfig, evaluation: bool = False):
    """``env`` in the ``VecNormalize`` of the config's ``normalize`` (its arguments, e.g.
    ``clip_obs``, with the entry's gamma), if any; for ``evaluation`` (the learning curve's
    env, as rl-zoo3's) the same observation pipeline with its statistics frozen and rewards
    left as they are."""
    if not cfg.normalize:
        return env
    from stable_baselines3.common.vec_env import VecNormalize

    kwargs = dict(cfg.normalize) if isinstance(cfg.normalize, dict) else {}
    if evaluation:
        kwargs.update(training=False, norm_reward=False)
    return VecNormalize(env, gamma=cfg.model_kwargs.get("gamma", 0.99), **kwargs)


def _model_kwargs(cfg: RunConfig, env) -> dict[str, Any]:
    """The algorithm's arguments: the entry's, with rl-zoo3's ``noise_type``/``noise_std``
    (both given, checked by the config) built into ``action_noise``."""
    kwargs = dict(cfg.model_kwargs)
    if "noise_type" in kwargs:
        from stable_baselines3.common.noise import (
            NormalActionNoise,
            OrnsteinUhlenbeckActionNoise,
        )

        kind = {"normal": NormalActionNoise,
                "ornstein-uhlenbeck": OrnsteinUhlenbeckActionNoise}[kwargs.pop("noise_type")]
        std = float(kwargs.pop("noise_std"))
        n = env.action_space.shape[0]
        kwargs["action_noise"] = kind(np.zeros(n), std * np.ones(n))
    return kwargs


def default_run_dir(algo: str, env_id: str, seed: int) -> Path:
    """``runs/<algo>-<env>-s<seed>`` (``algo`` ``ppo-rllib`` for the RLlib backend's): where a
    run goes without ``out`` (a variant's name keeps its namespace, :func:`env_file_name`:
    ``MyLab/RodSpin-v0`` trained into the shipped ``RodSpin-v0``'s folder, which ``--force``
    would have replaced)."""
    return Path("runs") / f"{algo}-{env_file_name(env_id)}-s{seed}"


def _checkpoint_steps(ckpt: Path) -> int:
    return int(re.findall(r"_(\d+)_steps", ckpt.name)[0])


def _checkpoint_file(folder: Path, steps: int | str, kind: str = "") -> Path:
    """A checkpoint's file in ``folder``, SB3's names: the model ``model_<steps>_steps.zip``
    (``kind`` ""), beside it ``model_vecnormalize_...pkl``, ``model_replay_buffer_...pkl`` and
    ``model_env_random_...pkl`` (the training env's random streams; ``steps`` "*": their glob
    pattern)."""
    if not kind:
        return folder / f"model_{steps}_steps.zip"
    return folder / f"model_{kind}_{steps}_steps.pkl"


def _next_mark(steps: int, every: int) -> int:
    """The first multiple of ``every`` after ``steps`` (checkpoints' and evaluations' grid)."""
    return (steps // every + 1) * every


def _latest_checkpoint(run_dir: Path) -> Path | None:
    folder = run_dir / "checkpoints"
    ckpts = sorted(folder.glob(_checkpoint_file(folder, "*").name), key=_checkpoint_steps)
    return ckpts[-1] if ckpts else None


#: how a run ends (``finish``), each with the command line's flag for it
FINISH_FLAGS = {"evaluate": "--no-eval", "eval_episodes": "--eval-episodes",
                "video": "--no-video"}


def _recorded_run(work: Path, given: dict[str, Any], config, timesteps,
                  finish: dict[str, Any]) -> tuple[str, RunConfig, int, dict]:
    """The run as ``work/config.yml`` records it: ``(algo, cfg, seed, finish)``, with the budget
    set to ``timesteps`` if given (``finish``: how the first command asked the run to end).
    ``given`` maps each command-line flag to its value, ``finish`` each key of ``FINISH`` (None:
    left out); a value that contradicts the record is refused, all of them in one message (a
    finish of its own left the files of the record's, a video of the model before, in place)."""
    meta = yaml.safe_load((work / "config.yml").read_text())
    try:
        algo, env_id, seed = meta["algo"], meta["env"], meta["seed"]
        entry = meta["hyperparameters"][env_id]
    except (KeyError, TypeError):
        raise AgentConfigError(f"resume: {work / 'config.yml'} does not record the run's algo, "
                               "env, seed and hyperparameters") from None
    cfg = recorded_agent_config(algo, env_id, entry, meta.get("source", ""))
    recorded = {"--algo": algo, "--env": env_id, "--seed": seed, "--n-envs": cfg.n_envs,
                "--imitate": (meta.get("imitation") or {}).get("teacher", "none")}
    wrong = [f"{flag} {given[flag]} (recorded: {value})" for flag, value in recorded.items()
             if given.get(flag) is not None and given[flag] != value]
    ends = {**FINISH, **(meta.get("finish") or {})}
    wrong += [f"{FINISH_FLAGS[key]} (recorded: {key} {ends[key]})" for key, value in
              finish.items() if value is not None and value != ends[key]]
    env_kwargs = dict(given.get("--env-kwargs") or {})
    if "scene" in env_kwargs:  # recorded as read (see train)
        from spinstrike.envs.config import resolve_scene

        env_kwargs["scene"] = resolve_scene(env_kwargs["scene"])
    if {**cfg.env_kwargs, **env_kwargs} != cfg.env_kwargs:
        wrong.append(f"--env-kwargs {env_kwargs} (recorded: {cfg.env_kwargs})")
    if config is not None and not wrong and not _same_entry(cfg, config):
        wrong.append(f"--config {config} (its {env_id} entry is not the recorded one)")
    if wrong:
        raise AgentConfigError(f"resume: {work} records {algo} on {env_id} (seed {seed}); "
                               f"the command line contradicts it: {'; '.join(wrong)}. Leave "
                               "them out: --resume --out RUN continues the run as recorded "
                               "(only --timesteps may change, to set a new budget)")
    _check_recorded_code(work, env_id, meta.get("code"))
    from spinstrike.agents.config import version_changes

    versions = version_changes(meta.get("versions"))
    if versions:  # (the session's commit is booked in runs:, W24b F5)
        print(f"note: resume: {work} was trained with other versions than these: "
              f"{'; '.join(versions)}", file=sys.stderr)
    if timesteps is not None:
        if isinstance(timesteps, bool) or not isinstance(timesteps, int) or timesteps < 1:
            raise AgentConfigError(f"timesteps: must be an integer >= 1 (got {timesteps!r})")
        cfg.n_timesteps = cfg.raw["n_timesteps"] = timesteps
    return algo, cfg, seed, meta.get("finish") or {}


def _check_recorded_code(work: Path, env_id: str, recorded: dict | None) -> None:
    """Refuse to resume a variant run whose code of the user's (``mylab.py``, the modules of
    theirs it imports) changed since it trained (``envs.code_check``): it trained on the new
    reward with no word and kept the old digest in ``config.yml``, which then said the whole
    run used code it did not (walk W24b F1). A digest that cannot be compared (recorded with an
    older scheme, or of a source not readable) is said, and the run goes on."""
    from spinstrike.envs import code_check

    changed, unchecked = code_check(env_id, recorded)
    if changed:
        raise AgentConfigError(
            f"resume: the code of {', '.join(changed)} ({env_id}'s classes and the modules of "
            f"yours they import) changed since {work} trained (its config.yml records a digest "
            f"of the code it trained on), so it would go on training on other code than it "
            f"records. Put the code back as it was to continue the run, or start a new run from "
            f"its record with the code as it is now: spinstrike train --config "
            f"{work / 'config.yml'} --out NEW_RUN")
    if unchecked:
        print(f"note: resume: cannot check the code of "
              f"{'; '.join(f'{m} ({why})' for m, why in unchecked.items())} against what {work} "
              f"trained on: the code as it is now trains", file=sys.stderr)


def recorded_budget(work: Path, meta: dict | None = None) -> int | None:
    """The budget (``n_timesteps``) ``work/config.yml`` records (``meta``: that file, read
    already), or None."""
    if meta is None:
        meta = run_record(work / "config.yml")
    try:
        return int(meta["hyperparameters"][meta["env"]]["n_timesteps"])
    except (KeyError, TypeError, ValueError):
        return None


def _same_entry(cfg: RunConfig, config) -> bool:
    """Whether hyperparameter file ``config`` holds the entry ``cfg`` was built from (its
    budget, ``n_envs`` and env kwargs aside: those are compared on their own)."""
    try:
        other = load_agent_config(cfg.algo, cfg.env_id, config)
    except AgentConfigError:
        return False

    def strip(raw: dict) -> dict:
        return {k: v for k, v in raw.items() if k not in ("n_timesteps", "n_envs", "env_kwargs")}

    return strip(other.raw) == strip(cfg.raw) and \
        {**cfg.env_kwargs, **other.env_kwargs} == cfg.env_kwargs


def _earlier_evaluations(work: Path, upto: int) -> dict[str, list] | None:
    """The periodic evaluations a resumed run made up to its checkpoint (``upto`` steps)."""
    path = work / "evaluations.npz"
    if not path.exists():
        return None
    with np.load(path) as data:
        keep = data["timesteps"] <= upto
        return {key: data[key][keep].tolist() for key in data.files}


def _csv_output(work: Path, upto: int | None):
    """SB3's ``progress.csv`` writer; resuming (``upto``: the checkpoint's steps), it starts
    with the earlier rows up to the checkpoint (SB3's own opens the file with mode ``w``)."""
    from stable_baselines3.common.logger import CSVOutputFormat

    path = work / "progress.csv"
    rows: list[list[str]] = []
    if upto is not None and path.exists():
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
    out = CSVOutputFormat(str(path))
    if rows:
        header, body = rows[0], rows[1:]
        col = header.index("time/total_timesteps") if "time/total_timesteps" in header else None
        keep = [row for row in body
                if col is None or col >= len(row) or not row[col] or float(row[col]) <= upto]
        csv.writer(out.file, lineterminator="\n").writerows([header, *keep])
        out.file.flush()
        out.keys = list(header)  # SB3 widens the header itself when new keys come
    return out


def plot_learning_curve(run_dir: Path, title: str) -> Path | None:
    """``learning_curve.png`` from the periodic evaluations (mean +/- std)."""
    path = run_dir / "evaluations.npz"
    if not path.exists():
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = np.load(path)
    steps, results = data["timesteps"], data["results"]
    mean, std = results.mean(1), results.std(1)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(steps, mean, label="agent (deterministic)")
    ax.fill_between(steps, mean - std, mean + std, alpha=0.25)
    ax.set_xlabel("timesteps")
    ax.set_ylabel("episode return")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    out = run_dir / "learning_curve.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def resume_folder(run_dir: Path) -> Path:
    """The folder a resume of ``run_dir`` continues: the run itself, or, if it does not exist
    (interrupted before it finished), the ``.partial`` beside it."""
    if run_dir.exists() or not run_dir.name:
        return run_dir
    return run_dir.with_name(run_dir.name + ".partial")


def _work_dir(run_dir: Path, resume: bool, force: bool) -> Path:
    """Where this invocation writes: the run itself (resume) or a fresh ``.partial`` beside it.

    ``force`` replaces a run directory only (one with a ``config.yml``) or an empty one: it
    deleted whatever ``--out`` named (a folder of runs, the home folder), and a file there
    failed only after training, taking the trained model with it."""
    if not run_dir.name or run_dir.name == "..":  # (with_name failed with a ValueError)
        raise AgentConfigError(f"out: {str(run_dir)!r} names a folder by its place, not a run "
                               "directory; give one, e.g. runs/my-run")
    partial = run_dir.with_name(run_dir.name + ".partial")
    for path in (run_dir, partial):
        if path.exists() and not path.is_dir():
            raise AgentConfigError(f"out: {path} is a file, not a run directory; choose "
                                   "another --out")
    if not resume and force and run_dir.exists() and any(run_dir.iterdir()) \
            and not _is_run(run_dir):
        raise AgentConfigError(f"out: {run_dir} is not a run directory (no config.yml recording "
                               "a run's algo and env) and not empty; --force replaces a run "
                               "only: choose another --out")
    here = Path.cwd().resolve()
    if not resume and force and run_dir.exists() and (
            run_dir.resolve() == here or run_dir.resolve() in here.parents):
        raise AgentConfigError(f"out: {run_dir} holds the working folder; --force would delete "
                               "the folder you are in: choose another --out")
    if resume:
        work = resume_folder(run_dir)
        if not (work / "config.yml").exists():
            raise AgentConfigError(f"resume: {run_dir} is not a run directory")
        if _latest_checkpoint(work) is None:
            raise AgentConfigError(f"resume: {run_dir} has no checkpoint to resume from")
        return work
    if run_dir.exists() and not force:
        if any(run_dir.iterdir()) and not _is_run(run_dir):  # --force would refuse it too
            raise AgentConfigError(f"out: {run_dir} exists and is not a run directory (no "
                                   "config.yml recording a run's algo and env): choose "
                                   "another --out")
        raise AgentConfigError(f"out: {run_dir} exists; pass --force to replace it or "
                               "--resume to continue it")
    if not force:
        _keep_interrupted(partial, run_dir)
    if partial.exists() and any(partial.iterdir()) and not _is_run(partial) \
            and not (partial / "command.txt").is_file():
        # a run's own .partial holds its command (written first) or its record; any other
        # folder of that name is not ours to delete
        raise AgentConfigError(f"out: {partial} exists and holds no run (the folder a run "
                               "trains in before it is renamed); move it or choose another --out")
    if partial.exists():
        shutil.rmtree(partial)
    return partial


def _keep_interrupted(partial: Path, run_dir: Path) -> None:
    """Refuse a new run into ``run_dir`` whose ``.partial`` holds an interrupted run, SB3's or
    RLlib's (its checkpoints are not ours to drop; an SB3 run deleted an RLlib one's, looking
    for SB3's checkpoints only: walk W26a)."""
    if not partial.is_dir():
        return
    from spinstrike.agents import rllib_train

    ckpt = _latest_checkpoint(partial)
    if ckpt is not None:
        what, steps = "an interrupted run", _checkpoint_steps(ckpt)
    elif rllib_train._checkpoint(partial) is not None:
        what, steps = "an interrupted RLlib run", rllib_train._checkpoint_steps(partial)
    else:
        return
    raise AgentConfigError(f"out: {partial} holds {what} (checkpoint at {steps} steps); pass "
                           f"--resume to continue it (`spinstrike train --resume --out "
                           f"{run_dir}`) or --force to start over")


def _is_run(folder: Path) -> bool:
    """Whether ``folder`` is a run directory: its ``config.yml`` is a run's record
    (:func:`~spinstrike.agents.config.is_run_record`) naming its env (a project folder with a
    ``config.yml`` of its own was replaced by ``--force``)."""
    try:
        meta = yaml.safe_load((folder / "config.yml").read_text())
    except (OSError, yaml.YAMLError):
        return False
    return is_run_record(meta) and "env" in meta


def _resume_model(cls, algo: str, cfg: RunConfig, work: Path, env, device: str):
    """Load the newest checkpoint (with its replay buffer and normalisation statistics)."""
    ckpt = _latest_checkpoint(work)
    steps = _checkpoint_steps(ckpt)
    model = cls.load(ckpt, env=env, device=device)
    if cfg.normalize:
        from stable_baselines3.common.vec_env import VecNormalize

        # without them the policy would see unnormalised observations
        stats = _checkpoint_file(ckpt.parent, steps, "vecnormalize")
        if not stats.exists():
            raise AgentConfigError(f"resume: {ckpt} has no normalisation statistics "
                                   f"({stats.name}) although the run normalizes")
        model.set_env(VecNormalize.load(str(stats), env.venv))
    _restore_env_random(model, _checkpoint_file(ckpt.parent, steps, "env_random"))
    buf = _checkpoint_file(ckpt.parent, steps, "replay_buffer")
    if algo in OFF_POLICY:
        if not buf.exists():  # an empty buffer would silently restart learning_starts' warm-up
            raise AgentConfigError(f"resume: {ckpt} has no replay buffer ({buf.name})")
        model.load_replay_buffer(buf)
    return model


def _native_env(model):
    """The native vector env under the model's SB3 env (``VecNormalize`` and the adapter)."""
    return model.get_env().unwrapped.venv.unwrapped


def _save_env_random(model, path: Path) -> None:
    """The training env's random streams, beside a checkpoint (see :func:`_restore_env_random`)."""
    state = _native_env(model).get_random_state()
    path.write_bytes(pickle.dumps(state))


def _restore_env_random(model, path: Path) -> None:
    """Put the training env's random streams back as the checkpoint left them, so the resumed
    stretch draws the tasks that come next. Rebuilt from the run's seed, the env replayed the
    run's first episodes (a resumed SAC run held each early transition twice in its buffer).
    A checkpoint written before the streams were kept has none: the episodes restart from the
    seed, as they did, and a warning says so."""
    if not path.exists():
        print(f"warning: resume: {path.parent} has no {path.name} (a checkpoint written before "
              f"the env's random state was kept): the resumed stretch's episodes start again "
              f"from the run's seed", file=sys.stderr)
        return
    _native_env(model).set_random_state(pickle.loads(path.read_bytes()))
    # the SB3 adapter's pending seed would reseed the streams at the reset
    model.get_env().unwrapped._reset_seeds()


#: seed of the learning curves' evaluation episodes (the same for every run)
EVAL_SEED = 10_000


def _atomic(path: Path, write) -> None:
    """``write(tmp)`` then rename ``tmp`` to ``path``: readers see the whole file or none."""
    tmp = path.with_name(path.name + ".tmp")  # a suffix SB3 keeps (it adds .zip to none)
    write(tmp)
    os.replace(tmp, path)


def book_resume(work: Path, cfg: RunConfig, command: str | None) -> None:
    """A resumed run's record (either backend's): its hyperparameters as resolved now (the
    budget, if ``--timesteps`` changed it) in ``config.yml``, and the command added to
    ``command.txt`` (the commands that made the run, in order)."""
    meta = yaml.safe_load((work / "config.yml").read_text())
    meta["hyperparameters"] = cfg.as_yaml_dict()
    write_yaml(work / "config.yml", meta)
    with (work / "command.txt").open("a") as f:
        f.write((command or shlex.join(sys.argv)) + "\n")


def write_yaml(path: Path, data: dict) -> None:
    """``data`` as YAML in ``path``, written whole or not at all (a signal between the open,
    which empties the file, and the write left an empty config.yml)."""
    _atomic(path, lambda tmp: tmp.write_text(yaml.safe_dump(data, sort_keys=False)))


def _checkpoint_callback(every: int, folder: Path, on_policy: bool, normalize: bool):
    """A checkpoint each ``every`` steps, and one at the end: ``model_<steps>_steps.zip`` (SB3's
    names), with the VecNormalize statistics; for off-policy algorithms the replay buffer, the
    newest only.

    SB3's ``CheckpointCallback`` saves on the step that completes each ``save_freq`` calls,
    before that step's transition is stored and, for PPO, inside a rollout whose update has not
    happened: a resumed PPO run redid up to a rollout and made one update fewer, and a resumed
    SAC run lacked a transition per resume. Here a checkpoint is saved where the algorithm's
    loop starts a rollout (for SAC and TD3 every ``train_freq`` steps), the first at or after
    each mark: every transition stored and every update made, so a resume goes on with nothing
    lost or repeated. Only the newest replay buffer is kept (the whole buffer, ~32 MB for 300k
    transitions of a control env; every checkpoint kept one, 325 MB a run): a resume reads
    only that one."""
    from stable_baselines3.common.callbacks import BaseCallback

    class _Checkpoints(BaseCallback):
        def _init_callback(self) -> None:
            folder.mkdir(parents=True, exist_ok=True)
            self._saved = self.model.num_timesteps
            self._next = _next_mark(self._saved, every)

        def _save(self) -> None:
            steps = self._saved = self.model.num_timesteps
            self._next = _next_mark(steps, every)
            older = list(folder.glob(_checkpoint_file(folder, "*", "replay_buffer").name))
            # Each file is written under a temporary name and renamed: a kill (Ctrl-C, a
            # scheduler's SIGTERM) while it is written leaves no truncated file under the real
            # name, which --resume would fail to load. The model last: a checkpoint is found by
            # its .zip, whose companions then exist; the older buffers go after it (a kill in
            # between leaves one buffer more, not one fewer).
            if not on_policy:
                _atomic(_checkpoint_file(folder, steps, "replay_buffer"),
                        self.model.save_replay_buffer)
            if normalize:
                _atomic(_checkpoint_file(folder, steps, "vecnormalize"),
                        lambda tmp: self.model.get_vec_normalize_env().save(str(tmp)))
            _atomic(_checkpoint_file(folder, steps, "env_random"),
                    lambda tmp: _save_env_random(self.model, tmp))
            _atomic(_checkpoint_file(folder, steps), self.model.save)
            for path in older:
                path.unlink(missing_ok=True)

        def _on_rollout_start(self) -> None:  # after the previous rollout's update
            if self.model.num_timesteps >= self._next:
                self._save()

        def _on_step(self) -> bool:
            return True

        def _on_training_end(self) -> None:  # a finished run can be extended by --resume
            if self.model.num_timesteps > self._saved:
                self._save()

    return _Checkpoints()


def _callbacks(algo: str, cfg: RunConfig, work: Path, seed: int, freq: int, episodes: int,
               history: dict[str, list] | None):
    from stable_baselines3.common.callbacks import CallbackList, EvalCallback
    from stable_baselines3.common.preprocessing import is_image_space
    from stable_baselines3.common.vec_env import VecTransposeImage

    # the interval in steps: a multiple of n_envs, the grid of an uninterrupted SB3 run
    every = max(freq // cfg.n_envs, 1) * cfg.n_envs

    class _FixedEpisodesEval(EvalCallback):
        """SB3's evaluation, reseeded before each so every point sees the same episodes, on
        the grid of ``every`` steps counted from the start of the run (SB3 counts calls from
        the start of ``learn``: a resumed run's points fell off the grid and its first one
        repeated the checkpoint's), and one at the end.

        Each evaluates the policy trained on the steps its point is labelled with: it runs
        where the algorithm's loop starts a rollout (after the update on the steps so far),
        the first at or after each mark, as the checkpoints are saved, and at the end of
        training. SB3's runs on the step that completes the mark, inside PPO's rollout, before
        its update: every point was the previous rollout's policy, and the curve's last point
        was not the model the run saved (W17: 0.313 where the final model scored 0.483)."""

        def _init_callback(self) -> None:
            super()._init_callback()
            # evaluated up to here: the run's start, or a resumed run's last point (one a stop
            # cut short, right after its checkpoint, is made again at the checkpoint's step)
            done = self.evaluations_timesteps
            self._done = int(done[-1]) if len(done) else self.model.num_timesteps
            self._next = _next_mark(self._done, every)

        def _on_step(self) -> bool:
            return True

        def _evaluate(self) -> None:
            self.num_timesteps = self._done = self.model.num_timesteps
            self._next = _next_mark(self._done, every)
            self.eval_env.seed(EVAL_SEED)
            # SB3 writes evaluations.npz in place: a Ctrl-C or a scheduler's SIGTERM during
            # the write (it comes right after a checkpoint) left a broken file, and --resume
            # failed reading it. Written beside it, then moved over it
            final = self.log_path  # (work/evaluations: SB3 adds .npz)
            self.log_path = final + ".writing"
            try:
                super()._on_step()  # eval_freq 1: SB3's evaluation, every time it is called
            finally:
                self.log_path = final
            written = Path(final + ".writing.npz")
            if written.exists():
                os.replace(written, final + ".npz")

        def _on_rollout_start(self) -> None:  # after the previous rollout's update
            if self.model.num_timesteps >= self._next:
                self._evaluate()

        def _on_training_end(self) -> None:  # the final model's point
            if self.model.num_timesteps > self._done:
                self._evaluate()

    from spinstrike.envs.sb3 import make_sb3_vec_env

    # the same episodes at every evaluation and for every seed and algorithm (reseeded above)
    eval_env = make_sb3_vec_env(cfg.env_id, n_envs=1, seed=EVAL_SEED, env_kwargs=cfg.env_kwargs)
    # the training env's normalisation (norm_obs, clip_obs, ...: SB3's EvalCallback syncs only
    # the running statistics), frozen
    eval_env = _normalized(eval_env, cfg, evaluation=True)
    if is_image_space(eval_env.observation_space):  # outermost, as SB3 wraps the training env
        eval_env = VecTransposeImage(eval_env)
    evals = _FixedEpisodesEval(eval_env, n_eval_episodes=episodes, eval_freq=1,
                               log_path=str(work), best_model_save_path=None,
                               deterministic=True, verbose=0)
    if history:  # a resumed run: its evaluations so far, which the next save writes out again
        evals.evaluations_timesteps = history["timesteps"]
        evals.evaluations_results = history["results"]
        evals.evaluations_length = history["ep_lengths"]
        evals.evaluations_successes = history.get("successes", [])
        if history["results"]:
            evals.best_mean_reward = float(max(np.mean(r) for r in history["results"]))
    return eval_env, CallbackList([
        _checkpoint_callback(every, work / "checkpoints", algo not in OFF_POLICY,
                             bool(cfg.normalize)),
        evals,
    ])


class _StopOnSignal:
    """Ctrl-C and SIGTERM while SB3 trains end ``model.learn`` at the env step under way (after
    the update or evaluation under way), and are raised after it (``KeyboardInterrupt``;
    ``SystemExit(143)``), not inside it.

    Raised inside it, at any bytecode, the exception could land in TensorBoard's event writer
    between its queue's bookkeeping steps; closing the logger then waited for the writer's
    thread (a fresh-venv run: the child silent 60 s after the signal, its main thread in
    ``EventFileWriter.stop`` joining the writer, which was waiting in its queue's ``get``; a CI
    run's SIGTERM test hung alike before the stacks were printed). A second signal is raised
    at once. Only in the main thread (where signal handlers run)."""

    def __init__(self) -> None:
        from stable_baselines3.common.callbacks import BaseCallback

        noted: list[int] = []
        self.noted = noted

        class Callback(BaseCallback):
            def _on_step(self) -> bool:
                return not noted

        self.callback = Callback()

    @staticmethod
    def _raise(signum: int):
        import signal

        raise KeyboardInterrupt if signum == signal.SIGINT else SystemExit(128 + signum)

    @contextlib.contextmanager
    def noting_signals(self):
        """Within: the first SIGINT or SIGTERM noted, a second raised; a signal the process
        ignores stays ignored (``imitate.handling``)."""
        import signal

        from spinstrike.agents.imitate import handling

        def note(signum, frame):
            if self.noted:  # the second: at once
                self._raise(signum)
            self.noted.append(signum)

        with handling((signal.SIGINT, signal.SIGTERM), note):
            yield

    def raise_noted(self) -> None:
        """After the logger is closed: the signal that stopped training, as its default."""
        if self.noted:
            self._raise(self.noted[0])


def _learn(algo, cfg: RunConfig, work: Path, *, seed, device, resume, progress, eval_freq,
           eval_episodes_during, command, torch_threads, imitate=None,
           finish=None) -> tuple[Any, float]:
    """Build (or resume) the model and train it to the budget; save it into ``work``."""
    from spinstrike.envs.warm import warm_up

    # compile the env's kernels on the other core while PyTorch and SB3 import
    warm = warm_up(cfg.env_id, cfg.n_envs, cfg.env_kwargs)
    import torch
    from stable_baselines3.common.logger import Logger, make_output_format

    if torch_threads:
        torch.set_num_threads(torch_threads)

    cls = algo_class(algo)
    warm.wait()
    # everything is validated: build the env before touching the disk, so a bad env kwarg
    # (raised by the env's own validation) leaves nothing behind either
    env = _make_env(cfg, seed, cfg.n_envs)
    work.mkdir(parents=True, exist_ok=True)
    if resume:
        model = _resume_model(cls, algo, cfg, work, env, device)
        book_resume(work, cfg, command)
    else:
        try:
            model = cls(cfg.policy, env, seed=seed, device=device, verbose=0,
                        **_model_kwargs(cfg, env))
        except (TypeError, ValueError, AssertionError) as exc:
            # keys SB3 takes through to torch or a buffer (policy_kwargs, *_kwargs) are checked
            # there: its message, naming the file, and no traceback
            raise AgentConfigError(f"hyperparameters ({cfg.source}, {cfg.env_id}): "
                                   f"stable-baselines3's {cls.__name__} refused them: "
                                   f"{type(exc).__name__}: {exc}") from None
        meta = {"algo": algo, "env": cfg.env_id, "seed": seed, "source": cfg.source,
                "versions": _versions(), "torch_threads": torch.get_num_threads(),
                "hyperparameters": cfg.as_yaml_dict(), "finish": finish,
                **_registered(cfg.env_id)}
        (work / "command.txt").write_text((command or shlex.join(sys.argv)) + "\n")
        if imitate:
            from spinstrike.agents.imitate import dagger

            done = dagger(model, cfg.env_id, seed=seed, env_kwargs=cfg.env_kwargs,
                          log=work / "imitation.csv", progress=progress, **imitate)
            meta["imitation"] = {**imitate, "wall_time_s": round(done.wall_time, 1),
                                 "states": done.rounds[-1]["states"],
                                 "last_return": done.rounds[-1]["return_mean"],
                                 "log_std": [round(x, 4) for x in done.log_std]}
        write_yaml(work / "config.yml", meta)
    upto = model.num_timesteps if resume else None  # the checkpoint's: history after it goes
    model.set_logger(Logger(str(work), [_csv_output(work, upto),
                                        make_output_format("tensorboard", str(work / "tb"))]))
    freq = eval_freq or max(cfg.n_timesteps // 10, 1)
    if algo not in OFF_POLICY and not eval_freq:
        # PPO's policy changes once a rollout: at least half a rollout apart, no policy is
        # evaluated more than twice (a 64-step smoke run of a control env, one rollout of 512
        # steps, evaluated the same policy 85 times: 50 s)
        freq = max(freq, int(cfg.model_kwargs.get("n_steps", 2048)) * cfg.n_envs // 2)
    history = _earlier_evaluations(work, upto) if resume else None
    eval_env, callbacks = _callbacks(algo, cfg, work, seed, freq, eval_episodes_during, history)
    start = time.time()
    remaining = cfg.n_timesteps - (model.num_timesteps if resume else 0)
    from stable_baselines3.common.callbacks import ProgressBarCallback

    # our own bar, closed on the way out: SB3's, left open by Ctrl-C, failed at exit
    bar = ProgressBarCallback() if progress and remaining > 0 else None
    stop = _StopOnSignal()
    try:
        if remaining > 0:
            with stop.noting_signals():
                model.learn(remaining, callback=[callbacks, stop.callback, bar] if bar else
                            [callbacks, stop.callback], reset_num_timesteps=not resume)
    except ValueError as exc:
        # torch's distributions refuse a NaN or infinite parameter: the updates diverged (a
        # learning rate of 1e30 ended in a hundred-line traceback naming a Normal's scale)
        if "invalid values" not in str(exc) and "nan" not in str(exc).lower():
            raise
        raise AgentConfigError(f"training diverged by step {model.num_timesteps}: the "
                               f"policy's parameters are no longer finite ({str(exc)[:80]}...); "
                               f"lower the learning_rate ({cfg.source}, {cfg.env_id})") from None
    finally:
        if getattr(bar, "pbar", None) is not None:
            bar.pbar.close()
        # progress.csv and the TensorBoard events, interrupted or not (SB3 leaves its logger's
        # files to the garbage collector: a ResourceWarning at exit)
        model.logger.close()
    stop.raise_noted()
    wall = time.time() - start
    model.save(work / "model.zip")
    if cfg.normalize:
        model.get_vec_normalize_env().save(str(work / "vecnormalize.pkl"))
    env.close()
    eval_env.close()
    plot_learning_curve(work, f"{algo.upper()} on {cfg.env_id}")
    return model, wall


#: what renders in each command that takes env kwargs (``render_mode`` is not theirs to set)
_RENDERING = {"train": "not an env argument of a training run ({got}; the evaluation renders "
                       "nothing, the video uses rgb_array_list)",
              "evaluate": "not taken by spinstrike evaluate ({got}; its episodes render "
                          "nothing: spinstrike record films them)",
              "record": "not taken by spinstrike record ({got}; it films with "
                        "rgb_array_list)"}


def _refuse_render_mode(env_kwargs: dict, field: str = "env_kwargs",
                        command: str = "train") -> None:
    """Env kwargs hold no ``render_mode``: a training run's evaluation and ``spinstrike
    evaluate`` render nothing, and the videos set ``rgb_array_list`` (given twice, ``gym.make``
    raised a TypeError after training). ``field`` names where they came from (``--env-kwargs``
    of ``command``)."""
    if "render_mode" in env_kwargs:
        why = _RENDERING[command].format(got=f"got {env_kwargs['render_mode']!r}")
        raise AgentConfigError(f"{field}: render_mode is {why}: drop it")


def check_env_kwargs(env_id: str, env_kwargs: dict, field: str = "env_kwargs",
                     command: str = "train"):
    """Build the env once with ``env_kwargs``: its own validation (a ConfigError naming the
    argument) speaks before anything about the run folder. Returns its observation space.
    ``field`` and ``command`` name where the kwargs came from in this function's own errors
    (default: a training run's ``env_kwargs``)."""
    import gymnasium as gym

    _refuse_render_mode(env_kwargs, field, command)
    steps = env_kwargs.get("max_episode_steps")
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, int)
                              or steps < 1):  # gymnasium's own check is a bare assert
        raise AgentConfigError(f"{field}: max_episode_steps: must be an int >= 1 "
                               f"(got {steps!r})")
    env = gym.make(env_id, **env_kwargs)
    space = env.observation_space
    never_ends = env.spec.max_episode_steps is None and _never_terminates(env.unwrapped)
    env.close()
    if never_ends:
        # gym.make adds no limit to a variant registered without one: the final evaluation,
        # `evaluate` and `record` ran for ever (training's vector env stopped at 250 steps)
        raise AgentConfigError(f"{env_id}: a control env's episodes never end and it registers "
                               f"no max_episode_steps, so evaluation and videos would run for "
                               f"ever: register it with max_episode_steps (the shipped control "
                               f"envs: 250, 5 s), or give max_episode_steps in {field}")
    return space


def _registered(env_id: str) -> dict:
    """``config.yml``'s record of a variant's registration when it trained (``registered``)
    and of the source of its classes of the user's (``code``: ``envs.code_fingerprint``),
    which ``evaluate`` / ``record RUN`` compare with the registration and code then; none
    for a shipped id."""
    from spinstrike.envs import code_fingerprint, registered_kwargs

    registered = registered_kwargs(env_id)
    code = code_fingerprint(env_id)
    return {**({"registered": registered} if registered else {}),
            **({"code": code} if code else {})}


def _check_entry_env_kwargs(env_id: str, cfg: RunConfig, given: dict | None):
    """``check_env_kwargs`` of a new run's ``env_kwargs``; an argument the env refuses that
    came from the hyperparameter file's entry (not ``--env-kwargs``) is named with the entry,
    as the file's other errors are (it was the bare argument, with no word of the file)."""
    from spinstrike.envs.config import ConfigError

    try:
        return check_env_kwargs(env_id, cfg.env_kwargs)
    except ConfigError as exc:
        key = str(exc).split(":", 1)[0]
        if cfg.where and key in (cfg.raw.get("env_kwargs") or {}) and key not in (given or {}):
            raise ConfigError(f"{cfg.where}.env_kwargs.{exc}") from None
        raise


def _never_terminates(env) -> bool:
    """A control env: its episodes end only by a step limit."""
    from spinstrike.envs.control import _ControlEnv

    return isinstance(env, _ControlEnv)


#: how a run ends when the command does not say (``train``'s evaluate, eval_episodes, video)
FINISH = {"evaluate": True, "eval_episodes": 50, "video": True}

#: the SB3 policy each kind of observation needs
POLICY_FOR = {"vector": "MlpPolicy", "dict": "MultiInputPolicy", "pixels": "CnnPolicy"}


def _policy_for(cfg: RunConfig, space) -> str:
    """The SB3 policy for the env's observations: the config's, or for a config's ``MlpPolicy``
    (what every shipped entry names) on dict or pixel observations the policy they need, said
    on one line; a config naming a policy that cannot take them is refused."""
    from gymnasium import spaces
    from stable_baselines3.common.preprocessing import is_image_space

    kind = ("dict" if isinstance(space, spaces.Dict)
            else "pixels" if is_image_space(space) else "vector")
    need = POLICY_FOR[kind]
    if cfg.policy == need:
        return need
    if cfg.policy == "MlpPolicy":
        print(f"policy: {need} for {kind} observations (obs_mode={kind!r}; the config's "
              f"MlpPolicy takes vectors)", file=sys.stderr)
        return need
    raise AgentConfigError(f"policy: {cfg.policy} cannot take {kind} observations "
                           f"(obs_mode={kind!r}); use {need}")


def _new_run(algo: str, env_id: str, config, seed: int | None, timesteps: int | None,
             n_envs: int | None, env_kwargs: dict | None,
             hyperparameters: dict | None = None) -> tuple[RunConfig, int]:
    """A new run's config (the file's entry, with the command line's overrides) and seed."""
    overrides: dict[str, Any] = dict(hyperparameters or {})
    if timesteps is not None:
        overrides["n_timesteps"] = timesteps
    if n_envs is not None:
        overrides["n_envs"] = n_envs
    cfg = load_agent_config(algo, env_id, config, overrides)
    if env_kwargs:
        cfg.env_kwargs = {**cfg.env_kwargs, **env_kwargs}
    seed = 0 if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise AgentConfigError(f"seed: must be an integer from 0 to 2**32 - 1 (SB3 seeds "
                               f"numpy's 32-bit generator; got {seed!r})")
    freq = cfg.model_kwargs.get("train_freq")
    if isinstance(freq, tuple) and len(freq) == 2 and str(freq[1]).startswith("episode") \
            and cfg.n_envs > 1:  # SB3 asserted it inside learn(): a traceback
        raise AgentConfigError(f"train_freq: {list(freq)} trains once per episode, which SB3 "
                               f"does with one env only (n_envs is {cfg.n_envs}): give "
                               f"--n-envs 1, or a train_freq in steps ({cfg.source})")
    starts = cfg.model_kwargs.get("learning_starts")
    if isinstance(starts, (int, float)) and starts >= cfg.n_timesteps:
        print(f"warning: learning_starts is {starts:g} and the budget {cfg.n_timesteps} steps: "
              f"{algo.upper()} makes no update in this run, and its agent is the untrained "
              f"policy ({cfg.source})", file=sys.stderr)
    return cfg, seed


def _settle_new_run(cfg: RunConfig, env_id: str, env_kwargs: dict | None) -> None:
    """A new run's ``cfg`` as its ``config.yml`` records it: the env built once with its
    arguments (a bad one refused), the policy its observations need, and the env's arguments
    as registered (``as_registered``)."""
    cfg.policy = cfg.raw["policy"] = _policy_for(cfg, _check_entry_env_kwargs(
        env_id, cfg, env_kwargs))
    # config.yml records the env: a variant's registered arguments and its scene as read
    # (not a path to a file that may change), so an edit of the user's module changes no run
    from spinstrike.envs import as_registered

    cfg.env_kwargs = as_registered(env_id, cfg.env_kwargs)


def new_run_record(algo: str, env_id: str, *, config: str | Path | None = None,
                   timesteps: int | None = None, env_kwargs: dict | None = None,
                   hyperparameters: dict | None = None) -> dict:
    """What ``train`` with these arguments would record now in a new run's ``config.yml`` of
    its env and hyperparameters (``hyperparameters``, and ``registered`` for a variant), as the
    file holds them: a finished run trained as asked now records the same. Nothing is
    written; the warnings ``train`` prints for such a run are not repeated."""
    import contextlib
    import io

    with contextlib.redirect_stderr(io.StringIO()):
        cfg, _ = _new_run(algo, env_id, config, None, timesteps, None, env_kwargs,
                          hyperparameters)
        _settle_new_run(cfg, env_id, env_kwargs)
    record = {"hyperparameters": cfg.as_yaml_dict(), **_registered(env_id)}
    return yaml.safe_load(yaml.safe_dump(record, sort_keys=False))


def train(algo: str | None, env_id: str | None, *, config: str | Path | None = None,
          seed: int | None = None,
          timesteps: int | None = None, out: str | Path | None = None,
          n_envs: int | None = None, device: str = "cpu", resume: bool = False,
          force: bool = False, progress: bool = True, evaluate: bool | None = None,
          eval_episodes: int | None = None, video: bool | None = None,
          env_kwargs: dict | None = None,
          eval_freq: int | None = None, eval_episodes_during: int = 10,
          torch_threads: int | None = 1, command: str | None = None,
          imitate: str | None = None, imitate_rounds: int = 20,
          imitate_episodes: int = 16, hyperparameters: dict | None = None) -> TrainResult:
    """Train ``algo`` on ``env_id``; return the run directory and what was measured.

    Args:
        config: rl-zoo3 hyperparameter file (default: the packaged ``configs/agents/<algo>.yml``).
        timesteps, n_envs, env_kwargs: override the file's ``n_timesteps``, ``n_envs`` and
            ``env_kwargs``.
        hyperparameters: entries replacing the file's for a new run (e.g.
            ``{"learning_starts": 1000}``), validated as the file's; recorded in ``config.yml``.
        seed: default 0.
        out: run directory (default ``runs/<algo>-<env>-s<seed>``).
        resume: continue ``out`` from its newest checkpoint, as its ``config.yml`` records it:
            ``algo``, ``env_id``, ``seed``, ``config``, ``n_envs``, ``env_kwargs``,
            ``evaluate``, ``eval_episodes`` and ``video`` may be None (or repeat the record;
            anything else is refused), ``timesteps`` sets a new budget (recorded in
            ``config.yml``); refused where the code of the user's that a variant runs changed
            since the run trained (``_check_recorded_code``).
        force: replace an existing run directory.
        evaluate, eval_episodes, video: after training, evaluate against random and oracle
            over ``eval_episodes`` (default True, 50), record an mp4 (default True); a resumed
            run finishes as its first command asked (``config.yml``'s ``finish``).
        eval_freq, eval_episodes_during: the learning curve's evaluations (default: 10 evenly
            spaced, for PPO at least half a rollout apart, of 10 episodes each).
        torch_threads: PyTorch CPU threads (1 is fastest for these small networks, and leaves
            the other core to the env); None keeps PyTorch's default.
        imitate: start PPO's policy from this teacher (one of ``agents.imitate.TEACHERS``:
            ``planner``, ``reactive-planner``, ``chase-and-hit``) by DAgger
            (``agents.imitate``): ``imitate_rounds`` rounds of ``imitate_episodes`` episodes,
            before the ``n_timesteps`` of PPO. Written to ``imitation.csv`` and ``config.yml``
            (its wall time there; the returned ``wall_time`` is PPO's).

    Interrupted by Ctrl-C, or by SIGTERM (in the main thread, while it trains SIGTERM raises
    ``SystemExit(143)``; the previous handler is restored after), it keeps the work folder
    (``<out>.partial`` for a new run), says how to go on, and re-raises.
    """
    if out is None and (algo is None or env_id is None):
        raise AgentConfigError("out: give the run directory (or algo and env)")
    run_dir = Path(out) if out is not None else default_run_dir(algo, env_id, seed or 0)
    imitation = None
    if resume:  # the run as recorded; the checkpoint holds an imitated policy already
        if hyperparameters:
            raise AgentConfigError(f"hyperparameters: a resumed run trains as its config.yml "
                                   f"records it (got {sorted(hyperparameters)})")
        _refuse_rllib_run(run_dir)
        work = _work_dir(run_dir, resume, force)
        given = {"--algo": algo, "--env": env_id, "--seed": seed, "--n-envs": n_envs,
                 "--env-kwargs": env_kwargs, "--imitate": imitate}
        algo, cfg, seed, recorded = _recorded_run(
            work, given, config, timesteps,
            {"evaluate": evaluate, "eval_episodes": eval_episodes, "video": video})
        env_id = cfg.env_id
        done = _latest_checkpoint(work)
        done = _checkpoint_steps(done) if done is not None else 0
        # the recorded budget given again is the same command, not a new budget (interrupted in
        # its final evaluation, or a budget SB3 rounds up to whole rollouts, it was refused)
        budget = recorded_budget(work)
        if timesteps is not None and timesteps <= done and timesteps != budget:
            raise AgentConfigError(f"timesteps: {work} has trained {done} steps; a new budget "
                                   f"must exceed them (got {timesteps}; the recorded budget, "
                                   f"{budget}, continues the run as recorded)")
    else:
        recorded = {}
        if algo is None or env_id is None:
            raise AgentConfigError("algo, env: a new run needs both")
        cfg, seed = _new_run(algo, env_id, config, seed, timesteps, n_envs, env_kwargs,
                             hyperparameters)
        if imitate is not None:
            from spinstrike.agents.imitate import settings

            imitation = settings(imitate, algo, env_id, bool(cfg.normalize), imitate_rounds,
                                 imitate_episodes)
        # a bad argument first, before "out exists"
        _settle_new_run(cfg, env_id, env_kwargs)
        work = _work_dir(run_dir, resume, force)
    # what is not given: as the run's first command asked (resumed), else the default
    finish = {key: value if value is not None else recorded.get(key, FINISH[key])
              for key, value in (("evaluate", evaluate), ("eval_episodes", eval_episodes),
                                 ("video", video))}
    evaluate, eval_episodes, video = finish["evaluate"], finish["eval_episodes"], finish["video"]
    if resume and work == run_dir and done >= cfg.n_timesteps:
        return _complete_run(run_dir, algo, env_id, seed, done, cfg.env_kwargs, finish)
    from spinstrike.agents.imitate import _sigterm_exits

    start = time.time()
    try:
        # SIGTERM (a scheduler's kill) as Ctrl-C: the logs are flushed, the message below says
        # how to go on, and DAgger's workers are stopped (by default it ends the process at once)
        with _sigterm_exits():
            model, wall = _learn(algo, cfg, work, seed=seed, device=device, resume=resume,
                                 progress=progress, eval_freq=eval_freq,
                                 eval_episodes_during=eval_episodes_during, command=command,
                                 torch_threads=torch_threads, imitate=imitation,
                                 finish=finish)
        if work != run_dir:
            if run_dir.exists():
                shutil.rmtree(run_dir)
            work.rename(run_dir)
    except (KeyboardInterrupt, SystemExit):  # Ctrl-C; SIGTERM (imitate._sigterm_exits)
        last = _latest_checkpoint(work)
        if resume or last is not None:
            _record_segment(work, _checkpoint_steps(last) if last is not None else 0,
                            time.time() - start, interrupted=True)
            print(f"interrupted: continue with --resume --out {run_dir}", file=sys.stderr)
        else:  # e.g. during --imitate's DAgger rounds, before PPO's first checkpoint
            print(f"interrupted before the first checkpoint: nothing to resume ({work} keeps "
                  "what was written); run the same command again to start over",
                  file=sys.stderr)
        raise
    except BaseException:
        if not resume:
            shutil.rmtree(work, ignore_errors=True)
        raise
    result = TrainResult(run_dir=str(run_dir), env=env_id, timesteps=int(model.num_timesteps),
                         wall_time=wall)
    return _book_and_finish(result, wall, run_dir, algo, env_id, seed, cfg.env_kwargs, finish)


def _refuse_rllib_run(run_dir: Path) -> None:
    """``resume`` of an RLlib run (``backend: rllib`` in its config.yml) is not this function's:
    it said the run "has no checkpoint to resume from", looking for SB3's (walk W26a F2)."""
    work = resume_folder(run_dir)
    if run_record(work / "config.yml").get("backend") == "rllib":
        raise AgentConfigError(
            f"resume: {work} is an RLlib run (its config.yml records backend: rllib), not an "
            f"SB3 one: `spinstrike train --resume --out {run_dir}` continues it (leave out "
            f"--backend, or give --backend rllib), or from Python "
            f"spinstrike.agents.rllib_train.train_rllib(None, out=..., resume=True)")


def _book_and_finish(result: TrainResult, wall: float, run_dir: Path, algo: str, env_id: str,
                     seed: int, env_kwargs: dict, finish: dict) -> TrainResult:
    """Book a trained stretch in ``config.yml`` and finish the run (``_finish_sb3``), with
    SIGTERM as Ctrl-C throughout: one there ended the run with no word, a finished-looking
    folder without its summary (walk W24b F10); now it says which command writes what is
    missing (``finish_run`` says it itself once it has begun)."""
    from spinstrike.agents.imitate import _sigterm_exits

    runs = None
    try:
        with _sigterm_exits():
            runs = _record_segment(run_dir, result["timesteps"], wall)
            return _finish_sb3(result, runs, run_dir, algo, env_id, seed, env_kwargs, finish)
    except (KeyboardInterrupt, SystemExit) as exc:
        if runs is None:  # booked still (walk W25 F2: the resumed run read "0 steps, 0 s")
            _record_segment(run_dir, result["timesteps"], wall)
        if not getattr(exc, "told", False):
            print(f"interrupted after training: the model is saved in {run_dir}; `spinstrike "
                  f"train --resume --out {run_dir}` writes what is missing", file=sys.stderr)
        raise


def _finish_sb3(result: TrainResult, runs: list[dict], run_dir: Path, algo: str, env_id: str,
                seed: int, env_kwargs: dict, finish: dict) -> TrainResult:
    """``finish_run`` for an SB3 run of ``runs`` (``config.yml``'s stretches of training)."""
    result.update(sessions=len(runs), total_wall_time=sum(r["wall_time_s"] for r in runs))
    policy = None
    if finish["evaluate"] or finish["video"]:
        from spinstrike.agents.evaluate import load_model_policy

        policy, _ = load_model_policy(run_dir)
    record = run_record(run_dir / "config.yml")
    return finish_run(result, policy, env_id, run_dir, env_kwargs,
                      run_title({**record, "algo": algo, "env": env_id, "seed": seed,
                                 "runs": runs}),
                      evaluate=finish["evaluate"], eval_episodes=finish["eval_episodes"],
                      video=finish["video"])


def run_title(meta: dict) -> str:
    """A run's summary title from its ``config.yml`` record: algorithm, env, the env arguments
    it was given beyond what the id registers (``--env-kwargs``, the hyperparameter file's: the
    runs of a grid had one title), seed, steps and the time of every stretch of training."""
    runs = meta.get("runs") or []
    total = sum(r["wall_time_s"] for r in runs)
    label = "PPO (RLlib)" if meta.get("backend") == "rllib" else str(meta["algo"]).upper()
    entry = (meta.get("hyperparameters") or {}).get(meta["env"]) or {}
    registered = meta.get("registered") or {}
    given = {key: value for key, value in (entry.get("env_kwargs") or {}).items()
             if key not in registered or registered[key] != value}
    with_ = " with " + ", ".join(f"{key} {short_value(value)}" for key, value in
                                 given.items()) if given else ""
    return (f"## {label} on {meta['env']}{with_} (seed {meta['seed']}, "
            f"{runs[-1]['timesteps'] if runs else 0} steps, {total:.0f} s"
            f"{f' in {len(runs)} sessions' if len(runs) > 1 else ''})")


def _complete_run(run_dir: Path, algo: str, env_id: str, seed: int, steps: int,
                  env_kwargs: dict, finish: dict) -> TrainResult:
    """``--resume`` of a run that has trained its budget: it trains nothing, and writes only
    what its finish asks and it lacks (stopped during its final evaluation or video); it
    re-loaded the last checkpoint, saved it again as a new session, and evaluated and filmed
    the run again."""
    runs = (yaml.safe_load((run_dir / "config.yml").read_text()) or {}).get("runs") or []
    missing = {"evaluate": finish["evaluate"] and not (run_dir / "summary.md").is_file(),
               "video": finish["video"] and not (run_dir / "rollout.mp4").is_file()}
    result = TrainResult(run_dir=str(run_dir), env=env_id, timesteps=steps, wall_time=0.0,
                         complete=[key for key, value in missing.items() if value])
    return _finish_sb3(result, runs, run_dir, algo, env_id, seed, env_kwargs,
                       {**finish, **missing})


def _record_segment(run_dir: Path, timesteps: int, wall: float,
                    interrupted: bool = False) -> list[dict]:
    """Add one stretch of training (to ``timesteps``, ``wall`` s) to ``config.yml``'s ``runs``
    (an interrupted one is marked, and counted in the run's wall time); returns them all."""
    path = run_dir / "config.yml"
    if not path.is_file():  # stopped before the run was set up
        return []
    meta = yaml.safe_load(path.read_text())
    from spinstrike.agents.config import commit

    # (each session's commit: a run resumed at another commit recorded only its first's,
    # walk W24b F5)
    entry = {"timesteps": timesteps, "wall_time_s": round(wall, 2), "commit": commit()}
    if interrupted:
        entry["interrupted"] = True
    meta.setdefault("runs", []).append(entry)
    write_yaml(path, meta)
    return meta["runs"]


def finish_run(result: TrainResult, policy, env_id: str, run_dir: Path, env_kwargs: dict,
               title: str, *, evaluate: bool, eval_episodes: int, video: bool) -> TrainResult:
    """The end of every backend's run: ``summary.md`` (the policy beside random and the
    reference over ``eval_episodes``) and ``rollout.mp4``, as asked; returns ``result``.

    Interrupted (Ctrl-C, SIGTERM) after training, it says that the model is saved and which
    commands write what is missing, and re-raises; a video stopped half way is not left."""
    from spinstrike.agents.imitate import _sigterm_exits

    try:
        with _sigterm_exits():
            if evaluate:
                from spinstrike.agents.evaluate import evaluate as run_eval
                from spinstrike.agents.evaluate import summarise

                results = run_eval(env_id, policy, episodes=eval_episodes,
                                   env_kwargs=env_kwargs)
                summarise(results, run_dir, title)
                result["evaluations"] = {r.policy: (r.mean, r.std) for r in results}
            if video:
                from spinstrike.agents.record import record

                result["video"] = record(policy, env_id, run_dir / "rollout.mp4", episodes=3,
                                         env_kwargs=env_kwargs)["path"]
    except (KeyboardInterrupt, SystemExit) as exc:
        exc.told = True  # (said here: the caller's own handler stays quiet)
        missing = [f"spinstrike evaluate {run_dir}"] if "evaluations" not in result and \
            evaluate else []
        if video and "video" not in result:
            missing.append(f"spinstrike record {run_dir}")
        print(f"interrupted after training: the model is saved in {run_dir}; "
              f"{' and '.join(f'`{m}`' for m in missing)} write"
              f"{'s' if len(missing) == 1 else ''} what is missing", file=sys.stderr)
        raise
    return result
