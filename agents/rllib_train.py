"""Train PPO with Ray RLlib (``spinstrike train --backend rllib``), into the same run folder as
SB3 runs::

    runs/<name>/
        config.yml  command.txt  progress.csv    resolved entry, metadata; RLlib's per-iteration log
        checkpoint/             RLlib's checkpoint (``Algorithm.from_checkpoint``)
        evaluations.npz         periodic evaluations      learning_curve.png
        summary.md/.json        final evaluation vs random and oracle      rollout.mp4

The hyperparameters come from the same rl-zoo3 file as SB3's (``configs/agents/ppo.yml``),
translated: ``n_envs`` envs in all (split over the env runners, one native vector env each),
``n_steps * n_envs`` steps per update, ``batch_size`` minibatches (at most the update: RLlib
refuses a larger one, so does this module, before Ray starts), ``n_epochs``,
``learning_rate``, ``gamma``, ``gae_lambda``, ``clip_range``, ``ent_coef``, ``net_arch``.
Evaluation, summary, learning curve and video are SB3 runs' own code
(``agents.evaluate``, ``agents.record``, ``agents.train.plot_learning_curve``), run on the
trained RLModule's deterministic action. Needs the ``rllib`` extra.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shlex
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from spinstrike.agents.config import (
    AgentConfigError,
    RunConfig,
    load_agent_config,
    run_record,
)
from spinstrike.agents.train import (
    EVAL_SEED,
    TrainResult,
    _check_entry_env_kwargs,
    _registered,
    _work_dir,
    book_resume,
    default_run_dir,
    finish_run,
    plot_learning_curve,
    run_title,
    write_yaml,
)
from spinstrike.envs import as_registered

__all__ = ["RunnersLost", "load_rllib_policy", "module_policy", "ppo_config",
           "train_rllib"]


#: the rl-zoo3 PPO keys ppo_config translates (of policy_kwargs: net_arch only)
_TRANSLATED = {"n_steps", "batch_size", "n_epochs", "learning_rate", "gamma", "gae_lambda",
               "clip_range", "ent_coef", "vf_coef", "policy_kwargs"}


def not_used(cfg: RunConfig) -> list[str]:
    """The hyperparameters of ``cfg`` that RLlib's PPO does not take (RLlib's defaults apply):
    config.yml records them as resolved and lists them under ``not_used`` (walk W26a F10:
    ``log_std_init: -1.0`` read as the run's, RLlib's initial log std being ~0)."""
    h = dict(cfg.model_kwargs)
    return sorted(set(h) - _TRANSLATED) + [
        f"policy_kwargs.{k}" for k in sorted(set(h.get("policy_kwargs") or {}) - {"net_arch"})]


def ppo_config(cfg: RunConfig, seed: int, num_env_runners: int):
    """RLlib's ``PPOConfig`` for an rl-zoo3 PPO entry, on the native vector env."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    from spinstrike.envs.rllib import configure

    h = dict(cfg.model_kwargs)
    unused = not_used(cfg)
    if unused:  # said, not silently dropped (config.yml records them, and lists them)
        print(f"warning: --backend rllib does not use {', '.join(unused)} (RLlib's defaults "
              "apply)", file=sys.stderr)
    lr = h.get("learning_rate", 3e-4)
    if callable(lr):  # rl-zoo3's lin_<value>: linear to 0 over the run, as RLlib's schedule
        lr = [[0, float(lr(1.0))], [int(cfg.n_timesteps), 0.0]]
    else:
        lr = float(lr)
    if callable(h.get("clip_range")):
        raise AgentConfigError("clip_range: a 'lin_' schedule is not supported by --backend "
                               "rllib (RLlib's clip_param is a number)")
    runners = max(int(num_env_runners), 1)
    per_runner = max(1, math.ceil(cfg.n_envs / runners))
    n_steps = int(h.get("n_steps", 2048))
    batch = n_steps * per_runner * runners
    minibatch = int(h.get("batch_size", 64))
    if minibatch > batch:  # RLlib's PPO refuses it (SB3 trains on one short minibatch)
        split = (f"; n_envs {cfg.n_envs} over {runners} runners, {per_runner} each"
                 if per_runner * runners != cfg.n_envs else "")
        raise AgentConfigError(
            f"batch_size: must be <= n_steps * n_envs, the env steps per update, with --backend "
            f"rllib (got batch_size {minibatch} > {n_steps} * {per_runner * runners} = "
            f"{batch}{split}): raise --n-envs or n_steps, or lower batch_size")
    net = (h.get("policy_kwargs") or {}).get("net_arch", [64, 64])
    if isinstance(net, dict):  # SB3's {pi: [...], vf: [...]}
        net = net.get("pi", [64, 64])
    config = (PPOConfig()
              .env_runners(num_env_runners=int(num_env_runners), rollout_fragment_length=n_steps)
              .training(train_batch_size_per_learner=batch, minibatch_size=minibatch,
                        num_epochs=int(h.get("n_epochs", 10)),
                        lr=lr, gamma=float(h.get("gamma", 0.99)),
                        lambda_=float(h.get("gae_lambda", 0.95)),
                        clip_param=float(h.get("clip_range", 0.2)),
                        entropy_coeff=float(h.get("ent_coef", 0.0)),
                        vf_loss_coeff=float(h.get("vf_coef", 0.5)))
              .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=list(net),
                                                         fcnet_activation="tanh"))
              .debugging(seed=seed))
    return configure(config, cfg.env_id, cfg.env_kwargs, num_envs_per_env_runner=per_runner)


