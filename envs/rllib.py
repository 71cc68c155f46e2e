"""Ray RLlib: every SpinStrike id registered with ``ray.tune.registry.register_env``.

    from ray.rllib.algorithms.ppo import PPOConfig
    from spinstrike.envs.rllib import configure

    config = configure(PPOConfig(), "SpinStrike/RodSpinControl-v0", {"max_force": 8.0},
                       num_envs_per_env_runner=64)
    algo = config.env_runners(num_env_runners=2).build_algo()

What it takes care of (each a way the plain ``register_env`` line goes wrong):

* **Runner processes**: the creator is pickled by value; on its first call in a runner process it
  imports ``spinstrike`` from the files the driver imported (which registers the ids there too).
  Ray puts the driver's working directory first on the runners' ``sys.path``, so from the root
  of a checkout a plain import would find the checkout, not the installed package the driver
  runs. A runner without those files (another node laid out differently) imports it as usual.
* **env_config**: passed to the env as its config; :func:`configure` (and :func:`check_env_config`)
  parses it in the driver first, so a bad key raises the env's ``ConfigError`` before any runner
  starts. Gymnasium's own arguments are taken out and given to ``gym.make``:
  ``max_episode_steps``, and ``render_mode`` (what RLlib's video callbacks set). The evaluation
  runners' ``env_config`` (RLlib merges ``.evaluation(evaluation_config={"env_config": ...})``
  over the main one) is checked by :func:`configure` when set before it, else by
  :func:`check_config` (RLlib's driver says only ``IndexError`` when every runner failed).
* **Vector envs**: with ``gym_env_vectorize_mode="vector_entry_point"`` (what :func:`configure`
  sets unless ``vectorize=False``) RLlib calls the creator with ``env_config | {"num_envs": N}``;
  the creator then returns the native vector env (one batched world) in ``NEXT_STEP`` autoreset
  mode, the mode RLlib's ``SingleAgentEnvRunner`` assumes (in SAME_STEP it would take every
  episode's first step for a reset).
* **Observations**: RLlib's default model (Ray 2.60's catalog) encodes a flat vector only:
  :func:`configure` refuses ``obs_mode`` ``"dict"`` and ``"pixels"`` unless told that the config
  brings its own (``default_encoders=False``).

The RLlib names are the Gymnasium ids (``"SpinStrike/RodSpin-v0"``, ...); ``configure`` also takes
the ``"spinstrike:SpinStrike/RodSpin-v0"`` form and drops the prefix, and a variant a user
registered with ``gym.register`` (``"module:Namespace/Name-vN"``, the shipped env class with
other arguments), which runs as the shipped id with its arguments (:func:`resolve`). Importing
this module does not import Ray; :func:`register_envs` and :func:`configure` do.
"""

from __future__ import annotations

import importlib
import numbers
import os
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from spinstrike.envs import ENV_IDS
from spinstrike.envs.config import (
    GYM_ARGUMENTS,
    ConfigError,
    EnvConfig,
    episode_limit,
    parse_config,
    resolve_scene,
)

__all__ = ["RunnerSeeds", "check_config", "check_env_config", "configure", "make_env",
           "register_envs", "resolve"]

#: the prefix of Gymnasium's module-qualified ids (``"spinstrike:SpinStrike/RodSpin-v0"``)
PREFIX = "spinstrike:"


def _split(env_config: Any) -> tuple[dict, dict]:
    """(the env's own config, Gymnasium's arguments) from an RLlib env_config: ``num_envs``
    (set by RLlib for a vector env), ``max_episode_steps`` and ``render_mode``."""
    cfg = dict(env_config or {})
    return cfg, {k: cfg.pop(k) for k in ("num_envs", *GYM_ARGUMENTS) if k in cfg}


