"""Evaluate policies: a trained SB3 model (deterministic), a random policy and the oracle.

Episodes run on single Gymnasium envs from seeds ``seed, seed+1, ...``, so every policy meets the
same episodes. Returns and lengths are reported as mean +/- std.
"""

from __future__ import annotations

import json
import pickle
import sys
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from spinstrike import envs  # noqa: F401  (registers the ids)
from spinstrike.agents.oracle import RandomPolicy, oracle_for

__all__ = ["Evaluation", "evaluate", "load_model_policy", "read_run_config", "summarise"]

Policy = Callable[[gym.Env, object], np.ndarray]


#: the control envs' hit anatomy (:attr:`Evaluation.hits`): key -> column heading
HIT_COLUMNS = {"hit_steps": "steps with a hit / ep.", "gained": "gained by hits / ep.",
               "lost": "lost by hits / ep."}


@dataclass
class Evaluation:
    """Returns of one policy over ``episodes`` episodes.

    ``hits`` (control envs, whose reward is paid only in steps in which the mallet touches the
    target): per-episode means of the steps with a hit (``hit_steps``), of the reward those
    steps gained (``gained``, the positive rewards) and of what they lost (``lost``, the
    negative ones: hits against the rod's spin or the puck's motion); ``gained + lost`` is the
    mean return. How a policy earns what it scores: on RodSpinControl the planner gains ~48 an
    episode in ~39 steps with a hit and loses under 1; PPO after 30M steps gains ~8 and loses ~4
    (``docs/baselines.md``, seventh session).
    None for the one-strike envs.
    """

    policy: str
    episodes: int
    mean: float
    std: float
    mean_length: float
    returns: list[float]
    hits: dict[str, float] | None = None

    @property
    def label(self) -> str:
        """The policy's name as the tables print it (``hits`` is counted on control envs)."""
        return policy_label(self.policy, control=self.hits is not None)

    def line(self) -> str:
        return (f"{self.label:>8s}: {self.mean:.4f} +/- {self.std:.4f} "
                f"over {self.episodes} episodes")


def policy_label(policy: str, control: bool) -> str:
    """A control env's reference is the scripted chase-and-hit, as the docs call it; the
    one-strike envs' is the closed-form oracle."""
    return "oracle (chase-and-hit)" if control and policy == "oracle" else policy


def run_episodes(policy: Policy, env_id: str, episodes: int, seed: int = 1000,
                 env_kwargs: dict | None = None, name: str = "policy") -> Evaluation:
    """Roll ``policy`` out for ``episodes`` episodes on seeds ``seed + k``."""
    if episodes < 1:
        from spinstrike.agents.config import AgentConfigError

        raise AgentConfigError(f"episodes: must be >= 1 (got {episodes!r})")
    env = gym.make(env_id, **(env_kwargs or {}))
    returns, lengths = [], []
    anatomy = np.zeros(3)  # steps with a hit, gained, lost (control envs)
    counts_hits = False
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        total, n, done = 0.0, 0, False
        while not done:
            obs, r, term, trunc, info = env.step(policy(env, obs))
            total += float(r)
            n += 1
            done = term or trunc
            if "reward_hit" in info:
                counts_hits = True
                if info["hits"] > 0:
                    anatomy += (1.0, max(float(r), 0.0), min(float(r), 0.0))
        returns.append(total)
        lengths.append(n)
    env.close()
    hits = (dict(zip(HIT_COLUMNS, (anatomy / episodes).tolist(), strict=True))
            if counts_hits else None)
    return Evaluation(name, episodes, float(np.mean(returns)), float(np.std(returns)),
                      float(np.mean(lengths)), returns, hits)