def module_policy(module):
    """``policy(env, obs)``: the RLModule's deterministic action (the mean), for one env; a
    squashed Gaussian's (SAC's) squashed: RLlib's ``to_deterministic`` gives its mean before
    the squash, an action outside the bounds the policy never takes (clipped, a mean of 1.5
    acted 1.0 where the policy acts tanh(1.5) = 0.91, walk W22a)."""
    import torch

    dist_cls = module.get_inference_action_dist_cls()

    def policy(env, obs):
        with torch.no_grad():
            out = module.forward_inference(
                {"obs": torch.as_tensor(np.asarray(obs, dtype=np.float32)[None])})
            dist = dist_cls.from_logits(out["action_dist_inputs"])
            action = dist.to_deterministic().sample()
            squash = getattr(dist, "_squash", None)
            if squash is not None:
                action = squash(action)
        return np.clip(action[0].numpy(), -1.0, 1.0)

    return policy


def load_rllib_policy(run_dir: str | Path):
    """(policy, config.yml) of an RLlib run folder: its checkpoint's RLModule, deterministic
    (what ``spinstrike evaluate``/``record RUN_DIR`` use)."""
    from spinstrike.agents.evaluate import read_run_config

    run_dir = Path(run_dir)
    meta = read_run_config(run_dir)
    return _checkpoint_policy(run_dir / "checkpoint", "run", "not an RLlib run folder"), meta


def _checkpoint_policy(checkpoint: Path, what: str, otherwise: str):
    """The deterministic policy of an RLlib checkpoint's default RLModule; ``what`` (a run, a
    checkpoint) and ``otherwise`` name the folder in the errors: no Ray, no module."""
    path = checkpoint / "learner_group" / "learner" / "rl_module" / "default_policy"
    try:
        from ray.rllib.core.rl_module.rl_module import RLModule
    except ImportError:
        raise AgentConfigError(f"run_dir: an RLlib {what} needs Ray RLlib: pip install "
                               "'spinstrike[rllib]'") from None
    if not path.is_dir():
        raise AgentConfigError(f"checkpoint: {path} is missing ({otherwise})")
    return module_policy(RLModule.from_checkpoint(str(path.resolve())))


def tune_checkpoint(path: str | Path) -> tuple[Path, Path] | None:
    """A Tune trial's checkpoint and its ``params.json`` (the trial's config: ``env``,
    ``env_config`` with the trial's values), for a trial folder (its newest
    ``checkpoint_*``) or one of its checkpoints; None if ``path`` is neither."""
    path = Path(path)
    if path.name.startswith("checkpoint_") and (path.parent / "params.json").is_file():
        return path, path.parent / "params.json"
    checkpoints = sorted(path.glob("checkpoint_*"))
    if (path / "params.json").is_file() and checkpoints:
        return checkpoints[-1], path / "params.json"
    return None


def load_tune_policy(path: str | Path):
    """(policy, env id, env arguments) of a Tune trial's RLlib checkpoint (:func:`tune_checkpoint`):
    its RLModule, deterministic, and the env its trial trained on (``params.json``), for
    ``spinstrike evaluate``/``record``. Only a SpinStrike env's trial."""
    import json

    from spinstrike.envs.rllib import PREFIX

    checkpoint, params = tune_checkpoint(path)
    try:
        config = json.loads(params.read_text())
    except (OSError, ValueError) as exc:
        raise AgentConfigError(f"run_dir: {params} could not be read ({exc})") from None
    env_id = config.get("env")
    if not isinstance(env_id, str):
        raise AgentConfigError(f"run_dir: {params} names no env id (env {env_id!r}): a trial of "
                               f"another env than a SpinStrike id")
    env_config = config.get("env_config") or {}
    if not isinstance(env_config, dict):
        raise AgentConfigError(f"run_dir: {params}'s env_config is not a mapping")
    policy = _checkpoint_policy(checkpoint, "checkpoint", "not an RLlib checkpoint of the new "
                                "API stack's default policy")
    return policy, env_id.removeprefix(PREFIX), env_config


