"""SpinStrike Gymnasium environments. Importing this package registers them.

    import gymnasium as gym
    import spinstrike  # registers the ids (or use "spinstrike:SpinStrike/RodSpin-v0" unimported)

    env = gym.make("SpinStrike/RodSpin-v0")
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", num_envs=1024)   # one batched world

=================================  ==========================================================
id                                 task
=================================  ==========================================================
``SpinStrike/RodSpin-v0``          one strike on a free rod; reward for reaching a target spin
``SpinStrike/PuckSpeed-v1``        one strike on a puck; reward for a target velocity
``SpinStrike/PuckSpeed-v0``        PuckSpeed with the strike heading as an angle (kept; use v1)
``SpinStrike/RodSpinControl-v0``   push a mallet on a walled table; reward for spin its hits add
``SpinStrike/PuckSpeedControl-v0`` push a mallet on a walled table; reward for speed its hits add
=================================  ==========================================================
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from spinstrike.envs.config import ConfigError

__all__ = ["ENV_IDS", "ConfigError", "as_registered", "base_id", "code_changes", "code_check",
           "code_fingerprint", "compare_code", "describe", "flat_kwargs", "native_vector",
           "registered_kwargs", "registration_changes", "scene_as_read", "unread_scene_file",
           "variant_kwargs"]

#: registered ids and a one-line description each
ENV_IDS: dict[str, str] = {
    "SpinStrike/RodSpin-v0": "one strike on a free rod; reward for reaching a target spin",
    "SpinStrike/PuckSpeed-v1": "one strike on a puck; reward for reaching a target velocity",
    "SpinStrike/PuckSpeed-v0":
        "PuckSpeed-v1 with the strike's heading as an angle (wraps at +-pi; kept, use v1)",
    "SpinStrike/RodSpinControl-v0":
        "push a mallet around a walled table; reward for the spin its hits give a rod",
    "SpinStrike/PuckSpeedControl-v0":
        "push a mallet around a walled table; reward for the speed its hits give a puck",
}

#: entry points (single env, native vector env, in ``spinstrike.envs``) and episode step limits
#: (each the vector env's ``MAX_EPISODE_STEPS``: a test checks; kept here so that registering
#: imports no env module)
_ENTRY = {
    "SpinStrike/RodSpin-v0": ("strike:RodSpinEnv", "strike:RodSpinVectorEnv", None),
    "SpinStrike/PuckSpeed-v0": ("strike:PuckSpeedEnv", "strike:PuckSpeedVectorEnv", None),
    "SpinStrike/PuckSpeed-v1": ("strike:PuckSpeedV1Env", "strike:PuckSpeedV1VectorEnv", None),
    "SpinStrike/RodSpinControl-v0": ("control:RodSpinControlEnv",
                                     "control:RodSpinControlVectorEnv", 250),
    "SpinStrike/PuckSpeedControl-v0": ("control:PuckSpeedControlEnv",
                                       "control:PuckSpeedControlVectorEnv", 250),
}


def _register() -> None:
    for env_id, (entry, vector_entry, steps) in _ENTRY.items():
        if env_id in gym.registry:
            continue
        gym.register(id=env_id, entry_point=f"spinstrike.envs.{entry}",
                     vector_entry_point=f"spinstrike.envs.{vector_entry}",
                     max_episode_steps=steps, disable_env_checker=False)


def _entry_class(entry_point):
    """The class (or factory) an entry point names."""
    from gymnasium.envs.registration import load_env_creator

    return load_env_creator(entry_point) if isinstance(entry_point, str) else entry_point


def base_id(env_id: str) -> str:
    """The shipped id whose env ``env_id`` makes: the id itself (also as
    ``"spinstrike:SpinStrike/RodSpin-v0"``), or for a variant registered elsewhere with
    ``gym.register`` and a SpinStrike env class as its entry point (that class or a subclass),
    the id of that class. A variant is given as ``"module:Namespace/Name-vN"``, ``gym.make``'s
    form, so that importing ``module`` registers it first (a plain id must be registered in
    this process already).

    Raises:
        ConfigError: an id that is not registered (the module not importable) or whose entry
            point is not a SpinStrike env class, naming it and what is allowed.
    """
    import importlib

    allowed = (f"allowed: {list(ENV_IDS)}, or a variant of one registered by your module with "
               "gym.register, given as 'module:Namespace/Name-vN'")
    if not isinstance(env_id, str):
        raise ConfigError(f"env id must be a string (got {env_id!r}); {allowed}")
    module, _, bare = env_id.rpartition(":")
    if bare in ENV_IDS:
        return bare
    if module:
        try:
            importlib.import_module(module)
        except ImportError as exc:
            # (no list of the shipped ids: the id names its module, which is what is missing,
            # walk W24b F12)
            raise ConfigError(f"{env_id!r}: cannot import {module!r}, the module that should "
                              f"register it ({exc}): run from the folder that holds "
                              f"{module.replace('.', '/')}.py, put that folder on PYTHONPATH, "
                              f"or install the module") from None
    spec = gym.registry.get(bare)
    if spec is None:
        import sys

        top = module.partition(".")[0]
        if top in sys.stdlib_module_names:  # (walk W25 F12: said "unknown id" alone)
            raise ConfigError(f"unknown id {env_id!r}: {top!r} is also a module of Python's "
                              f"standard library, which is what `import {module}` found; "
                              f"rename your module (e.g. {top}_lab.py) and the id's prefix")
        raise ConfigError(f"unknown id {env_id!r}; {allowed}")
    try:
        cls = _entry_class(spec.entry_point)
    except Exception as exc:  # noqa: BLE001  (whatever the user's entry point raises)
        raise ConfigError(f"{env_id!r}: its entry point {spec.entry_point!r} does not load "
                          f"({type(exc).__name__}: {exc})") from None
    if isinstance(cls, type):
        shipped = {base: _entry_class(f"spinstrike.envs.{entry}")
                   for base, (entry, _, _) in _ENTRY.items()}
        for base, base_cls in shipped.items():
            if cls is base_cls:
                return base
        # a subclass: the most derived shipped class it extends (PuckSpeed-v1's before v0's)
        matches = [base for base, base_cls in shipped.items() if issubclass(cls, base_cls)]
        if matches:
            return max(matches, key=lambda base: len(shipped[base].__mro__))
    raise ConfigError(f"{env_id!r}: its entry point {spec.entry_point!r} is not a SpinStrike env "
                      f"class (nor a subclass of one); {allowed}")


def flat_kwargs(kwargs: Mapping) -> dict:
    """An env's keyword arguments with a ``config`` dict among them (the env's own form,
    ``gym.register(..., kwargs={"config": {...}})``) laid flat, the other keywords winning, as
    the env merges them: one form for a run's record and for RLlib's ``env_config``. (Kept
    nested, the scene in it was recorded as a path, not as read, and ``train --backend rllib``
    refused the variant: ``config: unknown argument``.) A ``config`` that is not a mapping is
    left for the env to refuse."""
    out = dict(kwargs)
    nested = out.get("config")
    if isinstance(nested, Mapping):
        del out["config"]
        out = {**nested, **out}
    return out


def variant_kwargs(env_id: str) -> dict:
    """The keyword arguments ``env_id`` is registered with (none for a shipped id; a ``config``
    dict among them laid flat, :func:`flat_kwargs`), and its ``max_episode_steps`` if it
    registers one: what ``gym.make(env_id)`` passes its env."""
    bare = env_id.rpartition(":")[2]
    if bare in ENV_IDS:
        return {}
    base_id(env_id)  # checked, its module imported
    spec = gym.registry[bare]
    kwargs = flat_kwargs(spec.kwargs)
    if spec.max_episode_steps is not None:
        kwargs["max_episode_steps"] = spec.max_episode_steps
    return kwargs


def scene_as_read(env_id: str, env_kwargs: dict) -> dict:
    """``env_kwargs`` with the scene ``env_id``'s env is made with read in where it is a file:
    the argument's, else the one a variant registers (``variant_kwargs``). A run's
    ``config.yml`` records these, so a later edit of the file, or a run rebuilt in another
    folder, changes nothing (a variant registered with ``scene="my_table.yaml"`` recorded no
    scene, and ``evaluate`` silently rebuilt the table the file held then)."""
    from spinstrike.envs.config import resolve_scene

    out = dict(env_kwargs)
    scene = out.get("scene", variant_kwargs(env_id).get("scene"))
    if scene is not None:
        read = resolve_scene(scene)
        if "scene" in out or read is not scene:
            out["scene"] = read
    return out


def _plain(value: Any) -> Any:
    """``value`` as YAML writes and reads it back: tuples as lists, numpy values as Python's."""
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def as_registered(env_id: str, env_kwargs: dict) -> dict:
    """What a run records of its env: ``env_kwargs`` over the arguments a variant registers
    (``variant_kwargs``, its ``max_episode_steps`` included; the given win), as YAML holds
    them, a scene file read in (``scene_as_read``). ``evaluate RUN``, ``record RUN`` and
    ``--resume`` then rebuild the env trained on: only a scene file was recorded, so a dt, a
    table or a ``randomize`` range edited in the module that registers the variant silently
    changed what an old run was scored and filmed on."""
    import yaml

    out = _plain(scene_as_read(env_id, {**variant_kwargs(env_id), **flat_kwargs(env_kwargs)}))
    for key, value in out.items():
        try:
            yaml.safe_dump(value)
        except yaml.YAMLError:
            raise ConfigError(f"env: {env_id} is made with {key}={_short(value)}, which a run's "
                              f"config.yml cannot record: give or register plain values "
                              f"(numbers, strings, lists, dicts)") from None
    return out