def make_env(env_id: str, env_config: Any = None) -> gym.Env | gym.vector.VectorEnv:
    """The env RLlib's creator returns: a single env, or (``num_envs`` in ``env_config``) the
    native vector env in ``NEXT_STEP`` autoreset mode. ``env_id``: as :func:`resolve` takes it
    (the runners get a shipped id: a variant is resolved in the driver)."""
    import spinstrike.envs  # noqa: F401  (a runner process: registers the ids there)

    worker = getattr(env_config, "worker_index", None)  # RLlib's EnvContext has it
    env_id, env_config = resolve(env_id, env_config)
    cfg, args = _split(env_config)
    num_envs = args.pop("num_envs", None)
    if num_envs is None:
        return gym.make(env_id, config=cfg, **args)
    return RunnerSeeds(gym.make_vec(env_id, num_envs=int(num_envs),
                                    vectorization_mode="vector_entry_point",
                                    autoreset_mode=AutoresetMode.NEXT_STEP, config=cfg, **args),
                       worker)


class RunnerSeeds(gym.vector.VectorWrapper):
    """A runner's native vector env, its elements seeded apart from the other runners'.

    RLlib resets runner ``w``'s env with ``seed + w``, and a Gymnasium vector env seeds element
    ``i`` with ``seed + i``: runner ``w``'s element ``i + 1`` drew the tasks of runner
    ``w + 1``'s element ``i`` (with 2 runners of 8 envs, 7 of 8 task streams twice in every
    batch). Here ``reset(seed=s)`` seeds element ``i`` of runner ``w`` (``worker``, the
    ``worker_index`` of RLlib's ``EnvContext``) from ``numpy.random.SeedSequence([s, w, i])``:
    no two elements of a run share a stream, nor of two runs of other seeds (``s * num_envs
    + i`` kept runs apart within, not across: ``--seed 0``'s runner 2 was ``--seed 1``'s
    runner 1, walk W26a F11). Without a worker index (``make_env`` called directly) element
    ``i`` is seeded ``s * num_envs + i``. A list of seeds passes through. Other attributes are
    the vector env's."""

    def __init__(self, env: gym.vector.VectorEnv, worker: int | None = None) -> None:
        super().__init__(env)
        self.worker = worker

    def reset(self, *, seed=None, options=None):
        if isinstance(seed, numbers.Integral) and not isinstance(seed, bool):
            if self.worker is None:
                seed = [int(seed) * self.num_envs + i for i in range(self.num_envs)]
            else:
                seed = [int(np.random.SeedSequence([int(seed), int(self.worker), i])
                            .generate_state(1)[0]) for i in range(self.num_envs)]
        return self.env.reset(seed=seed, options=options)

    def __getattr__(self, name: str):
        env = self.__dict__.get("env")  # absent while unpickling
        if env is None or name.startswith("__"):
            raise AttributeError(name)
        return getattr(env, name)


def _bare_id(env_id: str) -> str:
    """``env_id`` without the ``spinstrike:`` prefix; an unknown id raises ``ConfigError``."""
    bare = env_id.removeprefix(PREFIX) if isinstance(env_id, str) else env_id
    if bare not in ENV_IDS:
        raise ConfigError(f"env: must be one of {sorted(ENV_IDS)}, with or without the "
                          f"{PREFIX!r} prefix (got {env_id!r})")
    return bare