def algorithm_checkpoint(path: str | Path) -> Path | None:
    """``path`` where it is an RLlib ``Algorithm`` checkpoint (``algo.save()``'s folder: its
    ``rllib_checkpoint.json`` and ``class_and_ctor_args.pkl``), else None."""
    path = Path(path)
    if (path / "rllib_checkpoint.json").is_file() and \
            (path / "class_and_ctor_args.pkl").is_file():
        return path
    return None


def load_algorithm_policy(path: str | Path):
    """(policy, env id, env arguments) of a user's own RLlib checkpoint (``algo.save()``):
    its RLModule, deterministic, and the env and ``env_config`` its config holds, for
    ``spinstrike evaluate``/``record`` (it was "not a run", walk W22a). Only a SpinStrike env's
    checkpoint."""
    import pickle

    from spinstrike.envs.rllib import PREFIX

    path = algorithm_checkpoint(path)
    try:
        import ray.rllib  # noqa: F401  (the pickle names its classes)
    except ImportError:
        raise AgentConfigError("run_dir: an RLlib checkpoint needs Ray RLlib: pip install "
                               "'spinstrike[rllib]'") from None
    try:
        state = pickle.loads((path / "class_and_ctor_args.pkl").read_bytes())
        config = state["ctor_args_and_kwargs"][0][0]
        if not isinstance(config, dict):
            config = config.to_dict()
    except Exception as exc:  # noqa: BLE001  (another Ray's or a damaged checkpoint)
        raise AgentConfigError(f"run_dir: {path}'s class_and_ctor_args.pkl could not be read "
                               f"({type(exc).__name__}: {exc})") from None
    env_id, env_config = config.get("env"), config.get("env_config") or {}
    if not isinstance(env_id, str):
        raise AgentConfigError(f"run_dir: {path} is an RLlib checkpoint of no env id (env "
                               f"{env_id!r}): a checkpoint of another env than a SpinStrike "
                               f"id")
    if not isinstance(env_config, dict):
        raise AgentConfigError(f"run_dir: {path}'s env_config is not a mapping")
    policy = _checkpoint_policy(path, "checkpoint", "not an RLlib checkpoint of the new API "
                                "stack's default policy")
    return policy, env_id.removeprefix(PREFIX), dict(env_config)


def _versions() -> dict[str, str]:
    import gymnasium
    import numba
    import ray
    import torch

    # numba too, the physics' compiler, as the SB3 backend's record (walk W26a F8: an upgrade
    # went unnoted when an rllib run was evaluated)
    versions = {"python": sys.version.split()[0], "numpy": np.__version__,
                "numba": numba.__version__, "ray": ray.__version__,
                "gymnasium": gymnasium.__version__, "torch": torch.__version__}
    from spinstrike.agents.config import code_version

    return {**code_version(), **{k: str(v) for k, v in versions.items()}}


def _steps(result: dict) -> int:
    runners = result.get("env_runners", {})
    return int(runners.get("num_env_steps_sampled_lifetime", 0))


class RunnersLost(RuntimeError):
    """Training stopped short of its budget: its iterations sampled no env steps (the env runners
    were lost: killed by Ray's memory monitor, a node gone). The run's folder is kept, with its
    checkpoint, for ``--resume``; ``spinstrike train`` exits 1."""


#: a run stops (:class:`RunnersLost`) after this many training iterations in a row that sampled
#: no env steps, once as many seconds have passed without one (a killed runner is restarted by
#: Ray, RLlib's default, and samples again: a new runner process imports Ray, RLlib and torch,
#: which took over 2 minutes on a loaded 2-core machine)
STALL_ITERATIONS = 5
STALL_SECONDS = 300.0

#: an RLlib run's checkpoint: ``checkpoint/`` (the newest), written as ``checkpoint.new/`` and
#: renamed over the old one (kept as ``checkpoint.old/`` while it is replaced), so a signal never
#: leaves a half-written checkpoint under the real name
CHECKPOINT, STEPS_FILE = "checkpoint", "spinstrike_steps.json"