def registered_kwargs(env_id: str) -> dict:
    """The arguments ``env_id`` registers (``variant_kwargs``; none for a shipped id), as a
    run's ``config.yml`` records them (``as_registered``)."""
    return _plain(scene_as_read(env_id, variant_kwargs(env_id)))


def registration_changes(env_id: str, env_kwargs: dict, registered: dict | None) -> list[str]:
    """Where ``env_id``'s registration now differs from what a run recorded: its
    ``env_kwargs`` (``as_registered``: what the run is rebuilt with) and ``registered``, the
    registration when it trained (None for a run recorded before 2026-11-28). Each as
    ``name (now X, the run's Y)`` (the run's is used), ``name (now X, not recorded)`` for
    one the run's record lacks, which the registration now gives, or ``name (no longer
    registered, the run's Y)`` for one the registration gave then and gives no more."""
    changes = []
    env_kwargs = flat_kwargs(env_kwargs)  # (recorded nested before 2026-11-28)
    registered = None if registered is None else flat_kwargs(registered)
    now = registered_kwargs(env_id)
    for key, value in now.items():
        if key == "scene" and unread_scene_file(value) and key in env_kwargs:
            continue  # not readable from here: nothing to compare (W17 reported it changed)
        if key not in env_kwargs:
            changes.append(f"{key} (now {_short(value)}, not recorded)")
        elif registered is not None and _plain(registered.get(key)) != value:
            changes.append(f"{key} (now {_short(value)}, the run's "
                           f"{_short(_plain(env_kwargs[key]))})")
    for key in (registered or {}).keys() - now.keys():  # (the run's env_kwargs hold it)
        changes.append(f"{key} (no longer registered, the run's "
                       f"{_short(_plain(env_kwargs.get(key, registered[key])))})")
    return changes