def resolve(env_id: str, env_config: Any = None) -> tuple[str, dict]:
    """The RLlib name and ``env_config`` that make ``env_id``'s env on the runners.

    A shipped id (with or without the ``spinstrike:`` prefix): itself, ``env_config`` as given.
    A variant registered with ``gym.register`` whose entry points are a shipped env's own
    classes (other arguments, another episode limit), given as gym.make takes it
    (``"module:Namespace/Name-vN"``): the shipped id, with the variant's registered arguments
    and ``max_episode_steps`` under ``env_config``'s keys (which win, as ``gym.make``'s
    arguments win over registered ones). The runner processes then need nothing from the
    variant's module, which they could not import (Ray starts them bare).

    Raises:
        ConfigError: an unknown id or one that is not a SpinStrike env (``envs.base_id``), a
            subclass of a shipped env (its class lives in the user's module), or a variant
            registered with Gymnasium's ``additional_wrappers`` (the runners would not wrap).
    """
    from spinstrike.envs import _entry_class, base_id, flat_kwargs, variant_kwargs

    if env_config is not None and not isinstance(env_config, Mapping):
        raise ConfigError(f"env_config: must be a mapping of the env's arguments (got "
                          f"{type(env_config).__name__} {env_config!r:.60})")
    config = dict(env_config or {})
    if isinstance(env_id, str) and env_id.removeprefix(PREFIX) in ENV_IDS:
        # a config dict among them laid flat, as for a variant (W17: refused for a shipped id
        # alone, as an unknown argument 'config')
        return env_id.removeprefix(PREFIX), flat_kwargs(config)
    try:
        base = base_id(env_id)
    except ConfigError as exc:
        raise ConfigError(f"env: {exc}") from None
    spec, shipped = gym.registry[env_id.rpartition(":")[2]], gym.registry[base]
    if (_entry_class(spec.entry_point) is not _entry_class(shipped.entry_point)
            or _entry_class(spec.vector_entry_point or shipped.vector_entry_point)
            is not _entry_class(shipped.vector_entry_point)):
        raise ConfigError(f"env: {env_id!r} registers a subclass of {base}'s env; RLlib's "
                          "runners would have to import it from your module, and Ray starts "
                          "them without it. Register the variant with the shipped env's "
                          f"classes and keyword arguments (entry_point={shipped.entry_point!r}, "
                          "kwargs={...}), or train it with the SB3 backend")
    wrappers = [w.name for w in spec.additional_wrappers or ()]
    if wrappers:  # (walk W26a F6: the runners trained it unwrapped; evaluate scored it wrapped)
        raise ConfigError(f"env: {env_id!r} is registered with additional_wrappers {wrappers}, "
                          f"which gym.make applies and RLlib's runners, which build {base} "
                          f"with the variant's arguments, would not: RLlib trains variants of "
                          f"the shipped classes and arguments only; for a changed reward or "
                          f"observation, register a subclass of the env and of its vector env "
                          f"and train it with the SB3 backend (README, 'mylab.py')")
    # gym.register(..., kwargs={"config": {...}}), the env's own config form, comes flat, as
    # env_config is (it was refused as an unknown key 'config'); so does one in env_config
    return base, {**variant_kwargs(env_id), **flat_kwargs(config)}


def _env_class(env_id: str, vector: bool = False) -> type:
    spec = gym.spec(_bare_id(env_id))
    module, name = (spec.vector_entry_point if vector else spec.entry_point).split(":")
    return getattr(importlib.import_module(module), name)


def check_env_config(env_id: str, env_config: Any = None, *, vector: bool = False) -> EnvConfig:
    """Parse ``env_config`` as the env ``env_id`` would (in this process): raises the env's
    ``ConfigError`` naming a bad key or value. ``vector``: for the native vector env (also when
    ``env_config`` holds ``num_envs``), whose ``render_mode`` can only be ``"rgb_array"``.
    ``env_id``: as :func:`resolve` takes it. Returns the parsed config."""
    return _checked_env(env_id, env_config, vector)[0][0]


def _is_grid(value: Any) -> bool:
    """Whether ``value`` is a ``tune.grid_search(...)`` (a dict of that one key)."""
    return isinstance(value, Mapping) and set(value) == {"grid_search"}


def _search_values(value: Any) -> tuple[str, list] | None:
    """The values a Tune search space can give that the driver checks: a ``grid_search``'s and a
    ``choice``'s every value, a ``uniform``/``randint``/... range's two ends (a sample can be
    either end; ``randint``'s upper end is excluded), as (what it is, values); an empty list for
    one with nothing to check (``sample_from``, ``randn``: unbounded); None for a plain value."""
    if _is_grid(value):
        return "a value of its tune.grid_search", list(value["grid_search"])
    if not type(value).__module__.startswith("ray.tune"):
        return None
    if hasattr(value, "categories"):
        return "a value of its tune.choice", list(value.categories)
    low, high = getattr(value, "lower", None), getattr(value, "upper", None)
    if low is None or high is None or not np.isfinite([low, high]).all():
        return type(value).__name__, []
    exclusive = isinstance(low, numbers.Integral) and \
        type(value.get_sampler()).__name__ == "_Uniform"  # (randint's end; qrandint's is in)
    return "an end of its range", [low, high - 1 if exclusive else high]