def train_rllib(env_id: str | None, *, config: str | Path | None = None,
                seed: int | None = None, timesteps: int | None = None,
                out: str | Path | None = None, n_envs: int | None = None,
                num_env_runners: int | None = None, address: str | None = None,
                force: bool = False, resume: bool = False, evaluate: bool | None = None,
                eval_episodes: int | None = None, video: bool | None = None,
                env_kwargs: dict | None = None, eval_every: int | None = None,
                eval_episodes_during: int = 10, command: str | None = None) -> TrainResult:
    """Train PPO on ``env_id`` with RLlib; return the run directory and what was measured.

    Args:
        num_env_runners: RLlib env runner processes (each one native vector env; default 2).
        address: a running Ray cluster (``ray start --head`` prints it; ``"auto"``); default
            a local Ray started (and stopped) here, or the one already initialised.
        eval_every: training iterations between the learning curve's evaluations (default:
            about 10 over the run).
        resume: continue ``out`` (or ``out.partial``) from its RLlib checkpoint
            (``checkpoint/``, saved after every training iteration), as its ``config.yml``
            records it: ``env_id``, ``seed``, ``n_envs``, ``num_env_runners``, ``env_kwargs``,
            ``evaluate``, ``eval_episodes``, ``video`` may be None (or repeat the record),
            ``timesteps`` sets a new budget; the new stretch is booked in ``runs:``.
        The rest as :func:`spinstrike.agents.train.train`.

    Interrupted by Ctrl-C, or SIGTERM (``SystemExit(143)``, in place of Ray's handler, which
    aborted the process), it keeps the work folder (``<out>.partial`` for a new run) with its
    last checkpoint, books the stretch as interrupted, says how to go on, and re-raises. Env
    runners lost for good (:data:`STALL_ITERATIONS`, :data:`STALL_SECONDS`) raise
    :class:`RunnersLost`, the folder kept the same way.
    """
    from spinstrike.agents.imitate import _sigterm_exits
    from spinstrike.agents.train import FINISH, _record_segment

    given_finish = {"evaluate": evaluate, "eval_episodes": eval_episodes, "video": video}
    if resume:
        run_dir, work, cfg, seed, num_env_runners, recorded, done = _resumed_run(
            env_id, out=out, config=config, seed=seed, timesteps=timesteps, n_envs=n_envs,
            num_env_runners=num_env_runners, env_kwargs=env_kwargs, finish=given_finish)
        env_id = cfg.env_id
    else:
        recorded, done = {}, 0
        run_dir, cfg, seed, num_env_runners = _new_run(
            env_id, out=out, config=config, seed=seed, timesteps=timesteps, n_envs=n_envs,
            num_env_runners=num_env_runners, env_kwargs=env_kwargs)
    finish = {key: value if value is not None else recorded.get(key, FINISH[key])
              for key, value in given_finish.items()}
    if not isinstance(num_env_runners, int) or num_env_runners < 0:
        raise AgentConfigError(f"num_env_runners: must be an integer >= 0 "
                               f"(got {num_env_runners!r})")
    if resume and work == run_dir and done >= cfg.n_timesteps:
        return _complete_run(run_dir, env_id, done, cfg.env_kwargs, finish)
    try:
        import ray
    except ImportError:
        raise AgentConfigError("backend: rllib needs Ray RLlib: pip install "
                               "'spinstrike[rllib]'") from None
    if address is not None and not ray.is_initialized():
        _probe(address)
    # the env's config is checked here, before Ray starts or the disk is touched; the env is
    # built once (as the SB3 backend does: its errors come before the run folder's)
    algo_config = ppo_config(cfg, seed, num_env_runners)
    _compile_kernels(env_id, cfg.env_kwargs)
    if not resume:
        work = _work_dir(run_dir, False, force)
    started = _init_ray(ray, address)
    start = time.time()
    # SIGTERM (a scheduler's kill) as Ctrl-C, in place of the handler ray.init installs (Ray's
    # aborted the driver, exit -6, and the run folder was lost): the checkpoint and the logs
    # are kept and the message below says how to go on
    finished = None  # the run's folder once its stretch is trained and booked
    with _sigterm_exits() as signals:
        try:
            _check_cpus(ray, num_env_runners)
            policy, steps, wall = _learn(algo_config, cfg, work, seed=seed, address=address,
                                         num_env_runners=num_env_runners,
                                         eval_every=eval_every,
                                         eval_episodes_during=eval_episodes_during,
                                         command=command, resume=resume, finish=finish,
                                         run_dir=run_dir)
            if work != run_dir:
                if run_dir.exists():
                    shutil.rmtree(run_dir)
                work.rename(run_dir)
                work = run_dir
            runs = _record_segment(run_dir, steps, wall)
            finished = run_dir
        except RunnersLost:
            _record_segment(work, _checkpoint_steps(work), time.time() - start,
                            interrupted=True)
            raise
        except (KeyboardInterrupt, SystemExit):
            _interrupted(work, run_dir, cfg.n_timesteps, time.time() - start)
            if signals:  # Ray's wait turns the SystemExit(143) raised in it into SystemExit(1)
                raise SystemExit(128 + signals[0]) from None
            raise
        except BaseException:
            if not resume:
                shutil.rmtree(work, ignore_errors=True)
            raise
        finally:
            if started:
                _shutdown(ray, finished)
    result = TrainResult(run_dir=str(run_dir), env=env_id, timesteps=steps, wall_time=wall,
                         sessions=len(runs),
                         total_wall_time=sum(r["wall_time_s"] for r in runs))
    return finish_run(result, policy, env_id, run_dir, cfg.env_kwargs,
                      run_title(run_record(run_dir / "config.yml")),
                      evaluate=finish["evaluate"], eval_episodes=finish["eval_episodes"],
                      video=finish["video"])


