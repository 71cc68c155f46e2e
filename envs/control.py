"""Control envs: ``SpinStrike/RodSpinControl-v0`` and ``SpinStrike/PuckSpeedControl-v0``.

The agent drives a mallet (a dynamic disk of finite mass, ``driven`` in the scene) around a walled
table by a bounded force, under a speed limit; no body of infinite mass ever moves, so every
impulse stays finite. Each control step is one ``world.step(dt)`` of the exact solver, and the
reward is the spin (or speed) the mallet's hits add to the rod (or puck) during that step.
"""

from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from spinstrike.envs import fast
from spinstrike.envs.config import (
    ConfigError,
    ControlConfig,
    build_scene,
    build_world,
    reset_room_error,
)
from spinstrike.envs.core import (
    SpinStrikeEnv,
    SpinStrikeVectorEnv,
    Task,
    action_error,
    check_actions,
)
from spinstrike.envs.fast import CONTROL_STEP, limit_force
from spinstrike.envs.layout import SPEED_SCALE, SPIN_SCALE, control_layout, layout_table
from spinstrike.envs.rendering import BodyDraw, Frame, Gauge, Marker, body_draws, body_points
from spinstrike.physics.layout import FALLBACK_NONFINITE, FORCE

__all__ = ["PuckSpeedControlEnv", "PuckSpeedControlTask", "PuckSpeedControlVectorEnv",
           "RodSpinControlEnv", "RodSpinControlTask", "RodSpinControlVectorEnv", "limit_force"]

#: distance (m) kept between the bodies and from the cushions when placing them at reset
CLEARANCE = 0.02
#: a control episode's registered length (``max_episode_steps``): 250 steps of 0.02 s
EPISODE_STEPS = 250
#: steps over which a body's motion trail reaches back in the video frames
TRAIL_STEPS = 12
#: contacts recorded a step (``hit_impulse`` counts every hit, recorded or not): a rod pressed
#: into a cushion and settled made up to ~150, more than a world's default 64
CONTROL_CONTACTS = 256