def _sweep_cases(env_config: Any) -> list[tuple[str, Any]]:
    """``env_config`` as the envs of a Tune sweep over it get it: for each search space in it
    (at any depth: ``randomize: {restitution: tune.grid_search(...)}``), one config per value to
    check (:func:`_search_values`) with the other spaces at their first value, each labelled by
    where the value comes from; ``[("", env_config)]`` when it holds no search space.

    Raises:
        ConfigError: a space with no values to check (``sample_from``, an unbounded ``randn``).
    """
    spaces: list[tuple[tuple, str, list]] = []

    def find(node: Any, path: tuple) -> None:
        if not isinstance(node, Mapping):
            return
        for key, value in node.items():
            found = _search_values(value)
            where = "".join(f"[{k!r}]" for k in (*path, key))
            if found is None:
                find(value, (*path, key))
            elif not found[1]:
                raise ConfigError(
                    f"env_config{where}: a Tune search space ({type(value).__name__}) with no "
                    f"values to check in the driver (a grid_search, a choice or a bounded range "
                    f"have some); leave it out of configure() and check_config(), set it after "
                    f"them, and each trial's runners check their own value only (a bad one "
                    f"fails the trial with RLlib's IndexError, the env's ConfigError in the "
                    f"console above it)")
            else:
                spaces.append(((*path, key), f"env_config{where} = {{}} ({found[0]})",
                               found[1]))

    find(env_config, ())
    if not spaces:
        return [("", env_config)]

    def put(config: Any, path: tuple, value: Any) -> Any:
        out = dict(config)
        out[path[0]] = value if len(path) == 1 else put(out[path[0]], path[1:], value)
        return out

    first = env_config
    for path, _, values in spaces:
        first = put(first, path, values[0])
    cases = []
    for path, label, values in spaces:
        cases += [(label.format(repr(v)), put(first, path, v)) for v in values]
    return cases


def _checked_env(env_id: str, env_config: Any, vector: bool) -> list[tuple[EnvConfig, tuple]]:
    """:func:`check_env_config` and the env's (observation space, action space) of every
    config a Tune sweep in ``env_config`` gives that the driver can check (:func:`_sweep_cases`:
    one, without a sweep); the first is ``env_config``'s with every space at its first value.
    A bad value's ``ConfigError`` names where in the sweep it is."""
    checked = []
    for label, concrete in _sweep_cases(env_config):
        try:
            checked.append(_checked_one(env_id, concrete, vector))
        except ConfigError as exc:
            if not label:
                raise
            raise ConfigError(f"{label}: {exc}") from None
    return checked


def _checked_one(env_id: str, env_config: Any, vector: bool) -> tuple[EnvConfig, tuple]:
    """:func:`check_env_config` of an env_config without Tune search spaces, and the env's
    (observation space, action space)."""
    env_id, env_config = resolve(env_id, env_config)
    cfg, args = _split(env_config)
    value = args.get("num_envs")
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
        raise ConfigError(f"env_config['num_envs']: must be an int >= 1 (got {value!r})")
    # as gym.make and the native vector env read it (None: the registered limit; -1: none)
    episode_limit(args.get("max_episode_steps"), gym.spec(_bare_id(env_id)).max_episode_steps,
                  "env_config['max_episode_steps']")
    env_class = _env_class(env_id, vector or "num_envs" in args)
    modes = env_class.metadata["render_modes"]
    if args.get("render_mode") not in (None, *modes):
        kind = "the native vector env" if vector or "num_envs" in args else "the env"
        raise ConfigError(f"env_config['render_mode']: must be one of {modes} or None for "
                          f"{kind} (got {args['render_mode']!r})")
    parsed = parse_config(env_class.TASK.CONFIG, cfg, {})
    # and the env itself, once: what only a built env can tell (its scene's bodies, overlaps,
    # a table too small) is refused here, not in every runner with an IndexError in the driver.
    # It is reset and stepped, as the runners will: on a cold kernel cache that compiles every
    # kernel they use here, once, and says so (reset alone left the step's kernels to each
    # runner, which compiled them silently: a first iteration ~45 s longer; RLlib walk W10)
    env = env_class(num_envs=1, config=cfg) if vector or "num_envs" in args else \
        env_class(config=cfg)
    try:
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, env.action_space.dtype))
        spaces = (getattr(env, "single_observation_space", env.observation_space),
                  getattr(env, "single_action_space", env.action_space))
    finally:
        env.close()
    return parsed, spaces


