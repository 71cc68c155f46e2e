"""Hyperparameter files in rl-zoo3's format, read strictly.

``configs/agents/<algo>.yml``: top-level keys are env ids (plus ``default``, used for an id that
has no entry of its own, as rl-zoo3 does); each value holds the algorithm's constructor arguments
plus rl-zoo3's reserved keys ``n_timesteps``, ``policy``, ``n_envs``, ``normalize`` and
``env_kwargs`` (SAC and TD3: also ``noise_type`` and ``noise_std``, together). ``policy_kwargs``
is a YAML mapping (never a string to ``eval``); learning rates may be ``lin_<value>`` (a linear
schedule, rl-zoo3's notation). What the command line or the run folder sets (``seed``,
``device``, ``verbose``, ``tensorboard_log``) is refused, saying what to use instead.
rl-zoo3 itself reads the same files: ``python -m rl_zoo3.train --algo ppo --env
SpinStrike/RodSpin-v0 --gym-packages spinstrike -conf configs/agents/ppo.yml``.

Unknown keys, unknown ids and bad values raise :class:`AgentConfigError` naming the key and what
is allowed, before anything is created on disk.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

__all__ = ["ALGOS", "SCHEDULE_KEYS", "AgentConfigError", "RunConfig", "algo_class", "env_file_name",
           "check_env_id", "is_run_record", "load_agent_config", "recorded_agent_config",
           "yaml_problem"]

#: algorithms the CLI trains
ALGOS = ("ppo", "sac", "td3")
RESERVED = ("n_timesteps", "policy", "n_envs", "normalize", "env_kwargs")
#: rl-zoo3's keys of the exploration noise, which it builds into SAC's and TD3's
#: ``action_noise``: both or neither (alone, rl-zoo3 passes ``noise_std`` on to the algorithm,
#: which refuses it, and fails on a ``noise_type`` without ``noise_std``)
NOISE = ("noise_type", "noise_std")
NOISE_TYPES = ("normal", "ornstein-uhlenbeck")
#: constructor arguments a file may not set, and what to do instead: the command line sets them
#: (given twice, SB3 raised a TypeError), the run folder fixes them, or SB3 needs an object
NOT_IN_FILE = {
    "seed": "the seed is the command line's: use --seed (train(seed=...)); rl-zoo3 takes it "
            "from its --seed too",
    "device": "use --device (train(device=...))",
    "verbose": "spinstrike train logs to RUN/progress.csv and RUN/tb (TensorBoard): drop it",
    "tensorboard_log": "spinstrike train writes the TensorBoard logs into the run folder, "
                       "RUN/tb (RUN: --out): drop it, or point TensorBoard at RUN/tb",
    "_init_setup_model": "SB3's internal switch; spinstrike train builds the model: drop it",
    "action_noise": "write rl-zoo3's noise_type: normal and noise_std: <std> (SAC and TD3)",
    "rollout_buffer_class": "SB3 needs a class, which a YAML file cannot give: drop it",
}
POLICY_KWARGS = ("net_arch", "activation_fn", "log_std_init", "ortho_init", "squash_output",
                 "use_sde", "full_std", "n_critics", "share_features_extractor",
                 "features_extractor_kwargs", "normalize_images", "optimizer_kwargs")
ACTIVATIONS = {"relu": "ReLU", "tanh": "Tanh", "elu": "ELU", "leaky_relu": "LeakyReLU",
               "gelu": "GELU", "silu": "SiLU"}


#: said with every ``pip install`` of an extra that brings PyTorch (else pip takes the CUDA build)
CPU_TORCH_FIRST = ("(with CPU-only PyTorch first: pip install torch --index-url "
                   "https://download.pytorch.org/whl/cpu)")


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
    #: the entry in its file, ``ppo.yml[SpinStrike/RodSpin-v0]``, for errors ("" if none)
    where: str = ""

    def as_yaml_dict(self) -> dict:
        """The entry as written in the hyperparameter file, with overrides (saved with a run)."""
        return {self.env_id: dict(self.raw, env_kwargs=self.env_kwargs) if self.env_kwargs
                else dict(self.raw)}


def env_file_name(env_id: str) -> str:
    """An env's part of file names: the shipped ids' name (``RodSpin-v0``); another namespace's
    id keeps its namespace (``MyLab-RodSpin-v0``: a variant named like a shipped env had its
    run and plot taken for the shipped env's)."""
    namespace, _, name = env_id.rpartition(":")[2].rpartition("/")
    return name if namespace in ("", "SpinStrike") else f"{namespace}-{name}"


def packaged_config_path(algo: str) -> Path:
    """Path of the packaged ``configs/agents/<algo>.yml``."""
    return Path(str(resources.files("spinstrike.configs.agents").joinpath(f"{algo}.yml")))


def _schedule(value: Any, key: str):
    if isinstance(value, str):
        try:  # a number PyYAML read as a string (3e-4: YAML 1.1 floats need a dot), as others
            return float(value)
        except ValueError:
            pass
        if value.startswith("lin_"):
            try:
                start = float(value[4:])
            except ValueError:
                raise AgentConfigError(f"{key}: 'lin_<number>' expected (got {value!r})") from None
            if not (math.isfinite(start) and start > 0):
                raise AgentConfigError(f"{key}: 'lin_<number>' needs a number > 0 (got "
                                       f"{value!r})")
            return lambda progress: progress * start
        raise AgentConfigError(f"{key}: a number or 'lin_<number>' expected (got {value!r})")
    return value


def _zoo_dict(text: str, where: str) -> dict:
    """rl-zoo3's string form of a mapping, ``"dict(log_std_init=-2, net_arch=[64, 64],
    activation_fn=nn.ReLU)"``, which rl-zoo3 evaluates as Python: read without evaluating
    anything. Taken: ``dict(...)`` with keywords or a ``{...}`` literal, nested; numbers,
    strings, booleans, None, lists and tuples of them; an activation class named as rl-zoo3
    files name it (``nn.ReLU``, ``th.nn.Tanh``, ``torch.nn.ELU``), read as its
    ``activation_fn`` name (``relu``). Anything else is refused, naming it."""
    import ast

    by_class = {cls: name for name, cls in ACTIVATIONS.items()}

    def bad(node: ast.AST, why: str):
        return AgentConfigError(f"{where}: {ast.unparse(node)!r} in {text!r}: {why}; "
                                "spinstrike reads rl-zoo3's dict(...) strings without "
                                "evaluating them (or write a YAML mapping)")

    def value(node: ast.AST) -> Any:
        if isinstance(node, ast.Call):
            return mapping(node)
        if isinstance(node, ast.Dict):
            if any(k is None for k in node.keys):
                raise bad(node, "a ** inside a mapping is not read")
            return {value(k): value(v) for k, v in zip(node.keys, node.values, strict=True)}
        if isinstance(node, ast.List | ast.Tuple):
            return [value(item) for item in node.elts]
        if isinstance(node, ast.Attribute | ast.Name):
            dotted = ast.unparse(node)
            head, _, leaf = dotted.rpartition(".")
            if head in ("", "nn", "th.nn", "torch.nn") and leaf in by_class:
                return by_class[leaf]
            raise bad(node, f"not a value or an activation (allowed: nn.<{'|'.join(by_class)}>)")
        try:
            return ast.literal_eval(node)
        except ValueError:
            raise bad(node, "not a literal") from None

    def mapping(node: ast.AST) -> dict:
        if isinstance(node, ast.Dict):
            return value(node)
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                and node.func.id == "dict" and not node.args
                and all(k.arg is not None for k in node.keywords)):
            raise bad(node, "must be dict(key=value, ...) or {...}")
        return {k.arg: value(k.value) for k in node.keywords}

    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError:
        raise AgentConfigError(f"{where}: {text!r} is neither a YAML mapping nor rl-zoo3's "
                               "dict(...) string") from None
    return mapping(tree.body)