def _resumed_run(env_id, *, out, config, seed, timesteps, n_envs, num_env_runners, env_kwargs,
                 finish):
    """The run ``--resume --out out`` continues, as its config.yml records it: (run dir, work
    folder, cfg, seed, env runners, the record's finish, steps of its checkpoint); the command
    line's contradictions are refused, as the SB3 backend's (``train._recorded_run``)."""
    from spinstrike.agents.train import _recorded_run

    if out is None:
        if env_id is None:
            raise AgentConfigError("out: give the run directory to resume")
        out = default_run_dir("ppo-rllib", env_id, seed or 0)
    run_dir = Path(out)
    work = _resume_dir(run_dir)
    given = {"--algo": None, "--env": env_id, "--seed": seed, "--n-envs": n_envs,
             "--env-kwargs": env_kwargs, "--imitate": None}
    _, cfg, seed, recorded = _recorded_run(work, given, config, timesteps, finish)
    meta = run_record(work / "config.yml")
    runners = meta.get("num_env_runners", 2)
    if num_env_runners is not None and num_env_runners != runners:
        raise AgentConfigError(
            f"resume: {work} records --num-env-runners {runners}; the command line "
            f"contradicts it (got {num_env_runners}). Leave it out: --resume --out RUN "
            f"continues the run as recorded (only --timesteps may change)")
    done = _checkpoint_steps(work, meta)
    budget = int(meta["hyperparameters"][cfg.env_id]["n_timesteps"])
    if timesteps is not None and timesteps <= done and timesteps != budget:
        raise AgentConfigError(f"timesteps: {work} has trained {done} steps; a new budget "
                               f"must exceed them (got {timesteps}; the recorded budget, "
                               f"{budget}, continues the run as recorded)")
    return run_dir, work, cfg, seed, runners, recorded, done


def _new_run(env_id, *, out, config, seed, timesteps, n_envs, num_env_runners, env_kwargs):
    """A new run's (run dir, cfg, seed, env runners), checked before Ray starts."""
    if env_id is None:
        raise AgentConfigError("env: a new run needs one")
    seed = 0 if seed is None else seed
    num_env_runners = 2 if num_env_runners is None else num_env_runners
    overrides: dict[str, Any] = {}
    if timesteps is not None:
        overrides["n_timesteps"] = timesteps
    if n_envs is not None:
        overrides["n_envs"] = n_envs
    cfg = load_agent_config("ppo", env_id, config, overrides)
    if env_kwargs:
        cfg.env_kwargs = {**cfg.env_kwargs, **env_kwargs}
    # config.yml records the env: a variant's registered arguments and its scene as read
    cfg.env_kwargs = as_registered(env_id, cfg.env_kwargs)
    if cfg.normalize:
        raise AgentConfigError("normalize: not supported with --backend rllib")
    # as the SB3 backend: a bad argument, max_episode_steps < 1 or a control env with no
    # step limit (whose learning-curve and final evaluations in this process never ended:
    # W17, a silent hang with both cores busy) is refused here, naming it
    _check_entry_env_kwargs(env_id, cfg, env_kwargs)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise AgentConfigError(f"seed: must be an integer from 0 to 2**32 - 1, as the SB3 "
                               f"backend's (got {seed!r})")
    run_dir = Path(out) if out is not None else default_run_dir("ppo-rllib", env_id, seed)
    return run_dir, cfg, seed, num_env_runners


def _init_ray(ray, address: str | None) -> bool:
    """Start a local Ray or join ``address``'s unless Ray runs here already; True if started."""
    if ray.is_initialized():
        return False
    # address None: a new local Ray, as documented (Ray itself would join any cluster
    # running on this machine, e.g. another job's)
    try:
        ray.init(address=address or "local", include_dashboard=False, log_to_driver=False)
    except ConnectionError as exc:  # (was Ray's traceback, exit 1)
        raise AgentConfigError(
            f"--address {address}: no Ray cluster to join ({str(exc).splitlines()[0]}); "
            "start one with `ray start --head` (see docs/rllib.md), or leave --address out "
            "to train on a new local Ray") from None
    return True