def _creator(env_id: str, init_file: str):
    """RLlib's creator of ``env_id``. A closure, so Ray pickles it by value: a runner process
    unpickles it without importing ``spinstrike``, and its first call imports the package from
    ``init_file`` (the driver's ``spinstrike/__init__.py``) when that file exists there, else
    as usual. (Ray puts the driver's working directory first on a runner's ``sys.path``: from the
    root of a checkout a plain import finds the checkout, while the driver runs the installed
    package.) Nothing here may refer to this module's globals: they would be imported."""

    def create(env_config):
        import os
        import sys

        if "spinstrike" not in sys.modules and os.path.isfile(init_file):
            import importlib.util

            spec = importlib.util.spec_from_file_location(
                "spinstrike", init_file, submodule_search_locations=[os.path.dirname(init_file)])
            module = importlib.util.module_from_spec(spec)
            sys.modules["spinstrike"] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del sys.modules["spinstrike"]
                raise
        from spinstrike.envs.rllib import make_env as make

        return make(env_id, env_config)

    return create


def register_envs() -> list[str]:
    """Register every SpinStrike id with RLlib (``ray.tune.registry.register_env``) under its
    Gymnasium id; returns the names."""
    from ray.tune.registry import register_env

    import spinstrike

    init_file = os.path.abspath(spinstrike.__file__)
    for env_id in ENV_IDS:
        register_env(env_id, _creator(env_id, init_file))
    return list(ENV_IDS)


#: the image sizes (width x height) RLlib's default CNN has layers for (Ray 2.60:
#: ``ray.rllib.models.utils.get_filter_config``)
DEFAULT_CNN_SIZES = ((42, 42), (64, 64), (84, 84), (96, 96))


def _check_default_encoders(cfg: EnvConfig) -> None:
    """Refuse the observations RLlib's default model cannot encode. Its catalog (Ray 2.60,
    ``Catalog._get_encoder_config``) has an MLP for a flat Box and a CNN for an image Box of one
    of :data:`DEFAULT_CNN_SIZES` with float pixels (its layers are float: SpinStrike's uint8
    pixels fail in the first convolution), and nothing for a Dict."""
    hint = ("use obs_mode 'vector'; from Python, with your own RLModule or an env-to-module "
            "connector that {what}, pass configure(..., default_encoders=False)")
    if cfg.obs_mode == "dict":
        raise ConfigError("obs_mode: 'dict' has no encoder in RLlib's default model (it takes "
                          "a flat vector); " + hint.format(what="flattens it "
                                                           "(FlattenObservations)"))
    if cfg.obs_mode == "pixels":
        *most, last = [f"{w}x{h}" for w, h in DEFAULT_CNN_SIZES]
        sizes = f"{', '.join(most)} or {last}"
        raise ConfigError(f"obs_mode: 'pixels' (obs_size {list(cfg.obs_size)}, uint8) does not "
                          f"work with RLlib's default model: its CNN takes float images of "
                          f"{sizes} pixels only; " + hint.format(what="converts them"))


def _read_scene(env_config: Any) -> None:
    """A ``scene`` file path in ``env_config`` read in place (as :func:`configure` reads the
    main one): the runners, whose working folder may be another, then hold the scene itself (a
    relative path in an evaluation ``env_config`` failed in every runner, an ``IndexError`` in
    the driver)."""
    if isinstance(env_config, dict) and "scene" in env_config:
        scene = env_config["scene"]
        if _is_grid(scene):  # a sweep over scenes
            env_config["scene"] = {"grid_search": [resolve_scene(s)
                                                   for s in scene["grid_search"]]}
        else:
            env_config["scene"] = resolve_scene(scene)