def _policy_kwargs(value: Any, where: str) -> dict:
    if isinstance(value, str):  # rl-zoo3's "dict(...)"
        value = _zoo_dict(value, f"{where}.policy_kwargs")
    if not isinstance(value, dict):
        raise AgentConfigError(f"{where}.policy_kwargs: must be a YAML mapping or rl-zoo3's "
                               f"dict(...) string (got {type(value).__name__})")
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


def _normalize(value: Any, where: str) -> bool | dict:
    """``normalize``: true / false, or a mapping of ``VecNormalize``'s arguments (rl-zoo3's
    form), also as rl-zoo3's string, ``"dict(norm_reward=False)"`` (read, not evaluated: it
    used to be taken for plain true)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str):
        value = _zoo_dict(value, f"{where}.normalize")
    if not isinstance(value, dict):
        raise AgentConfigError(
            f"{where}.normalize: must be true, false or a mapping of VecNormalize's "
            f"arguments, e.g. {{norm_obs: true, norm_reward: false}} (got {value!r})")
    from stable_baselines3.common.vec_env import VecNormalize

    allowed = set(inspect.signature(VecNormalize.__init__).parameters) - {"self", "venv",
                                                                          "gamma"}
    unknown = sorted(set(value) - allowed)
    if unknown:
        raise AgentConfigError(f"{where}.normalize.{unknown[0]}: unknown; allowed: "
                               f"{sorted(allowed)} (gamma is the entry's own)")
    return dict(value)


def _read_entry(path: Path, env_id: str, algo: str | None = None) -> tuple[str, dict]:
    """The raw entry of ``env_id`` (or ``default``) in a hyperparameter file, or in a run's
    ``config.yml`` (``spinstrike train``'s record: its ``hyperparameters``, for its ``algo``)."""
    from spinstrike import envs
    from spinstrike.physics.scene import load_yaml

    if path.is_dir():
        raise AgentConfigError(f"config: {str(path)!r} is a directory, not a YAML file")
    if not path.is_file():
        raise AgentConfigError(f"config: file {str(path)!r} does not exist")
    text = path.read_text()
    try:
        data = load_yaml(text)
    except yaml.YAMLError as exc:
        data = _zoo_run_config(path, text, env_id, algo)
        if data is None:
            raise AgentConfigError(f"config: {path} is not valid YAML "
                                   f"({yaml_problem(exc)})") from None
    if not isinstance(data, dict):
        raise AgentConfigError(f"config: {path} must map env ids to hyperparameters")
    if is_run_record(data):
        if algo is not None and data["algo"] != algo:
            raise AgentConfigError(f"config: {path} is the record of a {data['algo']} run; its "
                                   f"hyperparameters are {data['algo']}'s (give --algo "
                                   f"{data['algo']})")
        data = data["hyperparameters"]
    for key in data:
        if key != "default" and key not in envs.ENV_IDS and key != env_id:
            try:  # a variant's own entry (its id as registered, or module-prefixed)
                envs.base_id(key)
            except envs.ConfigError as exc:
                if _unseen_variant(key, env_id):
                    continue
                raise AgentConfigError(f"config: {path}: unknown env id {key!r} ({exc}); "
                                       f"a key is an id such as these, or 'default'") from None
    # a variant without an entry of its own takes its shipped env's, as rl-zoo3 would want it
    # written out: the id as given, the id without its module, the shipped id, 'default'
    bare = env_id.rpartition(":")[2]
    keys = [env_id, bare, envs.base_id(env_id), "default"]
    entry_key = next((key for key in keys if key in data), None)
    if entry_key is None:
        raise AgentConfigError(f"config: {path} has no entry for {env_id!r} and no 'default'")
    return entry_key, dict(data[entry_key] or {})


#: the tag rl-zoo3 writes its runs' ``config.yml`` and ``args.yml`` with (an OrderedDict)
ZOO_TAG = "tag:yaml.org,2002:python/object/apply:collections.OrderedDict"


def zoo_load(text: str) -> dict | None:
    """A file rl-zoo3 wrote with :data:`ZOO_TAG` as a dict (its pairs, in order); None if
    ``text`` is not one. Nothing else of Python's is constructed."""
    from spinstrike.physics.scene import _StrictLoader

    class ZooLoader(_StrictLoader):
        pass

    def ordered(loader, node):
        args = loader.construct_sequence(node, deep=True)
        return dict(args[0]) if len(args) == 1 else None

    ZooLoader.add_constructor(ZOO_TAG, ordered)
    try:
        data = yaml.load(text, Loader=ZooLoader)  # noqa: S506 (a SafeLoader)
    except (yaml.YAMLError, TypeError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _zoo_run_config(path: Path, text: str, env_id: str, algo: str | None) -> dict | None:
    """rl-zoo3's record of a run (``logs/<algo>/<env>_<n>/<env>/config.yml``: the run's
    hyperparameters, tagged as an OrderedDict) as a hyperparameter file of one entry, for
    ``env_id``; the ``env_kwargs`` its ``args.yml`` (beside it) holds from rl-zoo3's command
    line go over the entry's, as rl-zoo3 took them. None if ``text`` is not such a record.

    Raises:
        AgentConfigError: ``args.yml`` names another algorithm or env than this run's.
    """
    entry = zoo_load(text)
    if entry is None:
        return None
    args = {}
    if (path.parent / "args.yml").is_file():
        args = zoo_load((path.parent / "args.yml").read_text()) or {}
    trained = args.get("algo")
    if algo is not None and trained is not None and trained != algo:
        raise AgentConfigError(f"config: {path} is rl-zoo3's record of a {trained} run; its "
                               f"hyperparameters are {trained}'s (give --algo {trained})")
    env = args.get("env")
    if env is not None and str(env).rpartition(":")[2] != env_id.rpartition(":")[2]:
        raise AgentConfigError(f"config: {path} is rl-zoo3's record of a run on {env!r}, not "
                               f"{env_id!r} (give --env {env})")
    if args.get("env_kwargs"):
        entry["env_kwargs"] = {**(entry.get("env_kwargs") or {}), **args["env_kwargs"]}
    return {env_id: entry}


def _unseen_variant(key: Any, env_id: str) -> bool:
    """Whether a hyperparameter file's unregistered ``key`` is a plain id in a namespace of the
    user's own that this run does not load: another variant's entry, whose module (not named by
    the plain id) registers it only when that variant is trained. Such a key is skipped, as
    rl-zoo3 skips every other entry. Checked (so a typo is refused): a module-prefixed key (its
    module is there to import), an id in SpinStrike's namespace or in none, and an id in the
    namespace of the env being trained, whose module has been imported by now."""
    from gymnasium.envs.registration import parse_env_id
    from gymnasium.error import Error

    if not isinstance(key, str) or ":" in key:
        return False
    try:
        namespace = parse_env_id(key)[0]
        trained = parse_env_id(env_id.rpartition(":")[2])[0]
    except Error:
        return False
    return namespace not in (None, "SpinStrike", trained)


def _budget(entry: dict, where: str) -> tuple[int, int]:
    """Pop and check ``n_timesteps`` and ``n_envs``."""
    if "n_timesteps" not in entry:
        raise AgentConfigError(f"{where}.n_timesteps: required (training budget)")
    value = entry.pop("n_timesteps")
    try:
        if isinstance(value, bool):
            raise TypeError
        number = float(value)
    except (TypeError, ValueError):
        raise AgentConfigError(f"{where}.n_timesteps: must be a number (got {value!r})") from None
    if not (math.isfinite(number) and number.is_integer()):  # as --timesteps: not truncated
        raise AgentConfigError(f"{where}.n_timesteps: must be a whole number of steps (got "
                               f"{value!r})")
    n_timesteps = int(number)
    if n_timesteps < 1:
        raise AgentConfigError(f"{where}.n_timesteps: must be >= 1 (got {n_timesteps})")
    n_envs = entry.pop("n_envs", 1)
    if isinstance(n_envs, bool) or not isinstance(n_envs, int) or n_envs < 1:
        raise AgentConfigError(f"{where}.n_envs: must be an integer >= 1 (got {n_envs!r})")
    return n_timesteps, n_envs


#: the keys whose ``lin_<number>`` strings are schedules (rl-zoo3's)
SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")


def is_run_record(data: Any) -> bool:
    """Whether YAML ``data`` is a run's ``config.yml`` (``spinstrike train``'s record: ``algo``,
    ``env``, ``hyperparameters``), not a hyperparameter file."""
    return isinstance(data, dict) and isinstance(data.get("hyperparameters"), dict) \
        and "algo" in data


def run_record(path: str | Path) -> dict:
    """The record a run's ``config.yml`` holds, as written; empty for a file that is missing,
    unreadable or not a run's record (what to do then is the caller's: reading it as a
    hyperparameter file, or having nothing to compare)."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError, ValueError):
        return {}
    return data if is_run_record(data) else {}


def short_value(value: Any, width: int = 40) -> str:
    """``value`` as a title or a line shows it: a number or string as is, anything else its
    repr, cut to ``width`` characters (a scene read in is a long dict)."""
    text = value if isinstance(value, str) else repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."


def _convert_values(entry: dict, where: str) -> None:
    """Schedules, policy kwargs, and numbers PyYAML read as strings (``1e6``), in place."""
    for key in SCHEDULE_KEYS:
        if key in entry and entry[key] is not None:
            entry[key] = _schedule(entry[key], f"{where}.{key}")
    if isinstance(entry.get("train_freq"), list):  # [1, "episode"]: a tuple, as rl-zoo3 does
        entry["train_freq"] = tuple(entry["train_freq"])
    if "policy_kwargs" in entry:
        entry["policy_kwargs"] = _policy_kwargs(entry["policy_kwargs"], where)
    for key, value in entry.items():
        if isinstance(value, str) and key not in (*SCHEDULE_KEYS, "device", "train_freq",
                                                  "noise_type"):
            try:
                entry[key] = float(value)
            except ValueError:
                pass


def _integer(low: int, also: tuple = ()):
    def check(v):
        return v in also or (isinstance(v, (int, float)) and not isinstance(v, bool)
                             and float(v).is_integer() and v >= low)
    check.integer = True  # an integral float (PyYAML's 1e5) is stored as an int
    return check


def _number(low: float, high: float = math.inf, low_open: bool = False):
    def check(v):
        return (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                and (v > low if low_open else v >= low) and v <= high)
    return check


def _flag(v) -> bool:
    return isinstance(v, bool)


#: SB3's numeric hyperparameters: how each is checked and what to say when it fails (SB3 itself
#: fails late, deep in torch or its own code, or not at all: a negative learning rate raised in
#: torch's optimiser, a string n_steps in a comparison)
_VALUES: dict[str, tuple[Any, str]] = {
    "n_steps": (_integer(1), "an integer >= 1"),
    "batch_size": (_integer(1), "an integer >= 1"),
    "n_epochs": (_integer(1), "an integer >= 1"),
    "buffer_size": (_integer(1), "an integer >= 1"),
    "learning_starts": (_integer(0), "an integer >= 0"),
    "gradient_steps": (_integer(1, (-1,)), "an integer >= 1, or -1 (as many as env steps)"),
    "policy_delay": (_integer(1), "an integer >= 1"),
    "target_update_interval": (_integer(1), "an integer >= 1"),
    "sde_sample_freq": (_integer(-1), "an integer >= -1"),
    "seed": (_integer(0), "an integer >= 0"),
    "verbose": (_integer(0), "an integer >= 0"),
    "gamma": (_number(0.0, 1.0), "a number in [0, 1]"),
    "gae_lambda": (_number(0.0, 1.0), "a number in [0, 1]"),
    "tau": (_number(0.0, 1.0, low_open=True), "a number in (0, 1]"),
    "vf_coef": (_number(0.0), "a number >= 0"),
    "max_grad_norm": (_number(0.0, low_open=True), "a number > 0"),
    "target_policy_noise": (_number(0.0), "a number >= 0"),
    "target_noise_clip": (_number(0.0), "a number >= 0"),
    "noise_std": (_number(0.0), "a number >= 0"),
    "target_kl": (lambda v: v is None or _number(0.0, low_open=True)(v), "a number > 0 or null"),
    "use_sde": (_flag, "true or false"),
    "normalize_advantage": (_flag, "true or false"),
    "optimize_memory_usage": (_flag, "true or false"),
}


def _check_values(entry: dict, where: str) -> None:
    """Refuse values SB3 would fail on late or misuse silently, naming the key and what is
    allowed; integral floats (PyYAML reads ``1e5`` as a float) become ints."""
    for key in ("learning_rate", "clip_range"):
        value = entry.get(key)
        if value is not None and not callable(value) and not _number(0.0, low_open=True)(value):
            raise AgentConfigError(f"{where}.{key}: must be a number > 0 or 'lin_<number>' "
                                   f"(got {value!r})")
    ent = entry.get("ent_coef")
    if ent is not None and not (_number(0.0)(ent) or (isinstance(ent, str)
                                                       and ent.startswith("auto"))):
        raise AgentConfigError(f"{where}.ent_coef: must be a number >= 0, or 'auto' / "
                               f"'auto_<initial value>' for SAC (got {ent!r})")
    for key, (check, what) in _VALUES.items():
        if key in entry and not check(entry[key]):
            raise AgentConfigError(f"{where}.{key}: must be {what} (got {entry[key]!r})")
        if getattr(check, "integer", False) and isinstance(entry.get(key), float):
            entry[key] = int(entry[key])


def load_agent_config(algo: str, env_id: str, path: str | Path | None = None,
                      overrides: dict | None = None) -> RunConfig:
    """Read and validate the entry for ``env_id`` in an rl-zoo3 hyperparameter file.

    Args:
        algo: ``ppo``, ``sac`` or ``td3``.
        env_id: a registered SpinStrike id.
        path: the YAML file; default the packaged ``configs/agents/<algo>.yml``.
        overrides: keys replacing the file's (e.g. ``{"n_timesteps": 1000}``).
    """
    algo_class(algo)  # an unknown algorithm first, then an unknown id, then the file
    check_env_id(env_id)
    path = Path(path) if path is not None else packaged_config_path(algo)
    entry_key, entry = _read_entry(path, env_id, algo)
    entry.update(overrides or {})
    return _resolve(algo, env_id, entry, f"{path.name}[{entry_key}]", str(path))


def recorded_agent_config(algo: str, env_id: str, entry: dict, source: str) -> RunConfig:
    """A run's entry as its ``config.yml`` recorded it (``hyperparameters[env_id]``), validated
    as a hyperparameter file's; ``source`` is the file it was first read from."""
    check_env_id(env_id)
    return _resolve(algo, env_id, dict(entry), f"config.yml[{env_id}]", source)


def check_env_id(env_id: str, field: str = "env") -> str:
    """Refuse an id that is not a SpinStrike env, naming ``field``; return its shipped id (the
    id itself, or the one whose env a registered variant makes: ``envs.base_id``)."""
    from spinstrike import envs

    try:
        return envs.base_id(env_id)
    except envs.ConfigError as exc:
        raise AgentConfigError(f"{field}: {exc}") from None


def _check_keys(algo: str, entry: dict, where: str) -> None:
    """Refuse a key the algorithm does not take, one the file may not set (``NOT_IN_FILE``) and
    half of the exploration noise, naming it and what is allowed or what to do instead."""
    cls = algo_class(algo)
    reserved = set(RESERVED) | (set(NOISE) if algo != "ppo" else set())
    allowed = (set(inspect.signature(cls.__init__).parameters) - {"self", "env", "policy"}
               - set(NOT_IN_FILE)) | reserved
    for key in entry:
        if key in NOT_IN_FILE and key in inspect.signature(cls.__init__).parameters:
            raise AgentConfigError(f"{where}.{key}: not set by a hyperparameter file (got "
                                   f"{entry[key]!r}); {NOT_IN_FILE[key]}")
        if key in NOISE and algo == "ppo":
            raise AgentConfigError(f"{where}.{key}: PPO takes no action noise (noise_type and "
                                   f"noise_std are SAC's and TD3's); PPO explores by its "
                                   f"policy's std: policy_kwargs.log_std_init, or use_sde")
        if key not in allowed:
            raise AgentConfigError(f"{where}.{key}: unknown key; allowed: {sorted(allowed)}")
    given = [key for key in NOISE if key in entry]
    if len(given) == 1:
        missing = "noise_std: <std>" if given == ["noise_type"] else "noise_type: normal"
        raise AgentConfigError(f"{where}.{given[0]}: needs {missing} beside it (rl-zoo3 builds "
                               f"the exploration noise from both; alone it is no noise)")
    if "noise_type" in entry and entry["noise_type"] not in NOISE_TYPES:
        raise AgentConfigError(f"{where}.noise_type: unknown {entry['noise_type']!r}; allowed: "
                               f"{list(NOISE_TYPES)}")


def _resolve(algo: str, env_id: str, entry: dict, where: str, source: str) -> RunConfig:
    raw = dict(entry)
    _check_keys(algo, entry, where)
    n_timesteps, n_envs = _budget(entry, where)
    policy = entry.pop("policy", "MlpPolicy")
    normalize = _normalize(entry.pop("normalize", False), where)
    if "replay_buffer_class" in entry:  # rl-zoo3 turns its string into a class; SB3 needs one
        raise AgentConfigError(
            f"{where}.replay_buffer_class: not supported by spinstrike train (got "
            f"{entry['replay_buffer_class']!r}); for HER (obs_mode: dict), train with SB3's "
            f"HerReplayBuffer directly or with rl_zoo3.train")
    env_kwargs = entry.pop("env_kwargs", {}) or {}
    if not isinstance(env_kwargs, dict):
        raise AgentConfigError(f"{where}.env_kwargs: must be a mapping")
    _convert_values(entry, where)
    _check_values(entry, where)
    if algo == "ppo" and isinstance(entry.get("ent_coef"), str):  # failed inside learn()
        raise AgentConfigError(f"{where}.ent_coef: a number >= 0 for PPO; 'auto' is SAC's "
                               f"(got {entry['ent_coef']!r})")
    return RunConfig(algo, env_id, n_timesteps, policy, n_envs, normalize, env_kwargs, entry,
                     source, raw, where)


#: the file a wheel's build writes the commit it was built from into, at the package's top
#: (``setup.py``'s ``build_py``): an installed wheel has no ``.git`` to ask
BUILD_COMMIT_FILE = "_build_commit.txt"


def commit() -> str:
    """The commit of the code that runs (the checkout this module is in; not the folder the
    command runs from, which recorded another repository's commit), ``+dirty`` where tracked
    files are edited. Where git gives none (walk W24b F9: all of these said "unknown", which
    the help explained as a wheel):

    * git refuses the checkout (another user's: "dubious ownership", ``safe.directory``), or
      is not installed: the commit read from the checkout's ``.git`` (``HEAD`` and its ref),
      with ``(edits unchecked: <why>)`` (asking git about edits would run another user's
      configuration: what ``safe.directory`` guards against);
    * no checkout (an installed wheel): the commit its build stamped into the package
      (:data:`BUILD_COMMIT_FILE`);
    * else ``unknown: <why>``: ``not a git checkout`` (a copy without ``.git``, a wheel built
      from one), ``git refused (safe.directory)`` (and ``.git`` unreadable)."""
    import subprocess

    here = Path(__file__).resolve().parent
    checkout = here.parent  # a source checkout's root (agents/ is at its top)

    def git(*args: str) -> str:
        return subprocess.run(["git", "-C", str(here), *args], capture_output=True, text=True,
                              check=True).stdout.strip()

    refused = None
    try:
        # this file tracked there: an installed copy inside some repository is not its code
        git("ls-files", "--error-unmatch", Path(__file__).name)
        head = git("rev-parse", "--short", "HEAD")
        # edited and not committed: the commit alone named code that no longer matches (W16)
        edited = git("status", "--porcelain", "--untracked-files=no")
        return head + ("+dirty" if edited else "")
    except OSError:
        refused = "git not found"
    except subprocess.CalledProcessError as exc:
        if "safe.directory" in (exc.stderr or "") or "dubious ownership" in (exc.stderr or ""):
            refused = "git refused (safe.directory)"
    if refused is not None and (checkout / ".git").exists():
        head = _read_git_head(checkout / ".git")
        return f"{head} (edits unchecked: {refused})" if head else f"unknown: {refused}"
    try:
        stamp = (checkout / BUILD_COMMIT_FILE).read_text().strip()
    except OSError:
        stamp = ""
    return stamp or "unknown: not a git checkout"


def _read_git_head(dotgit: Path) -> str | None:
    """The short commit ``dotgit``'s ``HEAD`` names, read from its files (no git: nothing of
    the repository's configuration runs): a detached ``HEAD``, or its branch's ref file or
    line of ``packed-refs``; a worktree's ``.git`` file followed. None if unreadable."""
    import re

    try:
        gitdir = dotgit
        if dotgit.is_file():  # a worktree or submodule: "gitdir: <path>"
            text = dotgit.read_text().strip()
            if not text.startswith("gitdir:"):
                return None
            gitdir = (dotgit.parent / text[len("gitdir:"):].strip()).resolve()
        common = gitdir
        if (gitdir / "commondir").is_file():
            common = (gitdir / (gitdir / "commondir").read_text().strip()).resolve()
        sha = (gitdir / "HEAD").read_text().strip()
        if sha.startswith("ref:"):
            ref = sha[len("ref:"):].strip()
            loose = [base / ref for base in (gitdir, common) if (base / ref).is_file()]
            if loose:
                sha = loose[0].read_text().strip()
            else:
                packed = common / "packed-refs"
                lines = packed.read_text().splitlines() if packed.is_file() else []
                sha = next((line.split()[0] for line in lines
                            if line.split()[1:] == [ref] and not line.startswith("#")), "")
    except (OSError, UnicodeDecodeError):
        return None
    return sha[:7] if re.fullmatch(r"[0-9a-f]{40}([0-9a-f]{24})?", sha) else None


def version_changes(recorded: dict | None, now: dict | None = None) -> list[str]:
    """The entries of a run's ``versions`` record (SpinStrike's version and commit, Python's,
    the libraries') that differ from what runs now, each ``"numpy 2.4.6 (now 2.5.5)"``; a
    library not installed now is left out. ``now``: :func:`code_version`'s, where the caller
    has it (it asks git three times). A run evaluated, filmed or resumed at another commit or
    with other libraries said nothing of it (walk W24b F5)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    if now is None:
        now = code_version() if recorded else {}
    out = []
    for key, then in (recorded or {}).items():
        if key in now:
            current = now[key]
        elif key == "python":
            current = platform.python_version()
        else:
            try:
                current = version(key)
            except (PackageNotFoundError, ValueError):
                continue
        if str(current) != str(then):
            out.append(f"{key} {then} (now {current})")
    return out


def code_version() -> dict[str, str]:
    """SpinStrike's version and commit (:func:`commit`: ``unknown: <why>`` where it cannot be
    known), which a run records beside its libraries' versions: builds share one version
    number, so the commit tells them apart. ``spinstrike --version`` prints the same."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        number = version("spinstrike")
    except PackageNotFoundError:  # the source tree on sys.path, never installed
        number = "unknown"
    return {"spinstrike": number, "spinstrike_commit": commit()}