class _ControlTask(Task):
    """Mallet and target on a walled table, batched."""

    TARGET: ClassVar[str]
    SCENE: ClassVar[str]
    CONFIG = ControlConfig
    ACTIONS = ("force_x", "force_y")
    OBS_CLIPPED = True
    TRACES_EVERY_ELEMENT = True
    UNIFORMS = len(ControlConfig.RANDOMIZABLE) + 5
    SHAPES = {"mallet": ("disk", "the agent drives a mallet disk (its angle is not observed)")}
    NEEDS = {"walls": "its mallet and target play on a walled table (the observation and the "
                      "resets are scaled to the cushions)"}

    def __init__(self, cfg, batch_size: int, single: bool = False) -> None:
        super().__init__(cfg, batch_size, single)
        # real time: 1 / dt (an int where it is one; rounded, dt = 0.4 s played at 0.8x)
        fps = 1.0 / cfg.dt
        self.render_fps = round(fps) if abs(fps - round(fps)) < 1e-9 * fps else fps
        overrides = {"mallet": {"mass": cfg.mallet_mass}, self.TARGET: {"mass": cfg.target_mass}}
        scene = build_scene(self.SCENE, cfg, overrides, (self.TARGET, "mallet"), self.NEEDS,
                            shapes=self.SHAPES, placed={self.TARGET: 1, "mallet": -1},
                            clearance=CLEARANCE)
        self.world = build_world(scene, batch_size, CONTROL_CONTACTS)
        w = self.world
        if not w.walls or not w.driven[w.index("mallet")]:
            raise ConfigError("scene: a control env needs the 'walls' effect and a driven "
                              "'mallet' body")
        self.im = w.index("mallet")
        self.it = w.index(self.TARGET)
        self._check_room()
        w.watch(self.TARGET, "mallet")  # info['hits'] counts every hit, recorded or not
        # the fused step's buffers (envs.fast): actions in; observation, reward, info out
        self.tbuf = np.zeros((batch_size, fast.T_COLUMNS))
        #: the world's revision the observations in tbuf were written at (see observe)
        self._observed = -1
        k = np.zeros(fast.K_SIZE)
        k[[fast.K_MAX_FORCE, fast.K_MAX_SPEED, fast.K_SCALE, fast.K_MEASURE]] = (
            cfg.max_force, cfg.max_speed, self.SCALE, self.MEASURE)
        k[[fast.K_MALLET, fast.K_TARGET, fast.K_SPEED_SCALE, fast.K_SPIN_SCALE]] = (
            self.im, self.it, SPEED_SCALE, SPIN_SCALE)
        k[fast.K_LOW:fast.K_LOW + fast.OBS_SIZE] = self.obs_low
        k[fast.K_HIGH:fast.K_HIGH + fast.OBS_SIZE] = self.obs_high
        self.kcfg = k
        self._never = np.zeros(batch_size, dtype=bool)
        self._never.flags.writeable = False
        # every element's recent poses and return, for the video frames (``record_trace``):
        # the poses (x, y, angle of each body) of the last TRAIL_STEPS steps in a ring
        # ``[TRAIL_STEPS, B, N, 3]`` every element writes at once (made when first needed),
        # ``_kept[b]`` of them element b's own (its episode's), the newest at ``_head - 1``
        self._poses: np.ndarray | None = None
        self._kept = np.zeros(batch_size, dtype=np.int64)
        self._head = 0
        self._returns = np.zeros(batch_size)
        #: each element's last step reward as its frame shows it (what the env paid)
        self._shown = np.zeros(batch_size)
        #: each element's resets so far (a return from before its episode began is not its)
        self._episodes = np.zeros(batch_size, dtype=np.int64)
        # whether element b has stepped since its last reset or state put back: only then do
        # the world's last contacts and the step reward in tbuf belong to what its frame shows
        # (a reset frame drew the last episode's final impulse arrows and reward at t = 0);
        # element 0's last step as a state put back brought it (its reward, its contacts'
        # markers), else None
        self._stepped = np.zeros(batch_size, dtype=bool)
        self._put_back: tuple[float, list[Marker]] | None = None

    def _check_room(self) -> None:
        """A reset puts the target at any angle in the right half and the mallet in the left,
        ``CLEARANCE`` from the cushions: refuse a table too small for that."""
        w = self.world
        error = reset_room_error(
            [2 * float(h) for h in w.table_half_size[0]],
            {self.TARGET: (float(w.half_length[0, self.it] + w.radius[0, self.it]), 1),
             "mallet": (float(w.radius[0, self.im]), -1)}, CLEARANCE)
        if error:
            raise ConfigError(error)

    @property
    def _actions(self) -> np.ndarray:
        """The actions' columns of ``tbuf``, a view made when asked: a view kept as an attribute
        became an array of its own in a pickled or deep-copied env, whose actions then never
        reached the step."""
        return self.tbuf[:, fast.T_ACTION:fast.T_ACTION + len(self.ACTIONS)]

    def _set_random(self, edit, key, value) -> None:
        if key == "mallet_mass":
            edit.set_body("mallet", mass=value)
        elif key == "target_mass":
            edit.set_body(self.TARGET, mass=value)
        elif key == "restitution":
            edit.set_material(self.TARGET, "mallet", restitution=value)
        elif key == "table_friction":
            edit.set_table(friction=value)

    def reset(self, env, uniforms) -> dict[str, np.ndarray]:
        n_rand = len(self.CONFIG.RANDOMIZABLE)
        u = uniforms[:, n_rand:]
        w = self.world
        n = len(env)
        current = self._observed == w.revision  # the others' observations hold after this
        with w.edit(env) as e:
            self._apply_random(e, uniforms[:, :n_rand])
            hw = e.table_half_size
            reach_t = e.half_length[:, self.it] + e.radius[:, self.it] + CLEARANCE
            rm = e.radius[:, self.im] + CLEARANCE
            # target in the right half, mallet in the left half: they never overlap at reset
            angle = 2 * math.pi * u[:, 0] - math.pi
            tx = reach_t + u[:, 1] * np.maximum(hw[:, 0] - 2 * reach_t, 0.0)
            ty = (2 * u[:, 2] - 1) * np.maximum(hw[:, 1] - reach_t, 0.0)
            mx = -rm - u[:, 3] * np.maximum(hw[:, 0] - 2 * rm, 0.0)
            my = (2 * u[:, 4] - 1) * np.maximum(hw[:, 1] - rm, 0.0)
            pos = np.zeros((n, w.n_bodies, 2))
            pos[:, self.it] = np.stack([tx, ty], 1)
            pos[:, self.im] = np.stack([mx, my], 1)
            angles = np.zeros((n, w.n_bodies))
            angles[:, self.it] = angle
            e.set_state(positions=pos, angles=angles, velocities=0.0, omegas=0.0)
            e.set_force("mallet", 0.0)
            e.set_time(0.0)
        buf = w.buffers
        fast.control_observe(buf.fbuf, buf.ibuf, self.tbuf, self.kcfg,
                             np.asarray(env, dtype=np.int64))
        if current:
            self._observed = w.revision
        self._stepped[env] = False
        self._episodes[env] += 1
        if 0 in np.arange(self.batch_size)[env]:
            self._put_back = None
        if self.record_trace:
            self._returns[env] = 0.0
            self._restart_trails(env)
        return {}

    def _remember(self) -> None:
        """Add every element's pose to its motion trail (when recording)."""
        if not self.record_trace:
            return
        poses = self._ring()
        st = self.world.state
        poses[self._head, :, :, :2] = st.positions
        poses[self._head, :, :, 2] = st.angles
        self._head = (self._head + 1) % TRAIL_STEPS
        np.minimum(self._kept + 1, TRAIL_STEPS, out=self._kept)

    def _restart_trails(self, env) -> None:
        """Elements ``env``'s trails start again at their current poses (a reset, a state put
        back): the newest slot of the ring holds them, and only it."""
        poses = self._ring()
        st = self.world.state
        newest = (self._head - 1) % TRAIL_STEPS
        poses[newest, env, :, :2] = st.positions[env]
        poses[newest, env, :, 2] = st.angles[env]
        self._kept[env] = 1

    def _ring(self) -> np.ndarray:
        """The ring of poses, made at its first use (only an env that records needs it)."""
        if self._poses is None:
            self._poses = np.zeros((TRAIL_STEPS, self.batch_size, self.world.n_bodies, 3))
        return self._poses

    def _slots(self, b: int) -> list[int]:
        """The ring's slots of element b's trail, oldest first."""
        k = int(self._kept[b]) if self._poses is not None else 0
        return [(self._head - k + i) % TRAIL_STEPS for i in range(k)]

    def _trail(self, b: int) -> list[list[list[tuple[float, float]]]]:
        """Element b's motion trail, oldest step first: each step's points of every body
        (``rendering.body_points``: a centre, and a rod's tips)."""
        w = self.world
        steps = []
        for slot in self._slots(b):
            pose = self._poses[slot, b]
            steps.append([body_points(BodyDraw(w.names[j], pose[j, 0], pose[j, 1], pose[j, 2],
                                               w.radius[b, j], w.half_length[b, j], 0.0, 0.0,
                                               0.0)) for j in range(w.n_bodies)])
        return steps

    def step(self, actions, batch_info: bool = True):
        a = np.asarray(actions)
        if a.shape != self.action_shape or a.dtype.kind not in "iuf":
            check_actions(a, self.action_shape)  # raises the error that names the problem
        self._actions[...] = a  # checked for NaN and clipped by the compiled step
        worst = self.world.run(CONTROL_STEP, self.tbuf, self.kcfg, dt=self.cfg.dt)
        if worst < 0:
            raise ValueError(action_error(actions))
        if worst >= FALLBACK_NONFINITE:  # a state float64 cannot carry or place: raised
            self.world.check_fallback()
        self._observed = self.world.revision  # the step observed every element
        t = self.tbuf
        reward = t[:, fast.T_REWARD].copy()
        self._stepped[:] = True
        self._put_back = None
        if self.record_trace:
            self._returns += reward
            self._shown[:] = reward
            self._remember()
        if not batch_info:
            return reward, self._never, None
        info = {"hits": t[:, fast.T_HITS].astype(np.int64),
                "hit_impulse": t[:, fast.T_IMPULSE].copy(),
                "force": t[:, fast.T_FORCE:fast.T_FORCE + len(FORCE)].copy(),
                "spin": t[:, fast.T_SPIN].copy(), "speed": t[:, fast.T_SPEED].copy(),
                "mallet_speed": t[:, fast.T_MALLET_SPEED].copy(),
                "reward_hit": t[:, fast.T_REWARD].copy(),
                "fallback": t[:, fast.T_FALLBACK] != 0}
        return reward, np.zeros(self.batch_size, dtype=bool), info

    def info_row(self, b: int, info=None) -> dict:
        """The step's info of element ``b`` as plain Python values (single env)."""
        r = self.tbuf[b].tolist()
        return {"hits": int(r[fast.T_HITS]), "hit_impulse": r[fast.T_IMPULSE],
                "force": self.tbuf[b, fast.T_FORCE:fast.T_FORCE + len(FORCE)].copy(),
                "spin": r[fast.T_SPIN], "speed": r[fast.T_SPEED],
                "mallet_speed": r[fast.T_MALLET_SPEED], "reward_hit": r[fast.T_REWARD],
                "fallback": r[fast.T_FALLBACK] != 0}

    def observe(self) -> np.ndarray:
        """Observations as the fused step (or the last reset) left them, clipped already; of
        the world as it is now where it was edited or put back since (``world.edit()`` in a
        subclass's reset, ``set_physics_state``: they kept the old pose, walk W21b)."""
        w = self.world
        if self._observed != w.revision:
            buf = w.buffers
            fast.control_observe(buf.fbuf, buf.ibuf, self.tbuf, self.kcfg,
                                 np.arange(self.batch_size, dtype=np.int64))
            self._observed = w.revision
        return self.tbuf[:, fast.T_OBS:fast.T_OBS + fast.OBS_SIZE]

    def snapshot(self) -> dict:
        # what element 0's frame says: its episode's return (kept while recording, else 0), its
        # last step's reward and impulse markers (none since a reset)
        reward, markers = self._last_step(0)
        return {"return": float(self._returns[0]), "step_reward": reward,
                "markers": [dataclasses.astuple(m) for m in markers]}

    def _last_step(self, b: int) -> tuple[float, list[Marker]]:
        """Element ``b``'s last step as its frame shows it: the step reward and the markers of
        its contacts (0 and none before its episode's first step)."""
        if self._stepped[b]:
            c = self.world.last_contacts
            reward = self._shown[b] if self.record_trace else self.tbuf[b, fast.T_REWARD]
            return float(reward), [
                Marker.on(self.it, c.body_a[i], c.body_b[i], c.point[i], c.normal[i],
                          c.impulse[i]) for i in np.flatnonzero((c.batch == b) & ~c.held)]
        if b == 0 and self._put_back is not None:
            return self._put_back
        return 0.0, []

    def show_rewards(self, rewards: np.ndarray, returns_before=None) -> bool:
        if not self.record_trace:
            return False
        stepped = self._stepped
        paid = np.asarray(rewards, dtype=np.float64)[stepped]
        if returns_before is None:
            before = (self._returns - self._shown)[stepped]
        else:  # (0 for an element whose episode began since: a user's step that resets)
            returns, episodes = returns_before
            before = np.where(episodes == self._episodes, returns, 0.0)[stepped]
        changed = not (np.array_equal(paid, self._shown[stepped])
                       and np.array_equal(before + paid, self._returns[stepped]))
        self._returns[stepped] = before + paid
        self._shown[stepped] = paid
        return changed

    def shown_returns(self) -> tuple[np.ndarray, np.ndarray] | None:
        return (self._returns.copy(), self._episodes.copy()) if self.record_trace else None

    def trace(self) -> dict:
        slots = self._slots(0)
        return {"poses": self._poses[slots, 0].copy() if slots else [],
                "return": float(self._returns[0])}

    def put_trace(self, trace: dict) -> None:
        poses = trace.get("poses", ())  # (a trace pickled before poses were kept: no trail)
        self._returns[0] = float(trace.get("return", 0.0))
        self._kept[0] = len(poses)
        if len(poses):
            self._poses = None  # a fresh ring: the copy's own poses, element 0's trail only
            self._ring()[:len(poses), 0] = poses
            self._head = len(poses) % TRAIL_STEPS

    def restore(self, snap: dict) -> None:
        # the trail starts again at the restored pose (it joined the poses before the jump to
        # the restored ones with streaks across the table); the frame says the snapshot's return
        self._returns[0] = float(snap.get("return", 0.0))
        # the last step's reward and markers are the snapshot's (those of this env's last step
        # were another state's)
        self._stepped[0] = False
        self._put_back = (float(snap.get("step_reward", 0.0)),
                          [Marker(*m) for m in snap.get("markers", ())])
        if self.record_trace:
            self._restart_trails(np.array([0]))

    def frame(self, b: int, decorate: bool = True) -> Frame:
        w = self.world
        bodies = body_draws(self.world, b)
        hw = w.table_half_size[b]
        half = (float(hw[0]), float(hw[1]))
        target = bodies[self.it]
        spin = f"spin {target.omega:+6.2f} rad/s"
        speed = f"speed {math.hypot(target.vx, target.vy):.2f} m/s"
        if not decorate:  # the pixel observation (its pixels are a contract: keep it plain)
            return Frame(bodies, half, walls=True, text=f"{spin}   {speed}")
        step_reward, markers = self._last_step(b)
        trails = []
        trail = self._trail(b) if self.record_trace else []
        if trail:
            trails = [[pose[i][k] for pose in trail]
                      for i in range(len(bodies)) for k in range(len(trail[-1][i]))]
        ret = f"   return {self._returns[b]:+.3f}" if self.record_trace else ""
        name = self.TARGET
        return Frame(bodies, half, walls=True, trails=trails, markers=markers, smooth=True,
                     gauge=Gauge(self.GAUGE, self._gauge_value(target), None, 0.0,
                                 self.GAUGE_TOP),
                     panel=[f"{self.title}   t = {w.time[b]:5.2f} s   real time (x1)",
                            f"{name} {spin}   {speed}",
                            f"reward {step_reward:+.3f} (step){ret}"])

    def view_half(self) -> tuple[float, float]:
        hw = self.world.table_half_size[0]
        return float(hw[0]) + 0.03, float(hw[1]) + 0.03