def read_run_config(run_dir: str | Path) -> dict:
    """A run's ``config.yml``, checked: ``algo``, ``env`` and its ``hyperparameters`` entry.

    Raises:
        AgentConfigError: naming the file and the field, for corrupt YAML or a bad field.
    """
    import yaml

    from spinstrike.agents.config import ALGOS, AgentConfigError, yaml_problem

    path = Path(run_dir) / "config.yml"
    try:
        meta = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise AgentConfigError(f"config.yml: {path} is not valid YAML "
                               f"({yaml_problem(exc)})") from None
    if not isinstance(meta, dict):
        raise AgentConfigError(f"config.yml: {path} must be a mapping with algo, env and "
                               f"hyperparameters (got {type(meta).__name__})")
    algo, env_id = meta.get("algo"), meta.get("env")
    if not isinstance(algo, str) or algo not in ALGOS:
        raise AgentConfigError(f"config.yml: {path}: algo: unknown algorithm {algo!r}; "
                               f"allowed: {list(ALGOS)}")
    try:
        envs.base_id(env_id)  # a variant's module imports (and registers it) here
    except envs.ConfigError as exc:
        raise AgentConfigError(f"config.yml: {path}: env: {exc}") from None
    hyper = meta.get("hyperparameters")
    entry = hyper.get(env_id) if isinstance(hyper, dict) else None
    if not isinstance(entry, dict) or not isinstance(entry.get("env_kwargs") or {}, dict):
        raise AgentConfigError(f"config.yml: {path}: hyperparameters: must map {env_id!r} to "
                               "its entry (env_kwargs a mapping)")
    return meta


def load_model_policy(run_dir: str | Path) -> tuple[Policy, dict]:
    """The deterministic policy of a saved run (``model.zip``, optional ``vecnormalize.pkl``)."""
    run_dir = Path(run_dir)
    meta = read_run_config(run_dir)
    return _sb3_policy(meta["algo"], run_dir / "model.zip", run_dir / "vecnormalize.pkl",
                       run_dir, meta["env"]), meta


def zoo_run_files(run_dir: str | Path) -> tuple[Path, Path] | None:
    """An rl-zoo3 run folder's (``logs/<algo>/<env>_<n>``) final model and the folder of its
    records (``<env>/``: ``args.yml``, ``config.yml``, ``vecnormalize.pkl``); None if
    ``run_dir`` is not one."""
    import re

    run_dir = Path(run_dir)
    name = re.sub(r"_\d+$", "", run_dir.name)
    model, records = run_dir / f"{name}.zip", run_dir / name
    return (model, records) if model.is_file() and (records / "args.yml").is_file() else None


def load_zoo_policy(run_dir: str | Path) -> tuple[Policy, str, dict]:
    """The deterministic policy of an rl-zoo3 run (its final model, as ``rl_zoo3.enjoy`` loads
    by default; ``vecnormalize.pkl`` if it normalised), its env id and env arguments: its
    hyperparameters' ``env_kwargs`` under its command line's (``args.yml``), as rl-zoo3 made
    the training env. Its ``--gym-packages`` are imported (they register a variant's id)."""
    import importlib

    from spinstrike.agents.config import AgentConfigError, zoo_load

    model, records = zoo_run_files(run_dir)
    args = zoo_load((records / "args.yml").read_text()) or {}
    hyper = (zoo_load((records / "config.yml").read_text())
             if (records / "config.yml").is_file() else None) or {}
    if "algo" not in args or "env" not in args:
        raise AgentConfigError(f"run_dir: {records / 'args.yml'} names no algo and env (not "
                               f"rl-zoo3's record of a run)")
    for package in args.get("gym_packages") or ():
        try:
            importlib.import_module(package)
        except ImportError as exc:
            raise AgentConfigError(f"run_dir: the run's --gym-packages {package!r} does not "
                                   f"import here ({exc})") from None
    env_id = str(args["env"])
    env_kwargs = {**(hyper.get("env_kwargs") or {}), **(args.get("env_kwargs") or {})}
    return (_sb3_policy(str(args["algo"]), model, records / "vecnormalize.pkl", Path(run_dir),
                        env_id), env_id, env_kwargs)


