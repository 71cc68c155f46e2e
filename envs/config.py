"""Environment configuration: constructor keyword arguments, or one ``config`` dict (Ray RLlib).

Every env validates its arguments into a frozen pydantic model; an unknown key or a bad value
raises :class:`ConfigError` naming the field and what is allowed. Scenes ship inside the package
(``configs/scenes/*.yaml``) and load from a plain ``pip install .`` as well as from a checkout.
"""

from __future__ import annotations

import copy
import math
import numbers
import os
from collections.abc import Iterator, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from spinstrike.physics import EFFECTS, SceneError, World, load_scene
from spinstrike.physics.scene import (
    UNION_MEMBER,
    WALL_NAMES,
    Body,
    Integer,
    Number,
    Scene,
    is_path,
    join_by_field,
    packaged_scene,
    read_scene,
    solver_over,
)

__all__ = [
    "ConfigError",
    "ControlConfig",
    "EnvConfig",
    "PuckSpeedConfig",
    "RodSpinConfig",
    "load_packaged_scene",
    "parse_config",
    "resolve_scene",
]


#: the smallest and largest width or height of a rendered frame, in pixels
FRAME_SIZES = (16, 4096)


def size_problem(size: Any) -> str | None:
    """What is wrong with a frame's ``(width, height)`` (None: nothing)."""
    low, high = FRAME_SIZES
    if not all(low <= side <= high for side in size):
        return f"must be two sizes in [{low}, {high}] pixels (got {tuple(size)})"
    return None


class ConfigError(ValueError):
    """An invalid env argument. The message names the argument and what is allowed."""


#: a (low, high) pair of numbers (strings and booleans are refused)
Range = tuple[Number, Number]