#: top-level packages whose modules are never the user's, wherever they are installed (an
#: editable checkout of SpinStrike, a Gymnasium from source), beside the standard library's
_LIBRARIES = frozenset({"spinstrike", "gymnasium", "gym", "numpy", "numba", "scipy", "torch",
                        "stable_baselines3", "sb3_contrib", "rl_zoo3", "ray", "pygame",
                        "imageio", "yaml"})

#: the digest of a module of the user's whose source is not readable (a class defined in a
#: script, ``__main__``, or in a module installed without its ``.py``): recorded, not compared
UNKNOWN = "unknown"


def code_fingerprint(env_id: str) -> dict[str, str]:
    """A digest of the code of each module of the user's that ``env_id`` runs: the modules
    defining its env class, its vector env class, their bases and their ``TASK`` classes, but
    SpinStrike's, Gymnasium's, the other libraries' of ``_LIBRARIES`` and the standard
    library's, wherever the module is (in the working folder, on ``PYTHONPATH`` or installed:
    an installed ``mylab`` got no digest, so a changed reward went unnoticed and identical code
    read as changed against a run trained from a folder copy, walk W24b F2); and the modules of
    the user's these import, in turn (a reward kept in a helper module): those of the same
    top-level package, or not installed (a ``weights.py`` beside ``mylab.py``). ``{module:
    digest}``, empty for a shipped id and a variant of a shipped class; ``"unknown"``
    (``UNKNOWN``) for a module whose source is not readable. The digest
    (``spinstrike.envs._digest``: ``"ast-3:<sha256>"``) is of the module's syntax tree in a
    form no Python version changes, without its docstrings and its top-level ``register(...)``
    calls: a comment or a layout changes nothing, nor does an edit of the registered arguments
    (the run records those, and ``registration_changes`` names them). A run's ``config.yml``
    records it, so ``evaluate`` / ``record`` can say when the code changed since the run
    trained (walk W21b F10), and ``train --resume`` refuses to go on with other code."""
    import sys

    bare = env_id.rpartition(":")[2]
    if bare in ENV_IDS:
        return {}
    base_id(env_id)  # checked, its module imported
    spec = gym.registry[bare]
    roots = []
    for entry in (spec.entry_point, spec.vector_entry_point):
        try:
            cls = _entry_class(entry) if entry is not None else None
        except Exception:  # noqa: BLE001  (an entry point that does not load: nothing to digest)
            cls = None
        if isinstance(cls, type):
            task = getattr(cls, "TASK", None)
            roots += [c.__module__ for c in
                      (*cls.__mro__, *(task.__mro__ if isinstance(task, type) else ()))]
    out: dict[str, str] = {}
    todo: list[tuple[str, str | None]] = [(name, None) for name in dict.fromkeys(roots)]
    while todo:  # (module, the module of the user's that imports it; None: a class's own)
        name, by = todo.pop()
        if name in out:
            continue
        read = _users_module_code(name, sys.modules.get(name), by)
        if read is None:
            continue
        out[name], imports = read
        todo += [(m, name) for m in imports if m in sys.modules and m not in out]
    return dict(sorted(out.items()))