def _without_autoreset(env_config: dict | None, where: str) -> dict:
    """``env_config`` without Gymnasium's ``autoreset_mode``, which must be RLlib's NEXT_STEP
    (refused otherwise, naming ``where``)."""
    env_config = dict(env_config or {})
    mode = env_config.pop("autoreset_mode", None)
    if mode is not None:
        from spinstrike.envs.core import parse_autoreset_mode

        if parse_autoreset_mode(mode) != AutoresetMode.NEXT_STEP:
            raise ConfigError(f"{where}: autoreset_mode {mode!r}: RLlib's runners assume "
                              f"NEXT_STEP (in another mode they take each episode's last "
                              f"or first step for the wrong one); leave it out")
    return env_config


def _check_algorithm_env(config, where: str) -> list | None:
    """Check one ``AlgorithmConfig``'s env and ``env_config`` as its runners will make them;
    ``where`` names it in the message. Returns ``_checked_env``'s list (each env's parsed
    config and its (observation space, action space)), or None where the env is not a
    SpinStrike env (not checked)."""
    env = config.env
    if not isinstance(env, str):
        return None
    env_config = config.env_config
    if env.startswith(PREFIX) and env.removeprefix(PREFIX) in ENV_IDS:
        # RLlib makes it itself (gym.make / gym.make_vec with env_config as keyword arguments,
        # importing the package from the id): its env_config is the env's arguments, plus
        # Gymnasium's autoreset_mode for a vector env, which must be RLlib's NEXT_STEP
        env_config = _without_autoreset(env_config, where)
    elif env not in ENV_IDS:
        try:
            shipped, env_config = resolve(env, config.env_config)
        except ConfigError:
            return None  # another library's env
        raise ConfigError(f"{where}: env {env!r}: RLlib's runners make only the shipped ids "
                          f"(registered by register_envs): your module imports in a runner "
                          f"only on this machine and from this folder (Ray puts the driver's "
                          f"working directory on its path), not on other nodes; use "
                          f"{shipped!r} with env_config {env_config!r} (what "
                          f"spinstrike.envs.rllib.resolve gives)")
    vector = str(getattr(config.gym_env_vectorize_mode, "value", config.gym_env_vectorize_mode))
    try:
        return _checked_env(env, env_config, vector == "vector_entry_point")
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def _check_evaluation(config, spaces: tuple | None) -> tuple | None:
    """Check the env of ``config``'s evaluation runners, when ``.evaluation(evaluation_config=
    ...)`` changes it (RLlib merges that env_config over the main one), reading a scene file
    it names; its spaces must be the training env's (``spaces``): the evaluation runners run
    the trained module (a Dict observation failed there with RLlib's ``IndexError``, another
    env's vector after the first training iteration)."""
    override = config.evaluation_config  # a dict of overrides or a whole AlgorithmConfig
    if not override or isinstance(override, dict) and not {"env", "env_config"} & set(override):
        return None
    _read_scene(override.get("env_config") if isinstance(override, dict)
                else getattr(override, "env_config", None))
    theirs = _check_algorithm_env(config.get_evaluation_config_object(), "evaluation_config")
    theirs = None if theirs is None else theirs[0][1]
    if theirs is not None and spaces is not None and theirs != spaces:
        raise ConfigError(f"evaluation_config: its env's spaces (observations {theirs[0]}, "
                          f"actions {theirs[1]}) are not the training env's ({spaces[0]}, "
                          f"{spaces[1]}); the evaluation runners run the trained module")
    return theirs