class RodSpinControlTask(_ControlTask):
    TARGET = "rod"
    SCENE = "rod_control"
    SHAPES = {**_ControlTask.SHAPES,
              "rod": ("rod", "its reward is a rod's spin (a disk turns only by contact friction) "
                             "and its observation a rod's")}
    NEEDS = {**_ControlTask.NEEDS,
             "rotation": "its reward is the rod's spin, which a scene without rotation never "
                         "changes (reward 0 for every action)"}
    SCALE = SPIN_SCALE
    MEASURE = fast.MEASURE_SPIN
    LAYOUT = control_layout("rod")
    TITLE = "RodSpinControl-v0"
    GAUGE, GAUGE_TOP = "rod |spin| (rad/s)", SPIN_SCALE

    def _gauge_value(self, rod: BodyDraw) -> float:
        return abs(rod.omega)



class PuckSpeedControlTask(_ControlTask):
    TARGET = "puck"
    SCENE = "puck_control"
    SCALE = SPEED_SCALE
    MEASURE = fast.MEASURE_SPEED
    LAYOUT = control_layout("puck")
    TITLE = "PuckSpeedControl-v0"
    GAUGE, GAUGE_TOP = "puck speed (m/s)", SPEED_SCALE

    def _gauge_value(self, puck: BodyDraw) -> float:
        return math.hypot(puck.vx, puck.vy)