def _users_module_code(name: str, module: Any,
                       imported_by: str | None = None) -> tuple[str, list[str]] | None:
    """``(digest, names of the modules it imports)`` of module ``name`` where it is the
    user's, else None: not of a library (``_LIBRARIES``, the standard library) and, where
    ``imported_by`` (a module of the user's) imports it, of the same top-level package or not
    installed (outside the standard library's and site-packages' folders). Its digest is
    ``UNKNOWN`` where its source is not readable (``__main__``, a script's; a module installed
    without its source)."""
    import ast
    import inspect
    import sys
    import sysconfig

    from spinstrike.envs._digest import digest

    top = name.partition(".")[0]
    if top in _LIBRARIES or top in sys.stdlib_module_names:
        return None
    if name == "__main__":
        return (UNKNOWN, []) if imported_by is None else None
    try:
        path = Path(inspect.getsourcefile(module)).resolve()
    except TypeError:  # (no source file: a compiled module, a class made at run time)
        path = None
    if imported_by is not None and top != imported_by.partition(".")[0]:
        installed = {Path(sysconfig.get_paths()[k]).resolve()
                     for k in ("stdlib", "platstdlib", "purelib", "platlib")}
        if path is None or any(path.is_relative_to(root) for root in installed):
            return None  # another package's, installed: a library's
    try:
        tree = ast.parse(path.read_text(encoding="utf-8"))
    except (AttributeError, OSError, SyntaxError, ValueError, UnicodeDecodeError):
        return UNKNOWN, []
    imports = []
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imports += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the module's package up
                parts = package.split(".")
                up = parts[:len(parts) - node.level + 1] if node.level > 1 else parts
                base = ".".join([*up, *([base] if base else [])])
            imports += [base, *(f"{base}.{alias.name}" for alias in node.names)]
    return digest(tree), imports


def compare_code(recorded: Mapping | None, now: Mapping) -> tuple[list[str], dict[str, str]]:
    """``(changed, unchecked)``: the modules of a run's :func:`code_fingerprint` record
    ``recorded`` whose code differs from ``now``'s (or that are found no more, or are no longer
    among the env's), and those that cannot be compared, each with why: recorded with another
    digest scheme (a bare sha256: ``ast.dump``'s or ``ast.unparse``'s, the forms before
    ``ast-3``; each read as changed against the other, walk W24b F4), or whose source was not
    readable then or is not now (``UNKNOWN``). Only digests of one scheme are compared; none
    where the run recorded none."""
    from spinstrike.envs._digest import SCHEME

    changed, unchecked = [], {}
    for module, then in (recorded or {}).items():
        then, digest = str(then), now.get(module)
        scheme = then.partition(":")[0] if ":" in then else None
        if then == UNKNOWN:
            unchecked[module] = "its source was not readable when the run trained"
        elif scheme != SCHEME:
            unchecked[module] = ("recorded with an older digest; not compared" if scheme is None
                                 else f"recorded with another digest ({scheme}); not compared")
        elif digest == UNKNOWN:
            unchecked[module] = "its source is not readable now"
        elif digest != then:
            changed.append(module)
    return changed, unchecked


