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
import math
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
    env_file_name,
    load_agent_config,
    run_record,
)
from spinstrike.agents.train import (
    EVAL_SEED,
    TrainResult,
    _check_entry_env_kwargs,
    _registered,
    _work_dir,
    finish_run,
    plot_learning_curve,
    run_title,
)
from spinstrike.envs import as_registered

__all__ = ["load_rllib_policy", "module_policy", "ppo_config", "train_rllib"]


#: the rl-zoo3 PPO keys ppo_config translates (of policy_kwargs: net_arch only)
_TRANSLATED = {"n_steps", "batch_size", "n_epochs", "learning_rate", "gamma", "gae_lambda",
               "clip_range", "ent_coef", "vf_coef", "policy_kwargs"}


def ppo_config(cfg: RunConfig, seed: int, num_env_runners: int):
    """RLlib's ``PPOConfig`` for an rl-zoo3 PPO entry, on the native vector env."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

    from spinstrike.envs.rllib import configure

    h = dict(cfg.model_kwargs)
    unused = sorted(set(h) - _TRANSLATED) + [
        f"policy_kwargs.{k}" for k in sorted(set(h.get("policy_kwargs") or {}) - {"net_arch"})]
    if unused:  # said, not silently dropped (config.yml still records them)
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
    import ray
    import torch

    versions = {"python": sys.version.split()[0], "numpy": np.__version__,
                "ray": ray.__version__, "gymnasium": gymnasium.__version__,
                "torch": torch.__version__}
    from spinstrike.agents.config import code_version

    return {**code_version(), **{k: str(v) for k, v in versions.items()}}


def _steps(result: dict) -> int:
    runners = result.get("env_runners", {})
    return int(runners.get("num_env_steps_sampled_lifetime", 0))


def train_rllib(env_id: str, *, config: str | Path | None = None, seed: int = 0,
                timesteps: int | None = None, out: str | Path | None = None,
                n_envs: int | None = None, num_env_runners: int = 2,
                address: str | None = None, force: bool = False, evaluate: bool = True,
                eval_episodes: int = 50, video: bool = True, env_kwargs: dict | None = None,
                eval_every: int | None = None, eval_episodes_during: int = 10,
                command: str | None = None) -> TrainResult:
    """Train PPO on ``env_id`` with RLlib; return the run directory and what was measured.

    Args:
        num_env_runners: RLlib env runner processes (each one native vector env).
        address: a running Ray cluster (``ray start --head`` prints it; ``"auto"``); default
            a local Ray started (and stopped) here, or the one already initialised.
        eval_every: training iterations between the learning curve's evaluations (default:
            about 10 over the run).
        The rest as :func:`spinstrike.agents.train.train`.
    """
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
    # as the SB3 backend: a bad argument, max_episode_steps < 1 or a control env with no step
    # limit (whose learning-curve and final evaluations in this process never ended: W17, a
    # silent hang with both cores busy) is refused here, naming it
    _check_entry_env_kwargs(env_id, cfg, env_kwargs)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32:
        raise AgentConfigError(f"seed: must be an integer from 0 to 2**32 - 1, as the SB3 "
                               f"backend's (got {seed!r})")
    if not isinstance(num_env_runners, int) or num_env_runners < 0:
        raise AgentConfigError(f"num_env_runners: must be an integer >= 0 "
                               f"(got {num_env_runners!r})")
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
    name = f"ppo-rllib-{env_file_name(env_id)}-s{seed}"
    run_dir = Path(out) if out is not None else Path("runs") / name
    work = _work_dir(run_dir, False, force)
    started = False
    if not ray.is_initialized():
        # address None: a new local Ray, as documented (Ray itself would join any cluster
        # running on this machine, e.g. another job's)
        try:
            ray.init(address=address or "local", include_dashboard=False, log_to_driver=False)
        except ConnectionError as exc:  # (was Ray's traceback, exit 1)
            raise AgentConfigError(
                f"--address {address}: no Ray cluster to join ({str(exc).splitlines()[0]}); "
                "start one with `ray start --head` (see docs/rllib.md), or leave --address out "
                "to train on a new local Ray") from None
        started = True
    try:
        _check_cpus(ray, num_env_runners)
        policy, steps, wall = _learn(algo_config, cfg, work, seed=seed, address=address,
                                     num_env_runners=num_env_runners, eval_every=eval_every,
                                     eval_episodes_during=eval_episodes_during,
                                     command=command)
        if run_dir.exists():
            shutil.rmtree(run_dir)
        work.rename(run_dir)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    finally:
        if started:
            ray.shutdown()
    result = TrainResult(run_dir=str(run_dir), timesteps=steps, wall_time=wall)
    return finish_run(result, policy, env_id, run_dir, cfg.env_kwargs,
                      run_title(run_record(run_dir / "config.yml")),
                      evaluate=evaluate, eval_episodes=eval_episodes, video=video)


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
           eval_every, eval_episodes_during, command):
    """Build the algorithm, train to the budget with periodic evaluations; save into ``work``.
    Returns (policy, env steps, wall time)."""
    from spinstrike.agents.evaluate import run_episodes

    algo = algo_config.build_algo()
    work.mkdir(parents=True, exist_ok=True)
    meta = {"algo": "ppo", "backend": "rllib", "env": cfg.env_id, "seed": seed,
            "source": cfg.source, "num_env_runners": num_env_runners,
            "num_envs_per_env_runner": algo_config.num_envs_per_env_runner,
            "address": address, "versions": _versions(),
            "hyperparameters": cfg.as_yaml_dict(), **_registered(cfg.env_id)}
    (work / "config.yml").write_text(yaml.safe_dump(meta, sort_keys=False))
    (work / "command.txt").write_text((command or shlex.join(sys.argv)) + "\n")
    per_iter = algo_config.train_batch_size_per_learner
    iterations = max(1, math.ceil(cfg.n_timesteps / per_iter))
    every = eval_every or max(1, iterations // 10)
    evals_t, evals_r, evals_l = [], [], []
    start = time.time()
    steps = 0
    try:
        with open(work / "progress.csv", "w", newline="") as f:
            log = csv.writer(f)
            log.writerow(["iteration", "timesteps", "episode_return_mean", "time_s"])
            for it in range(1, iterations + 1):
                result = algo.train()
                steps = _steps(result)
                ret = result.get("env_runners", {}).get("episode_return_mean", float("nan"))
                log.writerow([it, steps, ret, round(time.time() - start, 3)])
                f.flush()
                if it % every == 0 or it == iterations:
                    # the SB3 backend's episodes (EVAL_SEED), the same for every seed: they
                    # were seed + 10,000's, so two seeds' curves scored other tasks (W17)
                    ev = run_episodes(module_policy(algo.get_module()), cfg.env_id,
                                      eval_episodes_during, seed=EVAL_SEED,
                                      env_kwargs=cfg.env_kwargs)
                    evals_t.append(steps)
                    evals_r.append(ev.returns)
                    evals_l.append([ev.mean_length] * len(ev.returns))
                    np.savez(work / "evaluations.npz", timesteps=np.array(evals_t),
                             results=np.array(evals_r), ep_lengths=np.array(evals_l))
        wall = time.time() - start
        algo.save_to_path(str((work / "checkpoint").resolve()))
        policy = module_policy(algo.get_module())
    finally:
        algo.stop()
    plot_learning_curve(work, f"PPO (RLlib) on {cfg.env_id}")
    meta["runs"] = [{"timesteps": steps, "wall_time_s": round(wall, 2)}]
    (work / "config.yml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return policy, steps, wall