def _shutdown(ray, trained: Path | None) -> None:
    """``ray.shutdown()``; a Ctrl-C or SIGTERM in it after the run trained its budget
    (``trained``: the run's folder, in place) says how the run is finished, which it said
    nothing of (walk W26a F7: no summary, no video, no word)."""
    try:
        ray.shutdown()
    except (KeyboardInterrupt, SystemExit):
        if trained is not None:
            print(f"interrupted after training: the run and its RLlib checkpoint are saved in "
                  f"{trained}; `spinstrike train --resume --out {trained}` writes what is "
                  f"missing (its summary and video)", file=sys.stderr)
        raise


def _interrupted(work: Path, run_dir: Path, budget: int, wall: float) -> None:
    """Book the stretch that a signal stopped (to its checkpoint) and say how to go on."""
    from spinstrike.agents.train import _record_segment

    if _checkpoint(work) is not None:
        trained = _checkpoint_steps(work)
        _record_segment(work, trained, wall, interrupted=True)
        print(f"interrupted at {trained} of the budget's {budget} steps ({work} keeps the run "
              f"and its RLlib checkpoint): continue with spinstrike train --resume --out "
              f"{run_dir}", file=sys.stderr)
    else:
        print(f"interrupted before the first training iteration ended: nothing to resume "
              f"({work} keeps what was written); run the same command again to start over",
              file=sys.stderr)


def _checkpoint(work: Path) -> Path | None:
    """``work``'s RLlib checkpoint (``checkpoint/``; ``checkpoint.old/`` put back where a signal
    came between the renames that replace it), or None."""
    path, old = work / CHECKPOINT, work / f"{CHECKPOINT}.old"
    if not path.is_dir() and old.is_dir():
        old.rename(path)
    return path if (path / "rllib_checkpoint.json").is_file() else None


def _checkpoint_steps(work: Path, meta: dict | None = None) -> int:
    """The env steps ``work``'s checkpoint was saved at (0: none); a run written before the
    checkpoint recorded them: its last stretch's (``config.yml``)."""
    ckpt = _checkpoint(work)
    if ckpt is None:
        return 0
    try:
        return int(json.loads((ckpt / STEPS_FILE).read_text())["timesteps"])
    except (OSError, ValueError, KeyError, TypeError):
        runs = (meta if meta is not None else run_record(work / "config.yml")).get("runs")
        return int(runs[-1]["timesteps"]) if runs else 0


def _save_checkpoint(algo, work: Path, steps: int, iteration: int) -> None:
    """RLlib's checkpoint (``Algorithm.save_to_path``) of ``algo`` at ``steps``, replacing the
    last one whole (:data:`CHECKPOINT`)."""
    new, path, old = (work / f"{CHECKPOINT}.new", work / CHECKPOINT,
                      work / f"{CHECKPOINT}.old")
    shutil.rmtree(new, ignore_errors=True)
    algo.save_to_path(str(new.resolve()))
    (new / STEPS_FILE).write_text(json.dumps({"timesteps": steps, "iteration": iteration}))
    if path.exists():
        shutil.rmtree(old, ignore_errors=True)
        path.rename(old)
    new.rename(path)
    shutil.rmtree(old, ignore_errors=True)


def _resume_dir(run_dir: Path) -> Path:
    """The folder ``--resume --out run_dir`` continues (the run, or its ``.partial``), checked:
    an RLlib run's record with an RLlib checkpoint."""
    from spinstrike.agents.train import resume_folder

    work = resume_folder(run_dir)
    if not (work / "config.yml").is_file():
        raise AgentConfigError(f"resume: {run_dir} is not a run directory")
    meta = run_record(work / "config.yml")
    if meta.get("backend") != "rllib":
        raise AgentConfigError(f"resume: {work} is not an RLlib run (its config.yml records no "
                               f"backend: rllib): resume it without --backend rllib")
    if _checkpoint(work) is None:
        raise AgentConfigError(f"resume: {work} has no RLlib checkpoint ({CHECKPOINT}/) to "
                               f"resume from: it stopped before its first training iteration "
                               f"ended; run its command again (without --resume) to start over")
    return work


def _complete_run(run_dir: Path, env_id: str, steps: int, env_kwargs: dict,
                  finish: dict) -> TrainResult:
    """``--resume`` of an RLlib run that has trained its budget: it trains nothing, and writes
    only what its finish asks and it lacks (stopped in its final evaluation or video)."""
    meta = run_record(run_dir / "config.yml")
    runs = meta.get("runs") or []
    missing = {"evaluate": finish["evaluate"] and not (run_dir / "summary.md").is_file(),
               "video": finish["video"] and not (run_dir / "rollout.mp4").is_file()}
    result = TrainResult(run_dir=str(run_dir), env=env_id, timesteps=steps, wall_time=0.0,
                         complete=[key for key, value in missing.items() if value],
                         sessions=len(runs),
                         total_wall_time=sum(r["wall_time_s"] for r in runs))
    policy = load_rllib_policy(run_dir)[0] if any(missing.values()) else None
    return finish_run(result, policy, env_id, run_dir, env_kwargs, run_title(meta),
                      evaluate=missing["evaluate"], eval_episodes=finish["eval_episodes"],
                      video=missing["video"])


