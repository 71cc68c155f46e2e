"""The machinery every SpinStrike env shares, written once for a batch.

A :class:`Task` holds a batched :class:`physics.World` and does the env's work for B elements at
once: reset chosen elements from rows of uniforms, step all of them with a batch of actions,
observe, reward. :class:`SpinStrikeEnv` is a Gymnasium ``Env`` over a task with B = 1;
:class:`SpinStrikeVectorEnv` is a native Gymnasium ``VectorEnv`` over a task with B = N (what
``gym.make_vec`` builds through ``vector_entry_point``). Both draw their randomness from
per-element streams (``envs.rng``), so element i of a vector env seeded s follows a single env
seeded s + i bit for bit.

Actions: float32 Boxes in [-1, 1]. A NaN or infinite action raises ``ValueError``; finite values
outside the box are clipped to it (as Gymnasium's ``ClipAction`` would), silently.

Render modes of a single env (``SpinStrikeEnv.render``): ``rgb_array`` (the current frame: after
a strike, its last frame, with the strike's ghost poses and impulses), ``rgb_array_list`` (the
frames since the last ``render()``, then cleared, as Gymnasium's ``RenderCollection`` does: the
reset frame, then every step's frames: one per control step, a whole strike in slow motion per
one-strike step) and ``human`` (the same frames in a window, at ``render_fps``). With
``render_mode=None`` nothing is traced or drawn.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import inspect
import numbers
import warnings
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.envs.registration import EnvSpec
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from spinstrike.envs.config import ConfigError, EnvConfig, episode_limit, parse_config
from spinstrike.envs.layout import ObsField
from spinstrike.envs.rendering import Frame, Renderer
from spinstrike.envs.rng import UniformStream
from spinstrike.physics import WorldEdit

__all__ = ["SpinStrikeEnv", "SpinStrikeVectorEnv", "Task", "action_error", "check_actions",
           "parse_autoreset_mode"]

#: lines of the video frames' information panel (a band along their top)
PANEL_LINES = 3


def action_error(actions: Any) -> str:
    """The message of a non-finite action."""
    return (f"action: must be finite numbers in [-1, 1] (got {np.asarray(actions).tolist()}); "
            "finite values outside the box are clipped")


def check_actions(actions: Any, shape: tuple[int, ...]) -> np.ndarray:
    """Validate actions of exactly ``shape`` (``(A,)`` for a single env, ``(B, A)`` for a batch):
    numbers only (no strings, booleans or objects), no NaN/inf; finite values outside [-1, 1]
    are clipped (as Gymnasium's ``ClipAction`` would). Returns float64 actions."""
    a = np.asarray(actions)
    if a.dtype.kind not in "iuf":
        raise ValueError(f"action: must be numbers (got dtype {a.dtype}: {actions!r})")
    if a.shape != shape:
        raise ValueError(f"action: expected shape {shape}, got {a.shape}")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)):
        raise ValueError(action_error(a))
    return np.clip(a, -1.0, 1.0)


