"""Control envs: ``SpinStrike/RodSpinControl-v0`` and ``SpinStrike/PuckSpeedControl-v0``.

The agent drives a mallet (a dynamic disk of finite mass, ``driven`` in the scene) around a walled
table by a bounded force, under a speed limit; no body of infinite mass ever moves, so every
impulse stays finite. Each control step is one ``world.step(dt)`` of the exact solver, and the
reward is the spin (or speed) the mallet's hits add to the rod (or puck) during that step.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from spinstrike.envs import fast
from spinstrike.envs.config import ControlConfig, build_scene
from spinstrike.envs.core import (
    ObsField,
    SpinStrikeEnv,
    SpinStrikeVectorEnv,
    Task,
    action_error,
    layout_table,
)
from spinstrike.envs.fast import limit_force
from spinstrike.envs.rendering import BodyDraw, Frame
from spinstrike.physics import World
from spinstrike.physics.layout import CF_DT
from spinstrike.physics.world import PARALLEL_BATCH

__all__ = ["PuckSpeedControlEnv", "PuckSpeedControlVectorEnv", "RodSpinControlEnv",
           "RodSpinControlVectorEnv", "limit_force"]

#: spin (rad/s) and speed (m/s) that count as 1 in observations and rewards
SPIN_SCALE = 20.0
SPEED_SCALE = 3.0
#: distance (m) kept between the bodies and from the cushions when placing them at reset
CLEARANCE = 0.02


class _ControlTask(Task):
    """Mallet and target on a walled table, batched."""

    TARGET: ClassVar[str]
    SCENE: ClassVar[str]
    CONFIG = ControlConfig
    ACTIONS = ("force_x", "force_y")
    OBS_CLIPPED = True
    UNIFORMS = len(ControlConfig.RANDOMIZABLE) + 5

    def __init__(self, cfg, batch_size: int) -> None:
        super().__init__(cfg, batch_size)
        self.render_fps = int(round(1.0 / cfg.dt))
        overrides = {"mallet": {"mass": cfg.mallet_mass}, self.TARGET: {"mass": cfg.target_mass}}
        self.world = World(build_scene(self.SCENE, cfg, overrides), batch_size)
        w = self.world
        if not w.walls or not w.driven[w.index("mallet")]:
            raise ValueError("scene: a control env needs the 'walls' effect and a driven "
                             "'mallet' body")
        self.im = w.index("mallet")
        self.it = w.index(self.TARGET)
        # the fused step's buffers (envs.fast): actions in; observation, reward, info out
        self.tbuf = np.zeros((batch_size, fast.T_COLUMNS))
        k = np.zeros(fast.K_SIZE)
        k[[fast.K_MAX_FORCE, fast.K_MAX_SPEED, fast.K_SCALE, fast.K_MEASURE]] = (
            cfg.max_force, cfg.max_speed, self.SCALE, self.MEASURE)
        k[[fast.K_MALLET, fast.K_TARGET, fast.K_SPEED_SCALE, fast.K_SPIN_SCALE]] = (
            self.im, self.it, SPEED_SCALE, SPIN_SCALE)
        k[fast.K_FIXED] = w.solver.mode == "fixed"
        k[fast.K_LOW:fast.K_LOW + fast.OBS_SIZE] = self.obs_low
        k[fast.K_LOW + fast.OBS_SIZE:] = self.obs_high
        self.kcfg = k
        w._fcfg[CF_DT] = cfg.dt
        self._actions = self.tbuf[:, fast.T_ACTION:fast.T_ACTION + 2]
        self._never = np.zeros(batch_size, dtype=bool)
        self._never.flags.writeable = False

    def _set_random(self, key, value, env) -> None:
        w = self.world
        if key == "mallet_mass":
            w.set_body("mallet", mass=value, env=env)
        elif key == "target_mass":
            w.set_body(self.TARGET, mass=value, env=env)
        elif key == "restitution":
            w.set_material(self.TARGET, "mallet", restitution=value, env=env)
        elif key == "table_friction":
            w.set_table(friction=value, env=env)

    def reset(self, env, uniforms) -> dict[str, np.ndarray]:
        n_rand = len(self.CONFIG.RANDOMIZABLE)
        self._apply_random(env, uniforms[:, :n_rand])
        u = uniforms[:, n_rand:]
        w = self.world
        hw = w.table_half_size[env]
        reach_t = w.half_length[env, self.it] + w.radius[env, self.it] + CLEARANCE
        rm = w.radius[env, self.im] + CLEARANCE
        # target in the right half, mallet in the left half: they never overlap at reset
        angle = 2 * math.pi * u[:, 0] - math.pi
        tx = reach_t + u[:, 1] * np.maximum(hw[:, 0] - 2 * reach_t, 0.0)
        ty = (2 * u[:, 2] - 1) * np.maximum(hw[:, 1] - reach_t, 0.0)
        mx = -rm - u[:, 3] * np.maximum(hw[:, 0] - 2 * rm, 0.0)
        my = (2 * u[:, 4] - 1) * np.maximum(hw[:, 1] - rm, 0.0)
        n = len(env)
        pos = np.zeros((n, w.n_bodies, 2))
        pos[:, self.it] = np.stack([tx, ty], 1)
        pos[:, self.im] = np.stack([mx, my], 1)
        angles = np.zeros((n, w.n_bodies))
        angles[:, self.it] = angle
        # apart by construction: target in the right half, mallet in the left
        w._place(env, pos, angles, np.zeros_like(pos), np.zeros_like(angles))
        w.set_force("mallet", np.zeros((n, 2)), env=env)
        w.time[env] = 0.0
        return {}

    def step(self, actions, batch_info: bool = True):
        try:
            self._actions[...] = actions  # converts and broadcasts a (2,) action to (1, 2)
        except (ValueError, TypeError):
            raise ValueError(f"action: expected shape ({self.batch_size}, 2) or (2,), got "
                             f"{np.shape(actions)}") from None
        self.world._fcfg[CF_DT] = self.cfg.dt
        if not fast.control_step(self.world, self.tbuf, self.kcfg,
                                 self.batch_size >= PARALLEL_BATCH):
            raise ValueError(action_error(actions))
        t = self.tbuf
        reward = t[:, fast.T_REWARD].copy()
        if not batch_info:
            return reward, self._never, None
        info = {"hits": t[:, fast.T_HITS].astype(np.int64),
                "hit_impulse": t[:, fast.T_IMPULSE].copy(),
                "force": t[:, fast.T_FORCE:fast.T_FORCE + 2].copy(),
                "spin": t[:, fast.T_SPIN].copy(), "speed": t[:, fast.T_SPEED].copy(),
                "mallet_speed": t[:, fast.T_MALLET_SPEED].copy(),
                "reward_hit": t[:, fast.T_REWARD].copy(),
                "fallback": t[:, fast.T_FALLBACK] != 0}
        return reward, np.zeros(self.batch_size, dtype=bool), info

    def info_row(self, b: int, info=None) -> dict:
        """The step's info of element ``b`` as plain Python values (single env)."""
        r = self.tbuf[b].tolist()
        return {"hits": int(r[fast.T_HITS]), "hit_impulse": r[fast.T_IMPULSE],
                "force": self.tbuf[b, fast.T_FORCE:fast.T_FORCE + 2].copy(),
                "spin": r[fast.T_SPIN], "speed": r[fast.T_SPEED],
                "mallet_speed": r[fast.T_MALLET_SPEED], "reward_hit": r[fast.T_REWARD],
                "fallback": r[fast.T_FALLBACK] != 0}

    def observe(self) -> np.ndarray:
        """Observations as the fused step (or the last reset) left them, clipped already."""
        return self.tbuf[:, fast.T_OBS:fast.T_OBS + fast.OBS_SIZE]

    def snapshot(self) -> dict:
        return {}

    def restore(self, snap: dict) -> None:
        pass

    def frame(self, b: int, decorate: bool = True) -> Frame:
        w = self.world
        bodies = [BodyDraw(w.names[i], *w.state.positions[b, i], w.state.angles[b, i],
                           w.radius[b, i], w.half_length[b, i], w.state.omegas[b, i])
                  for i in range(w.n_bodies)]
        contacts = []
        c = self.world._collect() if decorate else None
        if c is not None and len(c):
            for i in np.flatnonzero(c.batch == b):
                contacts.append((*c.point[i], *c.normal[i], c.impulse[i]))
        hw = w.table_half_size[b]
        text = (f"spin {w.state.omegas[b, self.it]:+6.2f} rad/s   "
                f"speed {math.hypot(*w.state.velocities[b, self.it]):.2f} m/s")
        return Frame(bodies, (float(hw[0]), float(hw[1])), walls=True, contacts=contacts,
                     text=text)

    def view_half(self) -> tuple[float, float]:
        hw = self.world.table_half_size[0]
        return float(hw[0]) + 0.03, float(hw[1]) + 0.03