def _sb3_policy(algo: str, model_file: Path, norm_file: Path, run_dir: Path,
                env_id: str) -> Policy:
    """The deterministic policy of an SB3 model file (observations normalised by ``norm_file``
    where it exists)."""
    from spinstrike.agents.config import AgentConfigError, algo_class

    # an off-policy model's replay buffer is not needed to act: a HER model's (SB3 asserts it
    # gets an env to rebuild one; evaluate and record crashed, walk W21a) is built as a plain
    # one of a single transition
    off_policy = {"replay_buffer_class": None, "replay_buffer_kwargs": {}, "buffer_size": 1}
    try:
        model = algo_class(algo).load(model_file, device="cpu",
                                      custom_objects=off_policy if algo != "ppo" else None)
    # not a zip, not an SB3 model; another algorithm's (AttributeError: a PPO policy has no
    # actor for TD3, TypeError: its arguments)
    except (ValueError, KeyError, EOFError, OSError, AttributeError, TypeError) as exc:
        raise AgentConfigError(f"{model_file.name}: {model_file} could not be loaded as a "
                               f"{algo} model ({exc})") from None
    norm = None
    if norm_file.exists():
        with open(norm_file, "rb") as f:
            norm = pickle.load(f)

    def policy(env, obs):
        if norm is not None:
            obs = norm.normalize_obs(obs)
        try:
            return model.predict(obs, deterministic=True)[0]
        except (ValueError, IndexError, KeyError) as exc:
            # the env changed since training (a variant's registered arguments, an edited
            # config.yml): SB3's own error was an IndexError or a shape deep in predict
            raise AgentConfigError(
                f"run_dir: {run_dir}'s model does not take {env_id}'s observations now "
                f"(the model's space: {model.observation_space}; {type(exc).__name__}: {exc}); "
                f"was the env changed since training (a variant's registered arguments, "
                f"config.yml), or was the model trained under an observation wrapper its run "
                f"does not record (SB3's VecFrameStack)?") from None

    return policy


def evaluate(env_id: str, policy: Policy | None = None, episodes: int = 50, seed: int = 1000,
             env_kwargs: dict | None = None, baselines: bool = True,
             name: str = "agent") -> list[Evaluation]:
    """Evaluate ``policy`` (if given, reported as ``name``) and, with ``baselines``, the random
    policy and the oracle (the control envs' scripted chase-and-hit)."""
    results = []
    if policy is not None:
        results.append(run_episodes(policy, env_id, episodes, seed, env_kwargs, name))
    if baselines:
        results.append(run_episodes(RandomPolicy(seed), env_id, episodes, seed, env_kwargs,
                                    "random"))
        results.append(run_episodes(oracle_for(env_id), env_id, episodes, seed, env_kwargs,
                                    "oracle"))
        caveat = oracle_caveat(env_id)
        if caveat:
            print(f"note: {caveat}", file=sys.stderr)
    return results


def oracle_caveat(env_id: str) -> str | None:
    """What the oracle row does not mean for ``env_id`` (registered: its episodes ran): where
    its env class is a user's subclass paying in its own ``step``, the oracle (its what-if
    strikes, the control envs' chase-and-hit) aims at the task's reward, not at what that step
    pays (the oracle row sat below an agent's, walk W21b F9)."""
    from spinstrike.envs import _entry_class

    cls = _entry_class(gym.spec(env_id.rpartition(":")[2]).entry_point)
    if not getattr(getattr(cls, "step", None), "_shows_what_it_pays", False):
        return None
    return (f"{env_id}'s {cls.__name__} pays in its own step: the oracle aims at its task's "
            f"reward ({cls.TASK.__name__}), not at what that step pays, so it is no upper "
            f"reference there (a reward changed in a subclass of the task, set as TASK, is what "
            f"it aims at)")


def summarise(results: list[Evaluation], path: str | Path | None = None,
              header: str = "", fields: dict | None = None) -> str:
    """A markdown table of the results; also written as ``summary.md``/``summary.json``
    (``fields`` added to each result there: ``evaluate RUN``'s ``code_changed``)."""
    hits = any(r.hits for r in results)
    extra = "".join(f" {h} |" for h in HIT_COLUMNS.values()) if hits else ""
    lines = [header, "", "| policy | mean return | std | episodes |" + extra,
             "|---|---|---|---|" + "---|" * (len(HIT_COLUMNS) if hits else 0)]
    for r in results:
        cells = "".join(f" {r.hits[k]:.2f} |" if r.hits else " - |" for k in HIT_COLUMNS) \
            if hits else ""
        lines.append(f"| {r.label} | {r.mean:.4f} | {r.std:.4f} | {r.episodes} |" + cells)
    if hits:
        lines += ["", "Control envs pay only in steps in which the mallet touches the target: "
                  "what those steps gained and lost, per episode (gained + lost = the mean "
                  "return)."]
    text = "\n".join(lines).strip() + "\n"
    if path is not None:
        path = Path(path)
        path.mkdir(parents=True, exist_ok=True)
        (path / "summary.md").write_text(text)
        (path / "summary.json").write_text(json.dumps([{**asdict(r), **(fields or {})}
                                                        for r in results], indent=2))
    return text