class Task(ABC):
    """A batched env: subclasses implement the physics-facing parts (the abstract methods).

    Class attributes:
        CONFIG: the config model.  LAYOUT: flat observation fields.  ACTIONS: action names.
        GOAL: slice of LAYOUT holding the desired goal (goal-conditioned mode), or None.
        UNIFORMS: uniforms drawn per reset of an element.
    """

    CONFIG: ClassVar[type[EnvConfig]]
    LAYOUT: ClassVar[tuple[ObsField, ...]]
    ACTIONS: ClassVar[tuple[str, ...]]
    GOAL: ClassVar[slice | None] = None
    ACHIEVED: ClassVar[tuple[ObsField, ...]] = ()
    UNIFORMS: ClassVar[int]
    #: the env's name on its video frames
    TITLE: ClassVar[str] = ""
    render_fps: ClassVar[float] = 50
    #: ``observe`` returns values already clipped to the layout's bounds
    OBS_CLIPPED: ClassVar[bool] = False
    #: effects the task cannot do without, each with why (``config.build_scene`` refuses a
    #: scene that leaves one out)
    NEEDS: ClassVar[dict[str, str]] = {}
    #: effects the task cannot take, each with why
    REFUSES: ClassVar[dict[str, str]] = {}
    #: the shape each of the task's bodies must have in a scene, with why (``build_scene``)
    SHAPES: ClassVar[dict[str, tuple[str, str]]] = {}

    def __init__(self, cfg: EnvConfig, batch_size: int, single: bool = False) -> None:
        self.cfg = cfg
        self.batch_size = batch_size
        #: the name on video frames: ``TITLE``, or the id the env was made with (a variant's)
        self.title = self.TITLE
        #: the exact shape ``step`` accepts: ``(A,)`` behind a single env, else ``(B, A)``
        self.action_shape = ((len(self.ACTIONS),) if single
                             else (batch_size, len(self.ACTIONS)))
        self.obs_low = np.array([f.low for f in self.LAYOUT], dtype=np.float32)
        self.obs_high = np.array([f.high for f in self.LAYOUT], dtype=np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (len(self.ACTIONS),), dtype=np.float32)
        #: record element 0's steps for video frames (set by a single env that renders; by a
        #: vector env that renders, where the task traces every element)
        self.record_trace = False
        self._renderer: Renderer | None = None
        self._obs_renderer: Renderer | None = None

    #: whether ``record_trace`` records every element's past (a motion trail and return, for
    #: a vector env's frames) or element 0's only (a strike's clip)
    TRACES_EVERY_ELEMENT: ClassVar[bool] = False

    # --- to implement ---------------------------------------------------------------------
    @abstractmethod
    def reset(self, env: np.ndarray, uniforms: np.ndarray) -> dict[str, np.ndarray]:
        """Start new episodes in elements ``env``; returns reset info arrays (over ``env``)."""

    @abstractmethod
    def step(self, actions: Any, batch_info: bool = True
             ) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray] | None]:
        """Advance every element with raw actions of exactly ``action_shape`` (validated here:
        see :func:`check_actions`); returns (reward[B], terminated[B], info arrays [B, ...]).

        ``batch_info=False`` lets a task skip the batched info when only :meth:`info_row` will
        be read (a single env)."""

    def info_row(self, b: int, info: dict[str, np.ndarray]) -> dict[str, Any]:
        """Element ``b``'s info as plain Python values (what a single env returns)."""
        return _scalar_info(info, b)

    def trace(self) -> dict[str, Any]:
        """What element 0's video frames remember of its past (``record_trace``: a strike's
        clip, a motion trail, the return so far), for a pickled or copied env."""
        return {}

    def put_trace(self, trace: dict[str, Any]) -> None:
        """Put back :meth:`trace`'s values (after the physics state)."""
        return None

    @abstractmethod
    def observe(self) -> np.ndarray:
        """Flat observations ``[B, len(LAYOUT)]`` (clipped to the bounds only if
        ``OBS_CLIPPED``)."""

    def by_layout(self, **columns: np.ndarray) -> np.ndarray:
        """Flat observations ``[B, len(LAYOUT)]`` from arrays named by the layout's fields, put
        in the layout's order (so the order is declared once, in ``LAYOUT``)."""
        names = [f.name for f in self.LAYOUT]
        if set(columns) != set(names):
            raise KeyError(f"{type(self).__name__}.observe: columns {sorted(columns)} do not "
                           f"match the layout {names}")
        return np.stack([columns[n] for n in names], axis=1)

    def achieved(self) -> np.ndarray:
        """Achieved goals ``[B, len(ACHIEVED)]`` (goal-conditioned tasks override this)."""
        raise TypeError(f"{type(self).__name__} is not goal-conditioned")

    @staticmethod
    def goal_reward(achieved: np.ndarray, desired: np.ndarray, cfg: EnvConfig) -> np.ndarray:
        """Reward for achieved vs desired goals, vectorised over leading axes (goal-conditioned
        tasks override this)."""
        raise TypeError("this task is not goal-conditioned")

    @abstractmethod
    def frame(self, b: int, decorate: bool = True) -> Frame:
        """What element ``b`` looks like now: a video frame with its overlays, or (``decorate``
        False) the plain frame of a pixel observation."""

    def step_frames(self) -> list[Frame]:
        """Element 0's last step as video frames (one-strike tasks: the whole strike)."""
        return [self.frame(0)]

    def show_rewards(self, rewards: np.ndarray, returns_before: Any = None) -> bool:
        """The rewards ``[B]`` the env paid for its last step, as its video frames show them
        (the step reward, a strike's score, the return so far): a task or env subclass's
        ``step`` may pay other than this task computed (the frames showed the shipped reward,
        walk W21b F8). ``returns_before``: :meth:`shown_returns` before that step (one of a
        subclass may be several of the task's); by default the return before the task's last
        step. Elements reset since their step keep showing their reset. Returns whether what
        the frames show changed."""
        return False

    def shown_returns(self) -> Any:
        """What the frames show of each element's return so far (None: none), for
        :meth:`show_rewards`."""
        return None

    @abstractmethod
    def view_half(self) -> tuple[float, float]:
        """Half extents (m) of the area a frame shows, centred on the origin."""

    @abstractmethod
    def _set_random(self, edit: WorldEdit, key: str, value: np.ndarray) -> None:
        """Apply a drawn value of the randomised parameter ``key`` (one of the config's
        ``RANDOMIZABLE``) to the elements of ``edit``."""

    def _apply_random(self, edit: WorldEdit, u: np.ndarray) -> None:
        """Draw the configured ``randomize`` ranges for the elements of ``edit`` from uniforms
        ``u`` (one column per ``RANDOMIZABLE`` parameter, used or not, so the draws do not depend
        on which are configured): masses log-uniformly, the rest uniformly."""
        for k, key in enumerate(self.CONFIG.RANDOMIZABLE):
            if key not in self.cfg.randomize:
                continue
            lo, hi = self.cfg.randomize[key]
            x = u[:, k]
            if key.endswith("mass"):
                value = np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo)))
            else:
                value = lo + x * (hi - lo)
            self._set_random(edit, key, value)

    # --- shared ---------------------------------------------------------------------------
    def observation_space(self) -> spaces.Space:
        mode = self.cfg.obs_mode
        vec = spaces.Box(self.obs_low, self.obs_high, dtype=np.float32)
        if mode == "vector":
            return vec
        if mode == "pixels":
            w, h = self.cfg.obs_size
            return spaces.Box(0, 255, (h, w, 3), dtype=np.uint8)
        if self.GOAL is None:
            name = type(self).__name__.removesuffix("Task")
            raise ConfigError(f"obs_mode: 'dict' needs a goal-conditioned env (the strike "
                              f"envs with goal='target'); the {name} envs have no goal: use "
                              f"'vector' or 'pixels'")
        keep = np.ones(len(self.LAYOUT), bool)
        keep[self.GOAL] = False
        glow = np.array([f.low for f in self.ACHIEVED], np.float32)
        ghigh = np.array([f.high for f in self.ACHIEVED], np.float32)
        return spaces.Dict({
            "observation": spaces.Box(self.obs_low[keep], self.obs_high[keep], dtype=np.float32),
            "achieved_goal": spaces.Box(glow, ghigh, dtype=np.float32),
            "desired_goal": spaces.Box(glow, ghigh, dtype=np.float32),
        })

    def _flat(self) -> np.ndarray:
        """``observe()`` clipped to the layout's bounds, as float32 (the vector observation)."""
        flat = self.observe()
        if not self.OBS_CLIPPED:
            flat = np.clip(flat, self.obs_low, self.obs_high)
        return flat.astype(np.float32)

    def goals(self, flat: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The achieved and desired goals ``[B, len(ACHIEVED)]`` exactly as a dict observation
        shows them (clipped to their bounds, float32)."""
        flat = self._flat() if flat is None else flat
        lo = np.array([f.low for f in self.ACHIEVED], np.float32)
        hi = np.array([f.high for f in self.ACHIEVED], np.float32)
        return np.clip(self.achieved(), lo, hi).astype(np.float32), flat[:, self.GOAL]

    def dict_reward(self, reward: np.ndarray) -> np.ndarray:
        """In ``obs_mode='dict'`` the reward of the goals the observation shows, so that
        ``compute_reward(achieved_goal, desired_goal, info)`` (HER's relabelling) equals the
        reward ``step`` paid; it differs from the exact one by float32 rounding. Otherwise
        ``reward`` as it is."""
        if self.cfg.obs_mode != "dict":
            return reward
        achieved, desired = self.goals()
        return self.goal_reward(achieved.astype(np.float64), desired.astype(np.float64),
                                self.cfg)

    def observations(self) -> Any:
        """Observations of every element in the configured mode (batched)."""
        flat = self._flat()
        mode = self.cfg.obs_mode
        if mode == "vector":
            return flat
        if mode == "pixels":
            return np.stack([self.pixels(b) for b in range(self.batch_size)])
        keep = np.ones(len(self.LAYOUT), bool)
        keep[self.GOAL] = False
        achieved, desired = self.goals(flat)
        return {"observation": flat[:, keep], "achieved_goal": achieved,
                "desired_goal": desired}

    def pixels(self, b: int) -> np.ndarray:
        """Element ``b``'s pixel observation: its plain frame at ``obs_size``."""
        if self._obs_renderer is None:
            self._obs_renderer = Renderer(self.cfg.obs_size, self.view_half())
        return self._obs_renderer.draw(self.frame(b, decorate=False))

    def render(self, b: int) -> np.ndarray:
        """Element ``b``'s current video frame, at ``render_size``."""
        return self.draw(self.frame(b))

    @property
    def renderer(self) -> Renderer:
        """The video frames' renderer (``render_size``)."""
        if self._renderer is None:
            self._renderer = Renderer(self.cfg.render_size, self.view_half(),
                                      panel_lines=PANEL_LINES)
        return self._renderer

    def draw(self, frame: Frame) -> np.ndarray:
        """Draw any video frame of this task (e.g. one of :meth:`step_frames`)."""
        return self.renderer.draw(frame)

    def close(self) -> None:
        for r in (self._renderer, self._obs_renderer):
            if r is not None:
                r.close()
        self._renderer = self._obs_renderer = None


def _take(tree: Any, i: int) -> Any:
    if isinstance(tree, dict):
        return {k: _take(v, i) for k, v in tree.items()}
    return tree[i]


def _scalar_info(info: dict[str, np.ndarray], i: int) -> dict[str, Any]:
    out = {}
    for k, v in info.items():
        x = v[i]
        out[k] = x.item() if isinstance(x, np.generic) else x
    return out


def _spec_as_made(spec, cfg: EnvConfig):
    """``spec`` with its kwargs as they were when the env was made, as the env's pickles and a
    run's ``config.yml`` hold them: a deep copy (``gym.make`` keeps the caller's dicts, so a
    ``randomize`` range edited afterwards in a sweep changed what ``gym.make(env.spec)``
    made), and a scene file given to the env (in its kwargs or its ``config`` dict) as read
    (``gym.make(env.spec)`` re-read the file: an edit since, or another working directory,
    made another env, or none)."""
    if spec is None or not isinstance(spec.kwargs, dict):
        return spec
    kwargs = copy.deepcopy(spec.kwargs)
    if cfg.scene is not None and "scene" in kwargs:
        kwargs["scene"] = copy.deepcopy(cfg.scene)
    elif (cfg.scene is not None and isinstance(kwargs.get("config"), dict)
          and "scene" in kwargs["config"]):
        kwargs["config"] = dict(kwargs["config"], scene=copy.deepcopy(cfg.scene))
    return dataclasses.replace(spec, kwargs=kwargs)


class _SpecOfScene:
    """``spec`` (which ``gym.make`` / ``gym.make_vec`` set) holds the kwargs as they were when
    the env was made, a scene file as read."""

    @property
    def spec(self):
        return self.__dict__.get("_spec")

    @spec.setter
    def spec(self, value) -> None:
        self._spec = _spec_as_made(value, self.cfg)
        if value is not None and "task" in self.__dict__:
            # frames name the id made (a variant's), not its env class's
            name = value.name if value.version is None else f"{value.name}-v{value.version}"
            self.task.title = name if value.namespace in (None, "SpinStrike") \
                else f"{value.namespace}/{name}"


def _users_class(cls: type) -> bool:
    """Whether ``cls`` is a class of the user's, not one of this package's."""
    return not cls.__module__.startswith("spinstrike.")


def _shows_what_it_pays(step: Callable) -> Callable:
    """A user's ``step`` (of an env or a vector env) whose video frames show the rewards it
    returns: each step of the base class films as it goes (a subclass of several base steps, an
    action repeat, keeps every frame; a ``render()`` within sees them), and when the outermost
    call returns, the frames of its last base step and the return so far are relabelled with
    what it paid (``_before_users_step`` / ``_after_users_step``)."""
    if getattr(step, "_shows_what_it_pays", False):
        return step

    @functools.wraps(step)
    def shows(self, *args: Any, **kwargs: Any):
        if self._step_depth or self.render_mode is None:  # (within, or nothing to show)
            return step(self, *args, **kwargs)
        before = self._before_users_step()
        self._step_depth = 1
        try:
            out = step(self, *args, **kwargs)
        finally:
            self._step_depth = 0
        self._after_users_step(_reward_of(out), before)
        return out

    shows._shows_what_it_pays = True
    return shows


def _reward_of(out: Any) -> np.ndarray | None:
    """The reward of a user's step's return ``out`` as a float array, or None where it has no
    number there (a reward of None, a tensor that needs its graph, no tuple)."""
    try:
        reward = out[1]
    except Exception:  # noqa: BLE001  (whatever the user's step returned: shown as the env's)
        return None
    if reward is None:
        return None
    for number in (lambda r: np.asarray(r, dtype=np.float64),  # (a tensor needing its graph:)
                   lambda r: np.asarray(float(r))):
        try:
            with warnings.catch_warnings():  # (torch's about its graph: the user's reward)
                warnings.simplefilter("ignore")
                return number(reward)
        except Exception:  # noqa: BLE001
            continue
    return None


class _ShowsWhatItPays:
    """The frames of a user's subclass overriding ``step`` (itself, or by a mixin before the
    env's class) show the reward it returns (they showed the shipped task's, walk W21b F8).
    Not seen: a reward a ``gym.Wrapper`` changes (the env draws its frames), a ``step``
    assigned to the class after it was made, a mixin's ``__init_subclass__`` that does not
    call ``super()``'s."""

    #: a user's ``step`` is under way (1): the outermost relabels the frames when it returns
    _step_depth: int = 0
    #: steps of the base class so far (a user's step that made none relabels nothing)
    _base_steps: int = 0

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if not _users_class(cls):
            return
        step = inspect.getattr_static(cls, "step", None)
        if (inspect.isfunction(step) and step is not SpinStrikeEnv.step
                and step is not SpinStrikeVectorEnv.step):  # (not a staticmethod's)
            cls.step = _shows_what_it_pays(step)

    def _before_users_step(self) -> Any:
        return self._base_steps, self.task.shown_returns()

    def __getstate__(self) -> dict:
        # (the vector env's pickle: a user's step under way is not the copy's; the single
        # env has its own, which rebuilds the env)
        state = dict(self.__dict__)
        state.pop("_step_depth", None)
        return state


def _plain(value: Any) -> bool:
    """Whether ``value`` is plain data: numbers, strings, arrays and containers of them."""
    if isinstance(value, (numbers.Number, str, bytes, np.ndarray, np.generic)) or value is None:
        return True
    if isinstance(value, (list, tuple)):
        return all(_plain(v) for v in value)
    if isinstance(value, dict):
        return all(_plain(k) and _plain(v) for k, v in value.items())
    return False


class SpinStrikeEnv(_ShowsWhatItPays, _SpecOfScene, gym.Env):
    """Gymnasium env over a :class:`Task` with one element. Subclasses set ``TASK``."""

    TASK: ClassVar[type[Task]]
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array", "rgb_array_list",
                                                           "human"], "render_fps": 50}
    #: the attributes this class keeps (a copy rebuilds them); a subclass's others are copied
    _OWN_ATTRIBUTES: ClassVar[frozenset[str]] = frozenset({
        "_config", "_ended", "_frames", "_np_random", "_np_random_seed", "_own", "_spec",
        "_started", "action_space", "cfg", "compute_reward", "observation_space", "render_mode",
        "task", "metadata", "_made_with",
        # a user's step under way when copied is not the copy's (it stuck, never relabelling)
        "_step_depth", "_base_steps", "_filmed_from"})

    def __new__(cls, *args: Any, **kwargs: Any):
        env = super().__new__(cls)
        # what a subclass of the user's was made with, so that a copy is rebuilt by its own
        # __init__: copies were made by this class's from its config, which dropped the
        # subclass's own arguments or failed on an __init__ of other parameters (walk W21b).
        # This package's classes are rebuilt from their config: nothing to keep
        env._made_with = None
        if _users_class(cls):
            try:
                env._made_with = copy.deepcopy((args, kwargs))
            except Exception:  # noqa: BLE001  (an argument that does not copy: as before)
                pass
        return env

    #: where the frames of the last step start in ``_frames`` (None: not kept there)
    _filmed_from: int | None = None

    def _after_users_step(self, paid: np.ndarray | None, before: Any) -> None:
        """A user's ``step`` paid ``paid``: its last base step's frames show it (those not
        rendered yet), its return ``before`` it plus ``paid``; ``human`` shows them now."""
        steps, returns = before
        if (paid is not None and paid.size == 1 and self._started
                and self._base_steps != steps
                and self.task.show_rewards(paid.reshape(1), returns)
                and self._filmed_from is not None):
            self._frames[self._filmed_from:] = self.task.step_frames()
        if self.render_mode == "human":  # (kept while the user's step ran)
            frames, self._frames, self._filmed_from = self._frames, [], None
            self._show(frames)

    def __init__(self, render_mode: str | None = None, config: dict | None = None,
                 **kwargs: Any) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ConfigError(f"render_mode: must be one of {self.metadata['render_modes']} or "
                              f"None (got {render_mode!r})")
        self.render_mode = render_mode
        self.cfg = parse_config(self.TASK.CONFIG, config, kwargs)
        # the arguments as given, for pickles and copies: a deep copy, so that a dict the
        # caller edits afterwards (a randomize range reused in a sweep) stays out of them
        self._config = copy.deepcopy(dict(config or {}) | kwargs)
        if "scene" in self._config:  # a scene file as read (config.resolve_scene), for pickles
            self._config["scene"] = self.cfg.scene
        self.task = self.TASK(self.cfg, 1, single=True)
        self.task.record_trace = render_mode is not None
        if self.task.render_fps != self.metadata["render_fps"]:  # e.g. a control dt != 0.02 s
            self.metadata = dict(self.metadata, render_fps=self.task.render_fps)
        #: ``rgb_array_list``: the frames since the last ``render()`` (drawn when it is called)
        self._frames: list[Frame] = []
        self.action_space = self.task.action_space
        self.observation_space = self.task.observation_space()
        self._started = False
        #: the last step ended the episode (terminated): the next must be a reset
        self._ended = False
        #: the parameters this env was made with (masses, sizes, materials, table), which the
        #: next reset puts back after :meth:`set_physics_state` brought in a snapshot's
        self._own = None
        if self.cfg.obs_mode == "dict" and getattr(type(self), "compute_reward", None) is None:
            # (an instance attribute; a subclass's own compute_reward method is left to act:
            # it was hidden, and HER relabelled with the base reward, walk W21b)
            self.compute_reward = self._goal_reward

    # pickling (SubprocVecEnv, Ray): rebuild from the arguments, then put back the live state
    def __getstate__(self) -> dict:
        users = _users_class(type(self))
        made = self.__dict__.get("_made_with")  # (None for this package's classes)
        if made is not None and isinstance(made[1].get("scene"), str):  # a file: as read
            made = (made[0], {**made[1], "scene": self.cfg.scene})
        return {"render_mode": self.render_mode, "config": self._config,
                # a subclass of the user's: its own arguments and attributes
                "made_with": made, "attributes": {
                    k: v for k, v in self.__dict__.items()
                    if users and k not in self._OWN_ATTRIBUTES},
                "physics": self.get_physics_state(),
                "np_random": self._np_random, "np_random_seed": self._np_random_seed,
                "started": self._started, "ended": self._ended,
                # the video's memory: frames not yet rendered, a strike's clip, trails
                "frames": self._frames, "trace": self.task.trace(), "spec": self.spec,
                # the spaces' generators (action_space.seed(...), then sample()): their streams
                "spaces": (self.action_space, self.observation_space)}

    def __setstate__(self, state: dict) -> None:
        made = state.get("made_with")
        if made is not None:
            self._made_with = made
            self.__init__(*made[0], **made[1])
        else:
            self.__init__(render_mode=state["render_mode"], config=state["config"])
        # a subclass's attributes: those its __init__ did not make, and the plain values of
        # those it did (a counter's count; an attribute holding this env's world or task is
        # the rebuilt env's own, not a copy of the old one's)
        self.__dict__.update({k: v for k, v in state.get("attributes", {}).items()
                              if k not in self.__dict__ or _plain(v)})
        self.set_physics_state(state["physics"])
        self._np_random = state["np_random"]
        self._np_random_seed = state.get("np_random_seed")
        self._started = state["started"]
        self._ended = state.get("ended", False)
        self._frames = list(state.get("frames", []))
        self.task.put_trace(state.get("trace", {}))
        self.spec = state.get("spec")
        if "spaces" in state:
            self.action_space = self.task.action_space = state["spaces"][0]
            self.observation_space = state["spaces"][1]

    @property
    def world(self):
        """The batched physics world (B = 1) behind this env."""
        return self.task.world

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        # straight from np_random, each reset: a generator the user puts in (the np_random
        # setter) or winds back (its bit_generator.state) draws the next episodes; the same
        # numbers as a vector env's element, which draws them in blocks (envs.rng)
        uniforms = self.np_random.random((1, self.TASK.UNIFORMS))
        if self._own is not None:  # a snapshot's parameters last until the episode ends
            self.task.world.restore(self._own)
            self._own = None
        info = self.task.reset(np.zeros(1, dtype=np.int64), uniforms)
        self._started = True
        self._ended = False
        if self.render_mode == "rgb_array_list":
            self._frames = [self.task.frame(0)]
            self._filmed_from = None
        elif self.render_mode == "human":
            self._show([self.task.frame(0)])
        return _take(self.task.observations(), 0), _scalar_info(info, 0)

    def step(self, action):
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._ended:  # a one-strike env would strike again and pay again
            raise gym.error.ResetNeeded("the episode ended (terminated=True): call reset() "
                                        "before step()")
        reward, terminated, info = self.task.step(action, batch_info=False)
        self._ended = bool(terminated[0])
        obs = _take(self.task.observations(), 0)
        if self.render_mode is not None:
            self._base_steps += 1
            self.task.show_rewards(reward)  # (a task subclass's, where it pays another)
            if self.render_mode == "rgb_array_list" or self._step_depth:
                # (human: shown when a user's step around this one returns, relabelled)
                self._filmed_from = len(self._frames)
                self._frames += self.task.step_frames()
            elif self.render_mode == "human":
                self._show(self.task.step_frames())
        return obs, float(reward[0]), bool(terminated[0]), False, self.task.info_row(0, info)

    def _goal_reward(self, achieved_goal, desired_goal, info):
        """Goal-conditioned reward (``obs_mode='dict'``), vectorised like SB3's HER expects.

        Bound as ``compute_reward`` only in dict mode: SB3 takes any env with a
        ``compute_reward`` for a goal env.
        """
        return self.task.goal_reward(np.asarray(achieved_goal, dtype=np.float64),
                                     np.asarray(desired_goal, dtype=np.float64), self.cfg)

    def get_physics_state(self) -> dict:
        """The full physical state (world arrays, the episode's parameters, e.g. a
        ``randomize`` draw, and its task data), for replays; pickling carries it."""
        return {"world": self.task.world.get_state(parameters=True),
                "task": self.task.snapshot()}

    def set_physics_state(self, state: dict):
        """Put back a state from :meth:`get_physics_state` (then ``step`` continues from it);
        returns its observation, as ``reset`` returns the first one's.

        Its parameters (masses, sizes, materials, the table: another env's, or edited for a
        what-if) hold until the next :meth:`reset`, which starts an episode of this env's own
        task again (they stayed: every later episode ran on the snapshot's task, and
        ``reset(seed=s)`` no longer repeated a fresh env's)."""
        own = self._own if self._own is not None else self.task.world.get_state(parameters=True)
        self.task.world.restore(state["world"])
        self._own = own
        self.task.restore(state["task"])
        self._started = True
        self._ended = False
        return _take(self.task.observations(), 0)

    def render(self):
        """``rgb_array``: the current frame; ``rgb_array_list``: the frames since the last call
        (then cleared); ``human``: shows the current frame, returns None."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode")
            return None
        if self.render_mode == "rgb_array_list":
            frames, self._frames = self._frames, []
            self._filmed_from = None
            return [self.task.draw(f) for f in frames]
        if self.render_mode == "human":
            self._show([self.task.frame(0)])
            return None
        return self.task.render(0)

    def _show(self, frames: list[Frame]) -> None:
        """Play frames in the window at ``render_fps`` (a strike at its slowed pace)."""
        for f in frames:
            self.task.renderer.show(self.task.draw(f), self.metadata["render_fps"])

    def close(self) -> None:
        self.task.close()


#: the accepted spellings of each autoreset mode (case and ``_``/``-`` ignored)
_MODE_NAMES = {"nextstep": AutoresetMode.NEXT_STEP, "samestep": AutoresetMode.SAME_STEP,
               "disabled": AutoresetMode.DISABLED}


def parse_autoreset_mode(value: Any) -> AutoresetMode:
    """Gymnasium's ``AutoresetMode`` from an enum member or a string (its name or value, any
    case: ``"next_step"``, ``"NextStep"``, ``"SAME_STEP"``, ``"disabled"``)."""
    if isinstance(value, AutoresetMode):
        return value
    if isinstance(value, str):
        mode = _MODE_NAMES.get(value.replace("_", "").replace("-", "").lower())
        if mode is not None:
            return mode
    raise ConfigError(f"autoreset_mode: must be a gymnasium.vector.AutoresetMode or one of "
                      f"'next_step', 'same_step', 'disabled' (got {value!r})")


def _reset_mask(options: dict | None, n: int) -> np.ndarray | None:
    """``options["reset_mask"]`` checked as Gymnasium's vector envs check it, or None."""
    if options is None or "reset_mask" not in options:
        return None
    mask = options["reset_mask"]
    if not isinstance(mask, np.ndarray):
        raise TypeError(f"options['reset_mask']: must be a numpy array, got {type(mask)}")
    if mask.shape != (n,):
        raise ValueError(f"options['reset_mask']: must have shape ({n},), got {mask.shape}")
    if mask.dtype != np.bool_:
        raise TypeError(f"options['reset_mask']: must have dtype bool, got {mask.dtype}")
    if not mask.any():
        raise ValueError("options['reset_mask']: must hold at least one True value")
    return mask