_COMMON_LAYOUT = (
    ObsField("mallet_x", -1.0, 1.0, "mallet x / table half width"),
    ObsField("mallet_y", -1.0, 1.0, "mallet y / table half height"),
    ObsField("mallet_vx", -5.0, 5.0, "mallet vx / max_speed"),
    ObsField("mallet_vy", -5.0, 5.0, "mallet vy / max_speed"),
)


def _target_layout(name: str) -> tuple[ObsField, ...]:
    """The target's seven observation fields (pose, velocity, spin), in ``fast._observe``'s
    order."""
    return (
        ObsField(f"{name}_x", -1.0, 1.0, f"{name} x / table half width"),
        ObsField(f"{name}_y", -1.0, 1.0, f"{name} y / table half height"),
        ObsField(f"{name}_cos", -1.0, 1.0, f"cos({name} angle)"),
        ObsField(f"{name}_sin", -1.0, 1.0, f"sin({name} angle)"),
        ObsField(f"{name}_vx", -10.0, 10.0, f"{name} vx / {SPEED_SCALE} m/s"),
        ObsField(f"{name}_vy", -10.0, 10.0, f"{name} vy / {SPEED_SCALE} m/s"),
        ObsField(f"{name}_spin", -10.0, 10.0, f"{name} spin / {SPIN_SCALE} rad/s (CCW > 0)"),
    )


