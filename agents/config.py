"""Hyperparameter files in rl-zoo3's format, read strictly.

``configs/agents/<algo>.yml``: top-level keys are env ids (plus ``default``, used for an id that
has no entry of its own, as rl-zoo3 does); each value holds the algorithm's constructor arguments
plus rl-zoo3's reserved keys ``n_timesteps``, ``policy``, ``n_envs``, ``normalize`` and
``env_kwargs``. ``policy_kwargs`` is a YAML mapping (never a string to ``eval``); learning rates
may be ``lin_<value>`` (a linear schedule, rl-zoo3's notation). rl-zoo3 itself reads the same
files: ``python -m rl_zoo3.train --algo ppo --env SpinStrike/RodSpin-v0 --gym-packages spinstrike
-conf configs/agents/ppo.yml``.

Unknown keys, unknown ids and bad values raise :class:`AgentConfigError` naming the key and what
is allowed, before anything is created on disk.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

__all__ = ["ALGOS", "AgentConfigError", "RunConfig", "algo_class", "load_agent_config",
           "yaml_problem"]

#: algorithms the CLI trains
ALGOS = ("ppo", "sac", "td3")
RESERVED = ("n_timesteps", "policy", "n_envs", "normalize", "env_kwargs", "noise_type",
            "noise_std")
POLICY_KWARGS = ("net_arch", "activation_fn", "log_std_init", "ortho_init", "squash_output",
                 "use_sde", "full_std", "n_critics", "share_features_extractor",
                 "features_extractor_kwargs", "normalize_images", "optimizer_kwargs")
ACTIVATIONS = {"relu": "ReLU", "tanh": "Tanh", "elu": "ELU", "leaky_relu": "LeakyReLU",
               "gelu": "GELU", "silu": "SiLU"}


class AgentConfigError(ValueError):
    """An invalid hyperparameter file, entry or CLI argument; the message names the key."""


def yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML parse error on one line: where (line, column) and what."""
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
    return where + " ".join(str(problem).split())


def algo_class(algo: str):
    """The SB3 class of ``algo`` (``ppo``, ``sac`` or ``td3``)."""
    if algo not in ALGOS:
        raise AgentConfigError(f"algo: unknown algorithm {algo!r}; allowed: {list(ALGOS)}")
    import stable_baselines3 as sb3

    return getattr(sb3, algo.upper())


@dataclass
class RunConfig:
    """A resolved hyperparameter entry: what to build and how long to train."""

    algo: str
    env_id: str
    n_timesteps: int
    policy: str
    n_envs: int
    normalize: bool | dict
    env_kwargs: dict
    model_kwargs: dict = field(default_factory=dict)
    source: str = ""
    raw: dict = field(default_factory=dict)

    def as_yaml_dict(self) -> dict:
        """The entry as written in the hyperparameter file, with overrides (saved with a run)."""
        return {self.env_id: dict(self.raw, env_kwargs=self.env_kwargs) if self.env_kwargs
                else dict(self.raw)}


def packaged_config_path(algo: str) -> Path:
    """Path of the packaged ``configs/agents/<algo>.yml``."""
    return Path(str(resources.files("spinstrike.configs.agents").joinpath(f"{algo}.yml")))


def _schedule(value: Any, key: str):
    if isinstance(value, str):
        if value.startswith("lin_"):
            try:
                start = float(value[4:])
            except ValueError:
                raise AgentConfigError(f"{key}: 'lin_<number>' expected (got {value!r})") from None
            return lambda progress: progress * start
        raise AgentConfigError(f"{key}: a number or 'lin_<number>' expected (got {value!r})")
    return value


def _policy_kwargs(value: Any, where: str) -> dict:
    if not isinstance(value, dict):
        raise AgentConfigError(f"{where}.policy_kwargs: must be a YAML mapping (got "
                               f"{type(value).__name__}); strings are not evaluated")
    out = dict(value)
    for key in out:
        if key not in POLICY_KWARGS:
            raise AgentConfigError(f"{where}.policy_kwargs.{key}: unknown; allowed: "
                                   f"{list(POLICY_KWARGS)}")
    if "activation_fn" in out:
        import torch.nn as nn

        name = out["activation_fn"]
        if name not in ACTIVATIONS:
            raise AgentConfigError(f"{where}.policy_kwargs.activation_fn: unknown {name!r}; "
                                   f"allowed: {list(ACTIVATIONS)}")
        out["activation_fn"] = getattr(nn, ACTIVATIONS[name])
    return out