def code_check(env_id: str, recorded: Mapping | None) -> tuple[list[str], dict[str, str]]:
    """:func:`compare_code` of a run's record ``recorded`` with ``env_id``'s code now
    (nothing where the run recorded none, or where ``env_id`` is not found now)."""
    if not recorded:
        return [], {}
    try:
        now = code_fingerprint(env_id)
    except ConfigError:
        return [], {}
    return compare_code(recorded, now)


def code_changes(env_id: str, recorded: Mapping | None) -> list[str]:
    """The modules of a run's :func:`code_fingerprint` record ``recorded`` whose code
    differs now (or that are found no more, or are no longer among ``env_id``'s); none where
    the run recorded none (:func:`code_check`'s first half: a digest of another scheme, or an
    unreadable source, is not compared)."""
    return code_check(env_id, recorded)[0]


def unread_scene_file(scene: Any) -> str | None:
    """``scene`` where it is a YAML file's path that is not found from the working directory
    (a variant registered with a relative path, used from another folder), else None."""
    from spinstrike.physics.scene import is_path, names_yaml_file

    if names_yaml_file(scene) and not is_path(Path(scene), "is_file"):
        return scene
    return None


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def native_vector(env_id: str) -> tuple[str, dict]:
    """The id and keyword arguments that build ``env_id``'s native vector env with
    ``gym.make_vec(id, n, vectorization_mode="vector_entry_point", **kwargs)``: the id itself
    where it has a vector entry point; for a variant registered without one whose entry point
    is a shipped env class itself, that class's id with the variant's registered arguments
    (:func:`variant_kwargs`), so the variant trains as it steps under ``gym.make``.

    Raises:
        ConfigError: what the batched vector env would silently not be: a subclass of a
            shipped env registered without a vector entry point, or with the shipped vector
            env itself, or with one of another ``TASK``; a registration with Gymnasium's
            ``additional_wrappers`` (``gym.make`` wraps the env, the vector env is not).
    """
    base = base_id(env_id)
    spec = gym.registry[env_id.rpartition(":")[2]]
    entry, shipped = (_entry_class(spec.entry_point),
                      _entry_class(f"spinstrike.envs.{_ENTRY[base][0]}"))
    wrappers = [w.name for w in spec.additional_wrappers or ()]
    if wrappers:  # (walk W21b: training ran the env unwrapped; evaluate and record wrapped it)
        raise ConfigError(f"{env_id!r}: registered with additional_wrappers {wrappers}, which "
                          f"gym.make applies and the batched vector env training uses does "
                          f"not: register the change as a subclass of the env and of its "
                          f"vector env instead (README, 'mylab.py')")
    if spec.vector_entry_point is not None:
        vector = _entry_class(spec.vector_entry_point)
        shipped_vector = _entry_class(f"spinstrike.envs.{_ENTRY[base][1]}")
        if entry is not shipped and vector is shipped_vector:  # the README's line, kept
            raise ConfigError(
                f"{env_id!r}: its entry point {spec.entry_point!r} subclasses {base}'s env, "
                f"but its vector_entry_point is the shipped "
                f"{_ENTRY[base][1].split(':')[1]} itself, which would train on the shipped "
                f"reward and observations: register a subclass of it that makes the same "
                f"change")
        tasks = getattr(entry, "TASK", None), getattr(vector, "TASK", None)
        if isinstance(vector, type) and tasks[0] is not tasks[1]:
            raise ConfigError(f"{env_id!r}: its env's TASK ({tasks[0].__name__}) and its vector "
                              f"env's ({getattr(tasks[1], '__name__', None)}) differ: both must "
                              f"set the same one")
        return env_id, {}
    if entry is shipped:
        return base, variant_kwargs(env_id)
    raise ConfigError(f"{env_id!r}: registered without a vector_entry_point, and its entry point "
                      f"{spec.entry_point!r} subclasses {base}'s env: the batched vector env "
                      f"training uses would not be the subclass; register a vector_entry_point "
                      f"too (a subclass of {_ENTRY[base][1].split(':')[1]})")


def describe() -> str:
    """One line per registered id."""
    return "\n".join(f"{k:34s} {v}" for k, v in ENV_IDS.items())


_register()