class RodSpinControlTask(_ControlTask):
    TARGET = "rod"
    SCENE = "rod_control"
    SCALE = SPIN_SCALE
    MEASURE = fast.MEASURE_SPIN
    LAYOUT = _COMMON_LAYOUT + _target_layout("rod")



class PuckSpeedControlTask(_ControlTask):
    TARGET = "puck"
    SCENE = "puck_control"
    SCALE = SPEED_SCALE
    MEASURE = fast.MEASURE_SPEED
    LAYOUT = _COMMON_LAYOUT + _target_layout("puck")



_CONTROL_DOC = """{summary}

    ## Description
    A mallet (a driven disk, 0.3 kg) and a {target} share a 1.2 m x 0.8 m walled table with cloth
    friction. Each step the agent's action pushes the mallet with a constant force for ``dt``
    (0.02 s) seconds, simulated by the exact solver (contacts, cushions, cloth friction in closed
    form). The mallet has a speed limit (``max_speed``, 3 m/s): the force is reduced so that free
    flight never ends a step faster.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``: the force (x, y) as a fraction of ``max_force`` (8 N); the box
    is mapped onto the unit disk (a longer action keeps its direction at full force). NaN or
    infinite actions raise ``ValueError``; finite values outside [-1, 1] are clipped.

    ## Observation Space
    ``Box(float32)``, each entry clipped to its bounds:

{layout}

    ## Rewards
    {reward}, computed after the physics step, and only in steps in which the mallet touches
    the {target} (``info['hits']``): what its hits add (or take away). Cushions and cloth
    friction never earn reward.

    ## Starting State
    {target_cap} at rest at a random pose in the right half, mallet at rest in the left half.

    ## Episode End
    Never terminates; truncated after ``max_episode_steps`` (250 steps = 5 s, set at
    registration; the native vector env truncates by itself).

    ## Arguments
    See :class:`envs.config.ControlConfig`: ``dt``, ``max_force``, ``max_speed``,
    ``mallet_mass``, ``target_mass``, restitution, friction, effects, solver, randomisation
    ranges, obs_mode, and ``render_mode``; or one ``config`` dict.

    ## Info
    ``hits``, ``hit_impulse`` (N s), ``force`` (N, after the speed limit), ``spin``, ``speed``,
    ``mallet_speed``, ``reward_hit``, ``fallback`` (the solver settled a resting contact).

    ## Version History
    * v0: initial version.
    """


class _ControlEnv(SpinStrikeEnv):
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 50}


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


class PuckSpeedControlVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`PuckSpeedControlEnv` (one batched world)."""

    TASK = PuckSpeedControlTask