_CONTROL_DOC = """{summary}

    ## Description
    A mallet (a driven disk, 0.3 kg) and a {target} share a 1.2 m x 0.8 m walled table with cloth
    friction. Each step the agent's action pushes the mallet with a constant force for ``dt``
    (0.02 s) seconds, simulated by the exact solver (contacts, cushions, cloth friction in closed
    form). The mallet has a speed limit (``max_speed``, 3 m/s): a force that would end the step
    faster in free flight is replaced by the one that ends it at the limit, nearest in velocity
    (so it may turn as well as shrink), cut to ``max_force``; a mallet a hit has pushed beyond
    the limit slows to it, and a step with a hit may end above it: the target's push within
    the step is not limited (at the defaults up to 3.37 m/s under random actions and 3.6 when
    pushing at the target; 8.5 m/s with ``mallet_mass`` 0.001; 3.027 m/s after a cushion
    bounce, the force acting on after it).

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: the force (x, y) as a fraction of ``max_force`` (8 N); the box
    is mapped onto the unit disk (a longer action keeps its direction at full force). NaN or
    infinite actions raise ``ValueError``; finite values outside [-1, 1] are clipped.

    ## Observation Space
    ``Box(float32)``, each entry clipped to its bounds:

{layout}

    ## Rewards
    {reward}, computed after the physics step, and only in steps in which the mallet touches
    the {target} (``info['hits']``): what the step added (or took away), so a cushion bounce or
    cloth friction in the same step counts with the hit (a chase policy's rod hits share their
    step with a cushion impact about three times in four); in steps without a hit cushions and
    cloth friction earn nothing.

    ## Starting State
    {target_cap} at rest at a random pose in the right half, mallet at rest in the left half,
    both 0.02 m clear of the cushions (their positions in a ``scene`` are not used; a table too
    small for this is refused at ``gym.make`` with the least size that fits).

    ## Episode End
    Never terminates; truncated after ``max_episode_steps`` (250 steps = 5 s, set at
    registration; the native vector env truncates by itself).

    ## Arguments
    See :class:`spinstrike.envs.config.ControlConfig`: ``dt``, ``max_force``, ``max_speed``,
    ``mallet_mass``, ``target_mass``, restitution, friction, effects, solver, randomisation
    ranges, obs_mode, and ``render_mode``; or one ``config`` dict.

    ## Info
    ``hits`` (every mallet-target impulse of the step), ``hit_impulse`` (N s, their sum, every
    one: a settled step of a mallet pushing the rod at e = 0 makes ~1,500), ``force`` (N, after
    the speed limit), ``spin``, ``speed``, ``mallet_speed``, ``reward_hit``, ``fallback`` (the
    solver settled a resting contact, or solved a jam without its contact friction:
    ``physics.StepStats``).

    ## Rendering
    One frame per step (real time at ``render_fps`` = 1 / ``dt``): ``"rgb_array"`` (the current
    frame), ``"rgb_array_list"`` (the frames since the last ``render()``), ``"human"`` (a
    window). Overlays: time, the {target}'s spin and speed, the step's reward and the return,
    impulse markers of the step's contacts, motion trails. Frames are ``render_size``
    (720 x 480, the whole table in view); pixel observations ``obs_size`` (480 x 320), without
    overlays.

    ## Version History
    * v0: initial version. Since 2026-11-23 the exact solver puts a mallet its force drives into
      a cushion at rest on it (the end of its Zeno bounces) instead of settling those steps with
      fixed substeps, which left it bouncing off at a few mm/s: in such steps trajectories
      differ from earlier releases; observations, actions and rewards are defined as before.
    """