def _check_cpus(ray, num_env_runners: int) -> None:
    """Refuse more env runners than the Ray cluster has CPUs: Ray places one runner per CPU
    and waited without end, silently, for the CPUs that were not there."""
    cpus = ray.cluster_resources().get("CPU", 0.0)
    if num_env_runners > cpus:
        raise AgentConfigError(
            f"num_env_runners: {num_env_runners} env runners need {num_env_runners} CPUs, and "
            f"the Ray cluster has {cpus:g} (Ray places one runner per CPU and would wait for "
            f"the others without end): use --num-env-runners {int(cpus)} or fewer, or a "
            f"larger cluster (--address)")


def _compile_kernels(env_id: str, env_kwargs: dict) -> None:
    """Build the runners' env here once (the native vector env; reset, one step). On a cold
    kernel cache this compiles the kernels in the driver, which says so on one line (the
    runners' output is not shown), and the runners load them from the cache; on a warm one it
    takes about half a second."""
    from spinstrike.envs.rllib import make_env

    env = make_env(env_id, {**env_kwargs, "num_envs": 1})
    try:
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, env.action_space.dtype))
    finally:
        env.close()


#: seconds a cluster's head (``--address HOST:PORT``) has to answer before the run is refused
PROBE_TIMEOUT = 5.0


def _probe(address: str) -> None:
    """Refuse an ``--address HOST:PORT`` where nothing answers, at once: ``ray.init`` retried
    it for ~14 minutes, a warning every ~35 s, before its error (RLlib walk W10: a typo or a
    head node not yet up). ``auto``, ``local`` and the like are left to Ray (it answers them at
    once); ``ray://HOST:PORT`` (Ray Client) is probed as HOST:PORT."""
    import socket

    target = address.removeprefix("ray://")
    host, sep, port = target.rpartition(":")
    if not sep or not host or not port.isdigit():
        return
    host = host.strip("[]")  # an IPv6 literal, [::1]:6379
    try:
        socket.create_connection((host, int(port)), timeout=PROBE_TIMEOUT).close()
    except OSError as exc:
        raise AgentConfigError(
            f"--address {address}: no Ray cluster to join: nothing answers at {host}:{port} "
            f"within {PROBE_TIMEOUT:g} s ({exc.strerror or exc}); start one with `ray start "
            "--head` on that machine (it prints the address to give; see docs/rllib.md), or "
            "leave --address out to train on a new local Ray") from None