class EnvConfig(BaseModel):
    """Arguments shared by every SpinStrike env.

    Attributes:
        scene: a scene (path, YAML string or dict) replacing the packaged one; its body names must
            match (``striker``/``mallet`` and ``rod``/``puck``). The env places its bodies at
            every reset, so their positions in the scene are not used.
        solver: solver block, e.g. ``{"mode": "fixed", "substeps": 8}`` or ``"pymunk"``: of the
            scene's mode, its keys override the scene's and the scene's others stay (RodSpin's
            ``settle_substep``); of another mode, it replaces the scene's block.
        effects: effect list replacing the scene's.
        restitution: e in [0, 1] of the target's pair with the striker or mallet (the one the
            observation shows; a scene's own value for that pair too), and of every pair the
            scene sets no value for (the packaged control scenes set the cushions').
        friction: contact friction mu >= 0 (needs ``contact_friction``; added when > 0), set as
            ``restitution`` is.
        table_friction: cloth friction mu_t >= 0 (needs ``table_friction``; added when > 0).
        randomize: ranges ``{param: [low, high]}`` drawn per episode (masses log-uniformly, the
            rest uniformly); the allowed params are listed by each env (``None``: none).
        obs_mode: ``vector`` (flat Box), ``dict`` (goal-conditioned, target envs) or ``pixels``.
        render_size: (width, height) of the video frames ``render()`` returns, pixels (the
            whole table, or the strike's surroundings on an unbounded plane, stays in view).
        obs_size: (width, height) of the pixel observations (``obs_mode='pixels'``), pixels;
            independent of ``render_size``, so a bigger video leaves the observations alone.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    scene: str | dict | None = None
    solver: dict | str | None = None
    effects: tuple[str, ...] | None = None
    restitution: Number | None = Field(None, ge=0.0, le=1.0)
    friction: Number | None = Field(None, ge=0.0)
    table_friction: Number | None = Field(None, ge=0.0)
    randomize: dict[str, Range] = Field(default_factory=dict)
    obs_mode: Literal["vector", "dict", "pixels"] = "vector"
    render_size: tuple[Integer, Integer] = (720, 480)
    obs_size: tuple[Integer, Integer] = (480, 320)

    #: parameters ``randomize`` may name (set by subclasses)
    RANDOMIZABLE: ClassVar[tuple[str, ...]] = ()

    @field_validator("scene", mode="before")
    @classmethod
    def _path(cls, v):
        try:
            # a deep copy: pydantic copies a dict one level deep, so nested lists and dicts
            # stayed the caller's, and a sweep editing its dict changed the env's copies
            return copy.deepcopy(resolve_scene(v))
        except SceneError as exc:
            raise ValueError(str(exc).removeprefix("scene: ")) from None

    @field_validator("effects")
    @classmethod
    def _known_effects(cls, v):
        if v is not None:
            for e in v:
                if e not in EFFECTS:
                    raise ValueError(f"unknown effect {e!r}; allowed: {sorted(EFFECTS)}")
        return v

    @field_validator("render_size", "obs_size")
    @classmethod
    def _size(cls, v):
        problem = size_problem(v)
        if problem:
            raise ValueError(problem)
        return v

    @field_validator("randomize", mode="before")
    @classmethod
    def _none_is_empty(cls, v):
        # randomize=None reads "none", as a script's cfg.get("randomize") passes it (walk W28a
        # F6: refused with "Input should be a valid dictionary")
        return {} if v is None else v

    @field_validator("randomize")
    @classmethod
    def _ranges(cls, v):
        allowed = cls.RANDOMIZABLE
        for key, (lo, hi) in v.items():
            if key not in allowed:
                raise ValueError(f"unknown parameter {key!r}; allowed: {list(allowed)}")
            if not lo <= hi:
                raise ValueError(f"{key}: needs low <= high (got [{lo}, {hi}])")
            if key.endswith("mass") and lo <= 0:
                raise ValueError(f"{key}: masses must be > 0 (got [{lo}, {hi}])")
            if key == "rod_length" and lo <= 0:
                raise ValueError(f"{key}: must be > 0, as rod_length (got [{lo}, {hi}])")
            if key == "restitution" and not (0 <= lo and hi <= 1):
                raise ValueError(f"restitution: must lie in [0, 1] (got [{lo}, {hi}])")
            if lo < 0:
                raise ValueError(f"{key}: must be >= 0 (got [{lo}, {hi}])")
        return v


class _StrikeConfig(EnvConfig):
    """One-strike envs.

    Attributes:
        speed_range: (min, max) strike speed of the striker, m/s.
        approach_max: largest approach angle from the target's normal, degrees.
        time_cap: simulated time after which a strike ends whatever happens, s.
        striker_mass, target_mass: kg (``target`` = the rod or the puck).
    """

    speed_range: Range = (0.5, 4.0)
    approach_max: Number = Field(75.0, gt=0.0, lt=90.0)
    time_cap: Number = Field(2.0, gt=0.0, le=60.0)
    striker_mass: Number | None = Field(None, gt=0.0)
    target_mass: Number | None = Field(None, gt=0.0)

    _speed_range = field_validator("speed_range")(lambda v: _positive_range(v, "m/s"))


#: the strike envs' achieved and desired goals (``obs_mode='dict'``) lie in +-GOAL_BOUND times the
#: largest target, per component
GOAL_BOUND = 5.0
#: what a spin or velocity clipped to GOAL_BOUND may still be paid (see _goal_width)
GOAL_CLIP_REWARD = 1e-6


def _goal_width(cfg) -> None:
    """In ``obs_mode='dict'`` the reward is the goals' as the observation shows them, so an
    achieved goal beyond ``GOAL_BOUND`` times the largest target is clipped there and paid as if
    it were on the bound. That is harmless where the bound pays nothing: the most it pays is at
    the largest target, ``exp(-((GOAL_BOUND - 1) / reward_width)^2 / 2)``. A wider reward made
    two different spins pay the same and the dict reward differ from the vector one by ~10 %."""
    if cfg.obs_mode != "dict":
        return
    paid = math.exp(-0.5 * ((GOAL_BOUND - 1.0) / cfg.reward_width) ** 2)
    if paid > GOAL_CLIP_REWARD:
        widest = (GOAL_BOUND - 1.0) / math.sqrt(-2.0 * math.log(GOAL_CLIP_REWARD))
        # printed rounded down: 0.76096 printed as 0.761 refused 0.761 "at most 0.761"
        raise ValueError(f"reward_width: with obs_mode='dict' at most "
                         f"{math.floor(widest * 1e4) / 1e4:.4f} (got "
                         f"{cfg.reward_width}): the achieved goal is clipped at {GOAL_BOUND:g} "
                         f"times the largest target, where this width still pays {paid:.2g}, "
                         f"so a result beyond it would be paid as if on it")


class RodSpinConfig(_StrikeConfig):
    """``SpinStrike/RodSpin-v0``.

    Attributes:
        goal: ``target`` (reach a target spin drawn per episode) or ``max`` (most spin).
        target_spin: (min, max) magnitude of the target spin, rad/s; its sign is drawn too.
        reward_width: the reward's width sigma, as a fraction of the target's magnitude.
        rod_length, rod_thickness: m.  rod_inertia: ``capsule`` (exact), ``thin_rod``
            (the seed's m r^2/3) or a number, kg m^2.
    """

    RANDOMIZABLE: ClassVar[tuple[str, ...]] = ("striker_mass", "target_mass", "restitution",
                                               "rod_length")
    goal: Literal["target", "max"] = "target"
    target_spin: Range = (2.0, 20.0)
    reward_width: Number = Field(0.1, gt=0.0)
    rod_length: Number | None = Field(None, gt=0.0)
    rod_thickness: Number | None = Field(None, ge=0.0)
    rod_inertia: Literal["capsule", "thin_rod"] | Annotated[Number, Field(gt=0.0)] = "capsule"

    _target_spin = field_validator("target_spin")(lambda v: _positive_range(v, "rad/s"))

    @model_validator(mode="after")
    def _dict_needs_a_goal(self):
        if self.obs_mode == "dict" and self.goal != "target":
            raise ValueError("obs_mode: 'dict' needs goal='target' (with goal='max' there is no "
                             "goal to relabel: use obs_mode='vector')")
        _goal_width(self)
        return self


class PuckSpeedConfig(_StrikeConfig):
    """``SpinStrike/PuckSpeed-v0``.

    Attributes:
        target_speed: (min, max) target speed of the puck, m/s; its heading is uniform.
        reward_width: sigma of the reward, as a fraction of the target speed.
    """

    RANDOMIZABLE: ClassVar[tuple[str, ...]] = ("striker_mass", "target_mass", "restitution",
                                               "friction")
    target_speed: Range = (0.75, 3.0)
    reward_width: Number = Field(0.1, gt=0.0)

    _target_speed = field_validator("target_speed")(lambda v: _positive_range(v, "m/s"))

    @model_validator(mode="after")
    def _goal_width(self):
        _goal_width(self)
        return self


class ControlConfig(EnvConfig):
    """Control envs: the agent pushes a mallet around a walled table.

    Attributes:
        dt: control time step (one ``world.step``), s.
        max_force: largest force on the mallet, N (the action's unit disk maps onto it).
        max_speed: the mallet's speed limit, m/s (a force that would end a step of free flight
            faster is replaced by the one that ends it at the limit, cut to ``max_force``).
        mallet_mass, target_mass: kg.
    """

    RANDOMIZABLE: ClassVar[tuple[str, ...]] = ("mallet_mass", "target_mass", "restitution",
                                               "table_friction")
    dt: Number = Field(0.02, gt=0.0, le=1.0)
    max_force: Number = Field(8.0, gt=0.0)
    max_speed: Number = Field(3.0, gt=0.0)
    mallet_mass: Number | None = Field(None, gt=0.0)
    target_mass: Number | None = Field(None, gt=0.0)


def _positive_range(v: Range, unit: str) -> Range:
    """A (min, max) range with 0 < min <= max."""
    if not 0 < v[0] <= v[1]:
        raise ValueError(f"needs 0 < min <= max ({unit}), got {list(v)}")
    return v


def _format(err: ValidationError) -> str:
    """``<field>: <what is wrong> (got <input>)``, one per field; the members of a union
    (``rod_inertia``: a name or a number) are said as one error, not one per member."""
    return join_by_field(_field_errors(err))


def _field_errors(err: ValidationError) -> Iterator[tuple[str, str, str]]:
    """``(field, message, got)`` of each pydantic error, in the env arguments' terms."""
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"] if not UNION_MEMBER.match(str(p))) or "config"
        msg = e["msg"].removeprefix("Value error, ")
        field, sep, rest = msg.partition(": ")
        if loc == "config" and sep and field.isidentifier():  # a check across arguments
            loc, msg = field, rest
        if e["type"] == "extra_forbidden":
            msg = "unknown argument"
        got = f" (got {e['input']!r})" if e["type"] != "value_error" and "input" in e else ""
        yield loc, msg, got


#: Gymnasium's own arguments of ``gym.make`` / ``gym.make_vec``, never keys of an env's config
#: (an RLlib env_config may hold them: ``spinstrike.envs.rllib`` passes them to Gymnasium)
GYM_ARGUMENTS = ("render_mode", "max_episode_steps")


def episode_limit(value: Any, registered: int | None,
                  field: str = "max_episode_steps") -> int | None:
    """``max_episode_steps`` as ``gym.make`` reads it: ``None`` the registered limit, ``-1`` no
    limit, else an int >= 1 (``ConfigError`` naming ``field`` otherwise, as ``TimeLimit``
    refuses it)."""
    if value is None:
        return registered
    if (isinstance(value, bool) or not isinstance(value, numbers.Integral)  # np.int64 too
            or (value < 1 and value != -1)):
        limit = "none" if registered is None else registered
        raise ConfigError(f"{field}: must be an int >= 1, -1 (no limit) or None (the "
                          f"registered limit, {limit}) (got {value!r})")
    return None if value == -1 else int(value)


def parse_config(model: type[EnvConfig], config: dict | None, kwargs: dict) -> EnvConfig:
    """Merge a ``config`` dict and keyword arguments (keywords win) and validate them."""
    if config is not None and not isinstance(config, Mapping):
        raise ConfigError(f"config: must be a mapping of arguments (got {config!r} of type "
                          f"{type(config).__name__}) [allowed arguments: "
                          f"{', '.join(sorted(model.model_fields))}]")
    merged = dict(config or {})
    for key in GYM_ARGUMENTS:
        if key in merged:
            raise ConfigError(
                f"config[{key!r}]: {key} is Gymnasium's argument, not a config key: pass "
                f"gym.make(id, {key}=...) (an RLlib env_config may hold it: "
                f"spinstrike.envs.rllib passes it to gym.make)")
    merged.update(kwargs)
    try:
        return model.model_validate(merged)
    except ValidationError as exc:
        allowed = sorted(model.model_fields)
        raise ConfigError(f"{_format(exc)} [allowed arguments: {', '.join(allowed)}]") from None


def build_world(scene: Scene, batch_size: int, max_contacts: int = 64) -> World:
    """The env's world; a scene the world refuses (bodies that overlap, or lie outside the
    table) is a :class:`ConfigError` of the env's ``scene`` argument, as every other."""
    try:
        return World(scene, batch_size, max_contacts=max_contacts)
    except SceneError as exc:
        raise ConfigError(f"scene: {exc}") from None


def resolve_scene(source: Any) -> Any:
    """A ``scene`` argument given as a path to a file, read now: the file's data (a dict), so
    that an env's config, a pickle of the env (a worker in another folder) and a run's
    ``config.yml`` hold the scene itself, not a path relative to where it was given, and a later
    edit of the file changes no env made from it. Names, YAML text and dicts stay as given."""
    if isinstance(source, os.PathLike) or (isinstance(source, str) and "\n" not in source
                                           and is_path(Path(source), "is_file")):
        return read_scene(source)
    return source


def load_packaged_scene(name: str) -> dict:
    """The raw dict of a packaged scene ``configs/scenes/<name>.yaml``
    (``physics.packaged_scene``)."""
    return packaged_scene(name)


#: scene sections the env edits, and the type each must have
_SECTIONS = {"effects": (list, "a list of effect names"), "materials": (dict, "a mapping"),
             "table": (dict, "a mapping"), "bodies": (list, "a list of body mappings")}


def _scene_data(source: str | dict) -> dict:
    """The raw dict of a user's scene (a dict, a packaged scene's name, a YAML string or a path
    to a YAML file: ``physics.scene.read_scene``), checked just enough for the env's overrides;
    every problem is a :class:`ConfigError` naming it. (Before, a missing file, a directory,
    malformed YAML or ``bodies`` that were not a list of mappings escaped as
    FileNotFoundError, IsADirectoryError, yaml.ParserError or TypeError.)
    """
    if isinstance(source, dict):
        data = copy.deepcopy(source)
    else:
        try:
            data = read_scene(source)
        except SceneError as exc:
            raise ConfigError(str(exc)) from None
    if not isinstance(data, dict):
        raise ConfigError(f"scene: must be a mapping of scene fields (table, effects, solver, "
                          f"materials, bodies), got {type(data).__name__}")
    for key, (kind, what) in _SECTIONS.items():
        if key in data and not isinstance(data[key], kind):
            raise ConfigError(f"scene.{key}: must be {what} (got {data[key]!r})")
    for i, body in enumerate(data.get("bodies", [])):
        if not isinstance(body, dict) or not isinstance(body.get("name"), str):
            raise ConfigError(f"scene.bodies[{i}]: must be a mapping with a name (got {body!r})")
    return data


def _solver_block(scene: Any, given: dict | str) -> dict:
    """The ``solver`` argument over the scene's block, by ``World``'s rule
    (``physics.scene.solver_over``): of the scene's mode, it keeps the scene's values it leaves
    out (RodSpin's ``settle_substep`` of 1e-5 s was lost to the 1 ms default when
    ``solver={"mode": "exact", "tolerance": 1e-10}`` changed the tolerance only); of another
    mode, it replaces the block. A bad block is refused naming ``solver`` (it read
    "scene: solver: ...")."""
    try:
        return solver_over(scene, given).model_dump()
    except SceneError as exc:
        raise ConfigError(str(exc)) from None


def _drop_parameters_of_dropped_effects(data: dict, effects: list[str]) -> None:
    """``effects=`` turns effects off: the scene's values for them (the packaged control scenes'
    cloth friction, say) go too, instead of being refused as set for an unlisted effect. The
    env's own arguments add their effect back first (``build_scene``), so none is dropped."""
    if "table_friction" not in effects and "friction" in data.get("table", {}):
        data["table"] = {k: v for k, v in data["table"].items() if k != "friction"}
    mats = dict(data.get("materials", {}))
    pairs = mats.get("pairs")
    if "contact_friction" not in effects:
        mats.pop("friction", None)
        if isinstance(pairs, list):
            pairs = [{k: v for k, v in p.items() if k != "friction"} if isinstance(p, dict)
                     else p for p in pairs]
    if "walls" not in effects and isinstance(pairs, list):  # pairs with the cushions go
        walls = {"walls", *WALL_NAMES}
        pairs = [p for p in pairs
                 if not (isinstance(p, dict) and walls & set(p.get("bodies", ())))]
    if pairs is not None:
        mats["pairs"] = pairs
    if mats:
        data["materials"] = mats
    if "rotation" not in effects and isinstance(data.get("bodies"), list):
        data["bodies"] = [{k: v for k, v in b.items() if k not in ("inertia", "omega")}
                          if isinstance(b, dict) else b for b in data["bodies"]]


def _check_bodies(data: dict, body_overrides: dict[str, dict],
                  shapes: Mapping[str, tuple[str, str]] = MappingProxyType({})) -> None:
    """The scene's bodies are the env's own (``body_overrides`` names them), each once, of the
    shapes the task needs (``shapes``: name -> (shape, why))."""
    names = [b["name"] for b in data.get("bodies", [])]
    for name in names:
        if names.count(name) > 1:
            raise ConfigError(f"scene: bodies: the name {name!r} is used twice")
    missing = [name for name in body_overrides if name not in names]
    if missing:
        raise ConfigError(f"scene: needs a body named {missing[0]!r} (has {sorted(names)})")
    extra = [name for name in names if name not in body_overrides]
    if extra:
        raise ConfigError(
            f"scene: bodies: {extra} are not this env's: it places, observes and rewards only "
            f"{sorted(body_overrides)}, so other bodies would be moved at every reset (build "
            f"larger scenes with spinstrike.physics.World)")
    for i, body in enumerate(data.get("bodies", [])):
        shape, why = shapes.get(body["name"], (body.get("shape"), ""))
        if body.get("shape") is not None and body.get("shape") != shape:
            raise ConfigError(f"scene: bodies[{i}].shape: this env's {body['name']!r} must be a "
                              f"{shape}: {why} (got {body.get('shape')!r})")
        pinned = [flag for flag in ("static", "pivot") if body.get(flag)]
        if pinned:  # refused here, not by every reset ("pivots cannot move")
            raise ConfigError(
                f"scene: bodies: {body['name']!r} is {pinned[0]}: the env places its bodies at "
                f"every reset, so they must be free to move; drop {pinned[0]!r} (pinned bodies "
                f"fit larger scenes built with spinstrike.physics.World)")


def _check_needs(effects: list[str], needs: Mapping[str, str], refuses: Mapping[str, str],
                 field: str) -> None:
    for effect, why in needs.items():
        if effect not in effects:
            raise ConfigError(f"{field}: this env needs {effect!r}: {why} (got {effects})")
    for effect, why in refuses.items():
        if effect in effects:
            raise ConfigError(f"{field}: {effect!r} is not allowed for this env: {why} (got "
                              f"{effects})")


def reset_room_error(size: list[float], reaches: Mapping[str, tuple[float, int]],
                     clearance: float) -> str | None:
    """The error for a walled table of ``size`` too small for resets that put each body at any
    angle in its half of the table (``reaches``: name -> (reach from its centre, m; side, -1
    left or +1 right)), ``clearance`` from the cushions; None where they fit. A table that
    passed ``gym.make`` and then failed most seeds' resets named no argument."""
    most = max(reach for reach, _ in reaches.values()) + clearance
    need = (4 * most, 2 * most)
    if size[0] >= need[0] and size[1] >= need[1]:
        return None
    where = " and ".join(f"the {name} (reach {reach:.4g} m) in the "
                         f"{'left' if side < 0 else 'right'} half"
                         for name, (reach, side) in reaches.items())
    return (f"scene.table.size: {list(size)} m is too small for this env's resets, which put "
            f"{where}, at any angle and {clearance} m clear of the cushions (their positions in "
            f"a scene are not used): it needs at least [{need[0]:.4g}, {need[1]:.4g}] m")


def _task_materials(data: dict, cfg: EnvConfig, pair: tuple[str, str]) -> dict:
    """The scene's materials with the env's ``restitution`` and ``friction`` (``build_scene``)."""
    mats = dict(data.get("materials", {}))
    if cfg.restitution is not None:
        mats["restitution"] = cfg.restitution
    if cfg.friction is not None:
        mats["friction"] = cfg.friction
    task_pair = []  # the scene's entries for the task's pair: the arguments win there too
    for entry in mats.get("pairs", []):
        entry = dict(entry)
        if sorted(entry.get("bodies", [])) == sorted(pair):
            entry.update({k: v for k, v in (("restitution", cfg.restitution),
                                            ("friction", cfg.friction)) if v is not None})
        task_pair.append(entry)
    if "pairs" in mats:
        mats["pairs"] = task_pair
    return mats


def _place(data: dict, bodies: dict[str, dict], placed: Mapping[str, int]) -> list | None:
    """Put each ``placed`` body at the middle of its half of a walled table (``build_scene``);
    the table's size, or None where there is none (or it is no pair of numbers, which the
    scene's own error names)."""
    size = (data.get("table") or {}).get("size") if isinstance(data.get("table"), dict) else None
    if not placed or not isinstance(size, (list, tuple)) or len(size) != 2 or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in size):
        return None  # (an infinite size: the bodies placed at +-inf were named, not the size)
    for name, side in placed.items():  # the scene's own dicts, as the overrides edit them
        bodies[name]["position"] = [0.25 * side * size[0], 0.0]
    return list(size)