class SpinStrikeVectorEnv(_ShowsWhatItPays, _SpecOfScene, VectorEnv):
    """Native vector env: N elements in one batched world, in one of Gymnasium's autoreset modes.

    ``autoreset_mode`` (``gym.make_vec(id, n, autoreset_mode=...)``: a
    ``gymnasium.vector.AutoresetMode`` or its name as a string; reported as the enum in
    ``metadata["autoreset_mode"]``), each exactly as Gymnasium's ``SyncVectorEnv`` of single
    envs in that mode:

    * ``NEXT_STEP`` (the default, as in Gymnasium): the step that ends an episode returns its
      last observation; the element's next ``step`` ignores its action and resets it, returning
      the new episode's first observation with reward 0, ``terminated = truncated = False`` and
      the reset's info.
    * ``SAME_STEP``: a finished element is reset within the same ``step``; its last observation
      and info are in ``info["final_obs"]`` / ``info["final_info"]`` (with ``_final_obs``
      masks). One call of the physics per step (the SB3 adapter and the speed benchmark use it).
    * ``DISABLED``: no autoreset; reset finished elements with
      ``reset(options={"reset_mask": mask})`` before the next ``step`` (else ``ResetNeeded``).

    ``max_episode_steps`` truncates by itself, read as ``gym.make`` reads it: ``None`` is the
    registered limit (``MAX_EPISODE_STEPS``), ``-1`` no limit; the step that reaches the limit
    is ``truncated`` also when it terminates (as Gymnasium's ``TimeLimit``). Info arrays are as
    ``SyncVectorEnv``'s: each ``_key`` mask a fresh array, zeros where it is False.
    """

    #: the registered ``max_episode_steps`` (``envs._ENTRY``): what ``None`` means
    MAX_EPISODE_STEPS: ClassVar[int | None] = None

    TASK: ClassVar[type[Task]]
    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 50,
                                          "autoreset_mode": AutoresetMode.NEXT_STEP}

    def _after_users_step(self, paid: np.ndarray | None, before: Any) -> None:
        """A user's ``step`` paid ``paid``: each element's frame shows it, its return
        ``before`` it plus ``paid``."""
        steps, returns = before
        if (paid is not None and paid.size == self.num_envs and self._started
                and self._base_steps != steps):
            self.task.show_rewards(paid.reshape(self.num_envs), returns)

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 render_mode: str | None = None, config: dict | None = None,
                 autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
                 **kwargs: Any) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ConfigError(f"render_mode: must be one of {self.metadata['render_modes']} or "
                              f"None (got {render_mode!r}); gym.make_vec(..., "
                              f"vectorization_mode='sync') takes every mode of the single env")
        if (isinstance(num_envs, (bool, np.bool_)) or not isinstance(num_envs, (int, np.integer))
                or num_envs < 1):
            raise ConfigError(f"num_envs: must be an int >= 1 (got {num_envs!r})")
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        # per instance: the class-level dict is shared by every instance of the class
        self.metadata = dict(self.metadata, autoreset_mode=self.autoreset_mode)
        self._same_step = self.autoreset_mode is AutoresetMode.SAME_STEP
        self.num_envs = int(num_envs)
        self.render_mode = render_mode
        self.max_episode_steps = episode_limit(max_episode_steps, self.MAX_EPISODE_STEPS)
        #: ``None`` was given: the limit is the registration's, read when ``gym.make_vec`` sets
        #: the spec (it passes a variant's registered limit only where the key is absent)
        self._registered_limit = max_episode_steps is None
        self.cfg = parse_config(self.TASK.CONFIG, config, kwargs)
        self.task = self.TASK(self.cfg, self.num_envs)
        # frames as the single envs draw them, where the task traces every element (a control
        # env's trail and return); a strike's clip is element 0's only, so not traced here
        self.task.record_trace = render_mode is not None and self.task.TRACES_EVERY_ELEMENT
        self.metadata["render_fps"] = self.task.render_fps  # as the single env's (a control dt)
        self.single_action_space = self.task.action_space
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_observation_space = self.task.observation_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self._stream = UniformStream(self.num_envs, self.TASK.UNIFORMS)
        self._steps = np.zeros(self.num_envs, dtype=np.int64)
        #: elements whose episode ended at the last step (NEXT_STEP: reset at the next one)
        self._done = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    @property
    def world(self):
        return self.task.world

    @_SpecOfScene.spec.setter
    def spec(self, spec: EnvSpec | None) -> None:
        """Set by ``gym.make_vec`` after the env is made. ``max_episode_steps=None`` given
        explicitly reached the env as None, which read as the class's limit (250) where
        ``gym.make`` and ``SyncVectorEnv`` use the variant's registered one (100): now read
        from the spec. A limit among a registration's ``kwargs``, which ``gym.make`` refuses,
        is refused here too (the native env truncated by it)."""
        registered = gym.registry.get(spec.id) if spec is not None else None
        if registered is not None and "max_episode_steps" in registered.kwargs:
            raise ConfigError(
                f"max_episode_steps: {spec.id} registers it among its kwargs, which gym.make "
                f"refuses (it is Gymnasium's argument, not the env's): register it as "
                f"gym.register(..., max_episode_steps="
                f"{registered.kwargs['max_episode_steps']!r})")
        _SpecOfScene.spec.fset(self, spec)
        if (spec is not None and self.__dict__.get("_registered_limit")
                and spec.max_episode_steps is not None):
            self.max_episode_steps = episode_limit(spec.max_episode_steps,
                                                   self.MAX_EPISODE_STEPS)

    @property
    def np_random_seed(self) -> tuple[int, ...]:
        """Each element's seed, as ``SyncVectorEnv`` reports its envs' (``reset(seed=4)``:
        4, 5, 6, ...); an element never seeded reports the seed its generator was drawn from,
        as a single env does, so ``reset(seed=list(envs.np_random_seed))`` replays it."""
        return tuple(self._stream.seeds)

    def get_random_state(self) -> UniformStream:
        """A copy of the elements' random streams (their generators' states and the rows drawn
        ahead): what a training checkpoint keeps, so a resumed run's resets draw the tasks that
        come next, not the seed's first ones again."""
        return copy.deepcopy(self._stream)

    def set_random_state(self, state: UniformStream) -> None:
        """Put back streams from :meth:`get_random_state` (of a vector env of this size and
        task); the next reset of each element draws from where they were."""
        if not isinstance(state, UniformStream) or (state.batch_size, state.width) != (
                self.num_envs, self.TASK.UNIFORMS):
            raise ValueError(f"state: random streams of {self.num_envs} elements and "
                             f"{self.TASK.UNIFORMS} uniforms a reset (get_random_state() of a "
                             f"vector env like this one), got {state!r}")
        self._stream = copy.deepcopy(state)
        self._np_random = self._stream.generators[0]

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        n = self.num_envs
        mask = _reset_mask(options, n)
        if mask is not None and not self._started:
            raise gym.error.ResetNeeded("options['reset_mask']: call reset() on every element "
                                        "first")
        if seed is not None:
            if isinstance(seed, numbers.Integral):
                seeds = [int(seed) + i for i in range(n)]
            elif isinstance(seed, (list, tuple, np.ndarray)):
                seeds = list(seed)
            else:
                raise gym.error.Error(f"Seed must be a python integer or a list of {n} "
                                      f"(integers or None), actual type: {type(seed)}")
            if len(seeds) != n:
                raise ValueError(f"seed: expected {n} seeds, got {len(seeds)}")
            chosen = [i for i in range(n) if seeds[i] is not None
                      and (mask is None or mask[i])]
            self._stream.seed([seeds[i] for i in chosen], np.asarray(chosen, dtype=np.int64))
        self._np_random = self._stream.generators[0]
        env = np.arange(n) if mask is None else np.flatnonzero(mask)
        info = self.task.reset(env, self._stream.draw(env))
        self._steps[env] = 0
        self._done[env] = False
        self._started = True
        return self.task.observations(), _masked(info, env, n)

    def step(self, actions):
        if not self._same_step:
            return self._step_next(actions) if self.autoreset_mode is AutoresetMode.NEXT_STEP \
                else self._step_disabled(actions)
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before step()")
        reward, terminated, truncated, info = self._physics_step(actions)
        obs = self.task.observations()
        done = terminated | truncated
        if done.any():  # as SyncVectorEnv: a reset element's info is its reset's
            env = np.flatnonzero(done)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in env:
                final_obs[i] = _take(obs, i)
            final_info = _only(info, done)
            reset_info = self.task.reset(env, self._stream.draw(env))
            self._steps[env] = 0
            obs = self.task.observations()
            info = _merge(_only(info, ~done), _masked(reset_info, env, self.num_envs))
            info.update(final_obs=final_obs, _final_obs=done, final_info=final_info,
                        _final_info=done.copy())
        return obs, reward, terminated, truncated, info

    def _physics_step(self, actions):
        """Step every element: (reward, terminated, truncated, info with ``_key`` masks)."""
        reward, terminated, info = self.task.step(actions)
        if self.render_mode is not None:  # (a task subclass may pay other than it computed)
            self._base_steps += 1
            self.task.show_rewards(reward)
        self._steps += 1
        truncated = np.zeros(self.num_envs, dtype=bool)
        if self.max_episode_steps is not None:
            truncated = self._steps >= self.max_episode_steps
        out = {}
        for k, v in info.items():
            out[k] = v
            out[f"_{k}"] = np.ones(self.num_envs, dtype=bool)
        return reward.astype(np.float64), terminated, truncated, out

    def _step_disabled(self, actions):
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before step()")
        if self._done.any():
            raise gym.error.ResetNeeded(
                f"autoreset_mode DISABLED: elements {np.flatnonzero(self._done).tolist()} ended "
                "their episodes; reset them with reset(options={'reset_mask': mask}) first")
        reward, terminated, truncated, info = self._physics_step(actions)
        self._done = terminated | truncated
        return self.task.observations(), reward, terminated, truncated, info

    def _step_next(self, actions):
        if not self._started:
            raise gym.error.ResetNeeded("call reset() before step()")
        pending = self._done
        n = self.num_envs
        if not pending.any():
            reward, terminated, truncated, info = self._physics_step(actions)
        elif pending.all():  # every element starts a new episode (e.g. after a one-strike step)
            # the actions are not used, but a wrong shape or type is refused as on every other
            # step (it passed here, every other step on a one-strike env; NaN passes, as in
            # SyncVectorEnv, whose resetting envs ignore their actions)
            a = np.asarray(actions)
            if a.shape != self.task.action_shape or a.dtype.kind not in "iuf":
                check_actions(actions, self.task.action_shape)
            env = np.arange(n)
            info = _masked(self.task.reset(env, self._stream.draw(env)), env, n)
            self._steps[:] = 0
            reward = np.zeros(n)
            terminated = np.zeros(n, dtype=bool)
            truncated = np.zeros(n, dtype=bool)
        else:
            # the batch steps every element: the ones being reset step from their new first
            # state (an action of zeros), then are put back to it (the same uniforms)
            env = np.flatnonzero(pending)
            a = np.array(actions)  # a copy
            if a.shape == self.task.action_shape and a.dtype.kind in "iuf":
                a[env] = 0  # (their actions are not used, as SyncVectorEnv's resetting envs')
            try:  # checked before the draw: a refused step leaves the random streams as they were
                a = check_actions(a, self.task.action_shape)
            except ValueError:
                check_actions(actions, self.task.action_shape)  # the message shows them as given
                raise
            u = self._stream.draw(env)
            self.task.reset(env, u)
            reward, terminated, truncated, info = self._physics_step(a)
            reset_info = self.task.reset(env, u)
            self._steps[env] = 0
            reward[env] = 0.0
            terminated[env] = False
            truncated[env] = False
            info = _merge(_only(info, ~pending), _masked(reset_info, env, n))
        self._done = terminated | truncated
        return self.task.observations(), reward, terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode")
            return None
        return tuple(self.task.render(b) for b in range(self.num_envs))

    def close_extras(self, **kwargs: Any) -> None:
        task = self.__dict__.get("task")  # absent when __init__ raised (VectorEnv.__del__)
        if task is not None:
            task.close()