def _learn(algo_config, cfg: RunConfig, work: Path, *, seed, address, num_env_runners,
           eval_every, eval_episodes_during, command, resume, finish, run_dir):
    """Build the algorithm (a resumed run: restored from its checkpoint), train to the budget
    with periodic evaluations and a checkpoint after every iteration, in ``work``. Returns
    (policy, env steps, wall time). Raises :class:`RunnersLost` where iterations stop sampling."""
    from spinstrike.agents.evaluate import run_episodes

    algo = algo_config.build_algo()
    try:
        if resume:
            ckpt = _checkpoint(work)
            done = _checkpoint_steps(work)
            algo.restore_from_path(str(ckpt.resolve()))
            # the run's history up to the checkpoint: rows and evaluations after it go
            _truncate_history(work, algo.iteration, done)
            book_resume(work, cfg, command)
        else:
            done = 0
            work.mkdir(parents=True, exist_ok=True)
            meta = {"algo": "ppo", "backend": "rllib", "env": cfg.env_id, "seed": seed,
                    "source": cfg.source, "num_env_runners": num_env_runners,
                    "num_envs_per_env_runner": algo_config.num_envs_per_env_runner,
                    "address": address, "versions": _versions(),
                    "hyperparameters": cfg.as_yaml_dict(), "finish": finish,
                    **_registered(cfg.env_id)}
            if not_used(cfg):
                meta["not_used"] = not_used(cfg)
            write_yaml(work / "config.yml", meta)
            (work / "command.txt").write_text((command or shlex.join(sys.argv)) + "\n")
            with open(work / "progress.csv", "w", newline="") as f:
                csv.writer(f).writerow(["iteration", "timesteps", "episode_return_mean",
                                        "time_s"])
        per_iter = algo_config.train_batch_size_per_learner
        iterations = max(1, math.ceil(cfg.n_timesteps / per_iter))
        every = (eval_every or max(1, iterations // 10)) * per_iter  # in env steps
        evals = _read_evaluations(work)
        start = time.time()
        steps, last, stalled = done, time.time(), 0
        next_eval = (steps // every + 1) * every
        with open(work / "progress.csv", "a", newline="") as f:
            log = csv.writer(f)
            # the budget in env steps actually sampled: an iteration whose runners were lost
            # samples nothing (it was counted as training, and the run booked as finished
            # short of its budget, exit 0: walk W26a F3)
            while steps < cfg.n_timesteps:
                result = algo.train()
                sampled = _steps(result)
                if sampled <= steps:
                    stalled += 1
                    healthy = _healthy_runners(algo)
                    if stalled == 1:
                        print(f"warning: training iteration {algo.iteration} sampled no env "
                              f"steps ({healthy} of {num_env_runners} env runners healthy); "
                              f"waiting up to {STALL_SECONDS:g} s for Ray to restore them",
                              file=sys.stderr)
                    if stalled >= STALL_ITERATIONS and time.time() - last >= STALL_SECONDS:
                        raise RunnersLost(
                            f"training stopped at {steps} of the budget's {cfg.n_timesteps} "
                            f"steps: the last {stalled} training iterations "
                            f"({time.time() - last:.0f} s) sampled no env steps, {healthy} of "
                            f"{num_env_runners} env runners healthy (lost: killed, e.g. by "
                            f"Ray's memory monitor, or their node gone; Ray's logs, "
                            f"/tmp/ray/session_latest/logs, say why). {work} keeps the run "
                            f"with its RLlib checkpoint at {steps} steps, booked as "
                            f"interrupted; continue it with spinstrike train --resume --out "
                            f"{run_dir} once the cluster has the CPUs and memory for its "
                            f"runners")
                    time.sleep(1.0)
                    continue
                steps, last, stalled = sampled, time.time(), 0
                ret = result.get("env_runners", {}).get("episode_return_mean", float("nan"))
                log.writerow([algo.iteration, steps, ret, round(time.time() - start, 3)])
                f.flush()
                if steps >= next_eval or steps >= cfg.n_timesteps:
                    next_eval = (steps // every + 1) * every
                    # the SB3 backend's episodes (EVAL_SEED), the same for every seed: they
                    # were seed + 10,000's, so two seeds' curves scored other tasks (W17)
                    ev = run_episodes(module_policy(algo.get_module()), cfg.env_id,
                                      eval_episodes_during, seed=EVAL_SEED,
                                      env_kwargs=cfg.env_kwargs)
                    evals["timesteps"].append(steps)
                    evals["results"].append(list(ev.returns))
                    evals["ep_lengths"].append([ev.mean_length] * len(ev.returns))
                    _write_evaluations(work, evals)
                # every iteration (milliseconds for these networks): a Ctrl-C or a scheduler's
                # SIGTERM loses at most the iteration it came in
                _save_checkpoint(algo, work, steps, algo.iteration)
        wall = time.time() - start
        policy = module_policy(algo.get_module())
    finally:
        algo.stop()
    plot_learning_curve(work, f"PPO (RLlib) on {cfg.env_id}")
    return policy, steps, wall


def _healthy_runners(algo) -> int:
    group = getattr(algo, "env_runner_group", None)
    try:
        return int(group.num_healthy_remote_env_runners()) if group is not None else 0
    except Exception:  # noqa: BLE001  (a message's number only)
        return 0


def _read_evaluations(work: Path) -> dict[str, list]:
    path = work / "evaluations.npz"
    if not path.is_file():
        return {"timesteps": [], "results": [], "ep_lengths": []}
    with np.load(path) as data:
        return {key: data[key].tolist() for key in ("timesteps", "results", "ep_lengths")}


def _write_evaluations(work: Path, evals: dict[str, list]) -> None:
    tmp = work / "evaluations.partial.npz"  # (np.savez adds .npz to a name without it)
    np.savez(tmp, **{key: np.array(value) for key, value in evals.items()})
    os.replace(tmp, work / "evaluations.npz")


def _truncate_history(work: Path, iteration: int, steps: int) -> None:
    """Drop ``progress.csv``'s rows after ``iteration`` and the evaluations after ``steps``:
    what a stretch logged after its last checkpoint, which the resumed run does again."""
    path = work / "progress.csv"
    if path.is_file():
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
        kept = rows[:1] + [r for r in rows[1:] if r and int(r[0]) <= iteration]
        tmp = path.with_name(path.name + ".partial")
        with open(tmp, "w", newline="") as f:
            csv.writer(f).writerows(kept)
        os.replace(tmp, path)
    evals = _read_evaluations(work)
    keep = [i for i, t in enumerate(evals["timesteps"]) if t <= steps]
    if len(keep) < len(evals["timesteps"]):
        _write_evaluations(work, {key: [value[i] for i in keep]
                                  for key, value in evals.items()})