def _read_entry(path: Path, env_id: str) -> tuple[str, dict]:
    """The raw entry of ``env_id`` (or ``default``) in a hyperparameter file."""
    from spinstrike import envs

    if path.is_dir():
        raise AgentConfigError(f"config: {str(path)!r} is a directory, not a YAML file")
    if not path.is_file():
        raise AgentConfigError(f"config: file {str(path)!r} does not exist")
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise AgentConfigError(f"config: {path} is not valid YAML ({yaml_problem(exc)})") from None
    if not isinstance(data, dict):
        raise AgentConfigError(f"config: {path} must map env ids to hyperparameters")
    for key in data:
        if key != "default" and key not in envs.ENV_IDS:
            raise AgentConfigError(f"config: {path}: unknown env id {key!r}; allowed: "
                                   f"{list(envs.ENV_IDS) + ['default']}")
    entry_key = env_id if env_id in data else "default"
    if entry_key not in data:
        raise AgentConfigError(f"config: {path} has no entry for {env_id!r} and no 'default'")
    return entry_key, dict(data[entry_key] or {})


def _budget(entry: dict, where: str) -> tuple[int, int]:
    """Pop and check ``n_timesteps`` and ``n_envs``."""
    if "n_timesteps" not in entry:
        raise AgentConfigError(f"{where}.n_timesteps: required (training budget)")
    value = entry.pop("n_timesteps")
    try:
        n_timesteps = int(float(value))
    except (TypeError, ValueError, OverflowError):
        raise AgentConfigError(f"{where}.n_timesteps: must be a number (got {value!r})") from None
    if n_timesteps < 1:
        raise AgentConfigError(f"{where}.n_timesteps: must be >= 1 (got {n_timesteps})")
    n_envs = entry.pop("n_envs", 1)
    if not isinstance(n_envs, int) or n_envs < 1:
        raise AgentConfigError(f"{where}.n_envs: must be an integer >= 1 (got {n_envs!r})")
    return n_timesteps, n_envs


def _convert_values(entry: dict, where: str) -> None:
    """Schedules, policy kwargs, and numbers PyYAML read as strings (``1e6``), in place."""
    for key in ("learning_rate", "clip_range"):
        if key in entry:
            entry[key] = _schedule(entry[key], f"{where}.{key}")
    if "policy_kwargs" in entry:
        entry["policy_kwargs"] = _policy_kwargs(entry["policy_kwargs"], where)
    for key, value in entry.items():
        if isinstance(value, str) and key not in ("learning_rate", "clip_range", "device",
                                                  "train_freq", "noise_type"):
            try:
                entry[key] = float(value)
            except ValueError:
                pass


def load_agent_config(algo: str, env_id: str, path: str | Path | None = None,
                      overrides: dict | None = None) -> RunConfig:
    """Read and validate the entry for ``env_id`` in an rl-zoo3 hyperparameter file.

    Args:
        algo: ``ppo``, ``sac`` or ``td3``.
        env_id: a registered SpinStrike id.
        path: the YAML file; default the packaged ``configs/agents/<algo>.yml``.
        overrides: keys replacing the file's (e.g. ``{"n_timesteps": 1000}``).
    """
    cls = algo_class(algo)
    from spinstrike import envs

    if env_id not in envs.ENV_IDS:
        raise AgentConfigError(f"env: unknown id {env_id!r}; allowed: {list(envs.ENV_IDS)}")
    path = Path(path) if path is not None else packaged_config_path(algo)
    entry_key, entry = _read_entry(path, env_id)
    entry.update(overrides or {})
    raw = dict(entry)
    where = f"{path.name}[{entry_key}]"
    allowed = set(inspect.signature(cls.__init__).parameters) - {"self", "env", "policy"}
    for key in entry:
        if key not in RESERVED and key not in allowed:
            raise AgentConfigError(f"{where}.{key}: unknown key; allowed: "
                                   f"{sorted(set(RESERVED) | allowed)}")
    n_timesteps, n_envs = _budget(entry, where)
    policy = entry.pop("policy", "MlpPolicy")
    normalize = entry.pop("normalize", False)
    env_kwargs = entry.pop("env_kwargs", {}) or {}
    if not isinstance(env_kwargs, dict):
        raise AgentConfigError(f"{where}.env_kwargs: must be a mapping")
    _convert_values(entry, where)
    return RunConfig(algo, env_id, n_timesteps, policy, n_envs, normalize, env_kwargs, entry,
                     str(path), raw)