def check_config(config, *, default_encoders: bool | None = None) -> None:
    """Check, here in the driver, the envs an RLlib ``AlgorithmConfig`` will make in its runners:
    its own env and ``env_config`` (as :func:`check_env_config`) and, when
    ``.evaluation(evaluation_config=...)`` changes them, the evaluation runners' (RLlib merges
    that ``env_config`` over the main one); registers the ids with RLlib when either env is a
    SpinStrike id. :func:`configure` does this for what is set when it is called; call this
    after setting the evaluation afterwards. Without it a bad key fails in the runners, and
    ``build_algo()`` reports only ``IndexError: list index out of range``. A ``scene`` file path
    in either env_config is read in place (the runners may start in another folder); the
    ``"spinstrike:..."`` id RLlib makes itself is checked too.

    Raises:
        ConfigError: naming ``env_config`` or ``evaluation_config``, the key and what is
            allowed; an evaluation env whose spaces are not the training env's; an
            ``autoreset_mode`` other than NEXT_STEP; a variant id
            (``"module:Namespace/Name-vN"``) set directly, which the runners cannot make; or,
            with ``default_encoders``, an ``obs_mode`` RLlib's default model cannot encode
            (``"dict"``, ``"pixels"``), as :func:`configure` refuses it. ``default_encoders``
            None: the config has no env-to-module connector and no RLModule spec of its own
            (it passed, and the runners failed with ``IndexError``, walk W22a).
    """
    _read_scene(config.env_config)
    checked = _check_algorithm_env(config, "env_config")
    ours = None if checked is None else checked[0][1]
    if default_encoders is None:
        default_encoders = (getattr(config, "_env_to_module_connector", None) is None
                            and getattr(config, "_rl_module_spec", None) is None)
    if default_encoders and checked is not None:
        try:
            for parsed, _ in checked:
                _check_default_encoders(parsed)
        except ConfigError as exc:
            raise ConfigError(f"env_config: {exc}; or check_config(..., "
                              f"default_encoders=False)") from None
    if _check_evaluation(config, ours) is not None or ours is not None:
        register_envs()


def configure(config, env_id: str, env_config: dict | None = None, *,
              num_envs_per_env_runner: int | None = None, vectorize: bool = True,
              default_encoders: bool = True):
    """Point an RLlib ``AlgorithmConfig`` at a SpinStrike env: checks ``env_config`` here (a bad
    key raises ``ConfigError`` now, not in the runners), registers the ids, and sets
    ``environment(env_id, env_config)`` and the runners' vectorisation (``vectorize``: the
    native vector env, one batched world per runner; else Gymnasium's ``SyncVectorEnv`` of
    single envs). ``env_id`` may carry the ``spinstrike:`` prefix (dropped), or name a variant
    registered with ``gym.register`` (``"module:Namespace/Name-vN"``; :func:`resolve`).
    ``default_encoders``: the config uses RLlib's default model, so an ``obs_mode`` it cannot
    encode (``"dict"``, ``"pixels"``) is refused here; pass False with your own RLModule, or a
    connector that turns the observations into what it takes. Returns ``config``."""
    # (Gymnasium's argument, not the env's: said as check_config says it, walk W22a)
    env_config = _without_autoreset(env_config, "env_config") \
        if isinstance(env_config, dict) else env_config
    env_id, env_config = resolve(env_id, env_config)
    # the scene itself, read now: the config (its pickles, the runners, a checkpoint) held the
    # path, which another folder could not open and a later edit changed
    _read_scene(env_config)
    if num_envs_per_env_runner is not None and (
            isinstance(num_envs_per_env_runner, bool)
            or not isinstance(num_envs_per_env_runner, numbers.Integral)
            or num_envs_per_env_runner < 1):  # 2.7 was 2, True was 1, "8" was 8
        raise ConfigError(f"num_envs_per_env_runner: must be an int >= 1 (got "
                          f"{num_envs_per_env_runner!r})")
    checked = _checked_env(env_id, env_config, vectorize)
    spaces = checked[0][1]
    if "num_envs" in env_config:  # RLlib replaces it (it was ignored where given alone)
        per = ("" if num_envs_per_env_runner is None
               else f" ({num_envs_per_env_runner}; the CLI's --n-envs)")
        raise ConfigError(f"env_config['num_envs']: RLlib sets each runner's envs from "
                          f"num_envs_per_env_runner{per}; pass that instead")
    if default_encoders:
        for parsed, _ in checked:
            _check_default_encoders(parsed)
    register_envs()
    config.environment(env_id)
    # exactly these arguments: RLlib's environment() merges env_config into the config's own,
    # so a config configured before for another env or variant kept that one's arguments
    # beside these (W18a: a sweep loop over variants ran DeadRod with HeavyRod's rod)
    config.env_config = dict(env_config)
    runners: dict[str, Any] = {"gym_env_vectorize_mode": ("vector_entry_point" if vectorize
                                                          else "sync")}
    if num_envs_per_env_runner is not None:
        runners["num_envs_per_env_runner"] = int(num_envs_per_env_runner)
    config.env_runners(**runners)
    # set before this call: RLlib merges its env_config over this one
    _check_evaluation(config, spaces)
    return config