def _only(info: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    """Vector infos (``key`` and ``_key`` mask) kept for elements ``mask`` only: zeros
    elsewhere, as ``SyncVectorEnv`` leaves an element that did not report a key; no keys
    when ``mask`` selects none."""
    out = {}
    if not mask.any():
        return out
    everyone = mask.all()  # nothing to zero (a one-strike env's every step)
    for k, v in info.items():
        if k.startswith("_"):
            continue
        if not everyone:
            v = np.where(mask.reshape(-1, *[1] * (v.ndim - 1)), v, np.zeros((), v.dtype))
        out[k], out[f"_{k}"] = v, mask.copy()
    return out


def _merge(info: dict[str, np.ndarray], more: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Two vector infos over disjoint elements in one (a key in both: each one's values)."""
    out = dict(info)
    for k, v in more.items():
        if k.startswith("_"):
            continue
        m = more[f"_{k}"]
        if k in out:
            out[k] = np.where(m.reshape(-1, *[1] * (v.ndim - 1)), v, out[k])
            out[f"_{k}"] = out[f"_{k}"] | m
        else:
            out[k], out[f"_{k}"] = v, m.copy()
    return out


def _masked(info: dict[str, np.ndarray], env: np.ndarray, n: int) -> dict[str, np.ndarray]:
    """Arrays over elements ``env`` as Gymnasium vector infos: ``[n, ...]`` values (zeros
    elsewhere) with ``_key`` masks."""
    mask = np.zeros(n, dtype=bool)
    mask[env] = True
    out = {}
    for k, v in info.items():
        v = np.asarray(v)
        if len(env) == n:
            full = v
        else:
            full = np.zeros((n, *v.shape[1:]), dtype=v.dtype)
            full[env] = v
        out[k], out[f"_{k}"] = full, mask.copy()
    return out