def _reach(body: Body) -> float:
    """How far a body reaches from its centre, m: its core's half-length and radius."""
    return body.half_length + body.core_radius


def _placed_outside(exc: SceneError, data: dict, bodies: dict[str, dict],
                    placed: Mapping[str, int], size: list, clearance: float) -> str | None:
    """``reset_room_error`` where the scene's error is a ``placed`` body outside the table."""
    for i, body in enumerate(data.get("bodies", [])):
        if body["name"] in placed and str(exc).startswith(f"bodies[{i}].position:"):
            # the bodies are valid (the table's check comes after theirs): their reach as the
            # scene defines it
            reaches = {n: (_reach(Body.model_validate(bodies[n])), side)
                       for n, side in placed.items()}
            return reset_room_error(size, reaches, clearance)
    return None


def build_scene(default: str, cfg: EnvConfig, body_overrides: dict[str, dict],
                pair: tuple[str, str], needs: Mapping[str, str] = MappingProxyType({}),
                refuses: Mapping[str, str] = MappingProxyType({}),
                shapes: Mapping[str, tuple[str, str]] = MappingProxyType({}),
                placed: Mapping[str, int] = MappingProxyType({}), clearance: float = 0.0) -> Scene:
    """Packaged (or user) scene with the env's overrides applied, validated once. ``pair``:
    the task's pair (target and striker or mallet), whose material ``restitution`` and
    ``friction`` set even where the scene names that pair (as ``randomize`` does). ``needs``:
    effects the task cannot do without, with why (a ConfigError where one is left out);
    ``refuses``: effects it cannot take, with why (checked before the scene is validated, whose
    errors would otherwise ask for what the effect needs); ``shapes``: the shape each of the
    task's bodies must have, with why (a RodSpin "rod" given as a disk earned 0 for every
    action); ``placed``: bodies the env puts at a random pose on a walled table at every reset,
    each with the side of the table it goes to (-1 left, +1 right). Their scene positions are
    never used, so they stand at the middle of their halves for the scene's checks (a smaller
    table was refused for the packaged mallet's position, which the user never chose), and a
    table too small for the resets (``reset_room_error``, ``clearance`` from the cushions) is
    refused as such."""
    data = load_packaged_scene(default) if cfg.scene is None else _scene_data(cfg.scene)
    # a scene that leaves ``effects`` out has the schema's default (rotation), as in World
    effects = (list(cfg.effects) if cfg.effects is not None
               else list(data.get("effects", Scene.model_fields["effects"].default)))
    if cfg.friction and "contact_friction" not in effects:
        effects.append("contact_friction")
    if cfg.table_friction and "table_friction" not in effects:
        effects.append("table_friction")
    if "friction" in cfg.randomize and "contact_friction" not in effects:
        effects.append("contact_friction")
    if "table_friction" in cfg.randomize and "table_friction" not in effects:
        effects.append("table_friction")
    data["effects"] = effects
    if cfg.effects is not None:
        _drop_parameters_of_dropped_effects(data, effects)
    if cfg.solver is not None:
        data["solver"] = _solver_block(data.get("solver"), cfg.solver)
    data["materials"] = _task_materials(data, cfg, pair)
    if cfg.table_friction is not None:
        data["table"] = dict(data.get("table", {}), friction=cfg.table_friction)
    _check_bodies(data, body_overrides, shapes)
    _check_needs(effects, needs, refuses,
                 "effects" if cfg.effects is not None else "scene.effects")
    bodies = {b["name"]: b for b in data.get("bodies", [])}
    for name, changes in body_overrides.items():
        bodies[name].update({k: v for k, v in changes.items() if v is not None})
    size = _place(data, bodies, placed)
    try:
        return load_scene(data)
    except SceneError as exc:
        error = size and _placed_outside(exc, data, bodies, placed, size, clearance)
        if error:
            raise ConfigError(error) from None
        raise ConfigError(f"scene: {exc}") from None