class _ControlEnv(SpinStrikeEnv):
    metadata = dict(SpinStrikeEnv.metadata, render_fps=50)


class RodSpinControlEnv(_ControlEnv):
    TASK = RodSpinControlTask


class PuckSpeedControlEnv(_ControlEnv):
    TASK = PuckSpeedControlTask


RodSpinControlEnv.__doc__ = _CONTROL_DOC.format(
    summary="Spin a rod by hitting it with a mallet you push around a walled table.",
    target="rod", target_cap="Rod", layout=layout_table(RodSpinControlTask.LAYOUT),
    reward=f"``reward = (|w_after| - |w_before|) / {SPIN_SCALE}`` (rod spin, rad/s)")
PuckSpeedControlEnv.__doc__ = _CONTROL_DOC.format(
    summary="Send a puck fast by hitting it with a mallet you push around a walled table.",
    target="puck", target_cap="Puck", layout=layout_table(PuckSpeedControlTask.LAYOUT),
    reward=f"``reward = (|v_after| - |v_before|) / {SPEED_SCALE}`` (puck speed, m/s)")


class RodSpinControlVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`RodSpinControlEnv` (one batched world)."""

    TASK = RodSpinControlTask
    MAX_EPISODE_STEPS = EPISODE_STEPS


class PuckSpeedControlVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`PuckSpeedControlEnv` (one batched world)."""

    TASK = PuckSpeedControlTask
    MAX_EPISODE_STEPS = EPISODE_STEPS
