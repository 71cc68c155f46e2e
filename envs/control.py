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

from envs.config import ControlConfig, build_scene
from envs.core import ObsField, SpinStrikeEnv, SpinStrikeVectorEnv, Task, layout_table
from envs.rendering import BodyDraw, Frame
from physics import World

__all__ = ["PuckSpeedControlEnv", "PuckSpeedControlVectorEnv", "RodSpinControlEnv",
           "RodSpinControlVectorEnv", "limit_force"]

#: spin (rad/s) and speed (m/s) that count as 1 in observations and rewards
SPIN_SCALE = 20.0
SPEED_SCALE = 3.0
#: distance (m) kept between the bodies and from the cushions when placing them at reset
CLEARANCE = 0.02


def limit_force(action, velocity, mass, dt, max_force, max_speed):
    """Force from actions in the unit disk, reduced so that free flight keeps the speed limit.

    The action's box [-1, 1]^2 is mapped onto the disk of radius ``max_force`` (an action outside
    the unit disk keeps its direction, at full force). If the mallet would end the step faster
    than ``max_speed`` in free flight, the force is the one that ends it at the limit (projected
    onto the speed ball; never more than ``max_force``).

    Args:
        action: [B, 2]; velocity: [B, 2] m/s; mass: [B] kg; dt: s.

    Returns:
        [B, 2] force, N.
    """
    a = np.asarray(action, dtype=np.float64)
    norm = np.sqrt((a**2).sum(1, keepdims=True))
    force = a * max_force / np.maximum(norm, 1.0)
    v_end = velocity + force * dt / mass[:, None]
    speed = np.sqrt((v_end**2).sum(1, keepdims=True))
    over = speed[:, 0] > max_speed
    if over.any():
        target = v_end[over] * (max_speed / speed[over])
        f = (target - velocity[over]) * mass[over, None] / dt
        fn = np.sqrt((f**2).sum(1, keepdims=True))
        force[over] = f * np.minimum(1.0, max_force / np.maximum(fn, 1e-300))
    return force


class _ControlTask(Task):
    """Mallet and target on a walled table, batched."""

    TARGET: ClassVar[str]
    SCENE: ClassVar[str]
    CONFIG = ControlConfig
    ACTIONS = ("force_x", "force_y")
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
        self._last_contacts = None

    def _apply_random(self, env, u) -> None:
        for k, key in enumerate(self.CONFIG.RANDOMIZABLE):
            if key not in self.cfg.randomize:
                continue
            lo, hi = self.cfg.randomize[key]
            x = u[:, k]
            value = np.exp(np.log(lo) + x * (np.log(hi) - np.log(lo))) if key.endswith("mass") \
                else lo + x * (hi - lo)
            if key == "mallet_mass":
                self.world.set_body("mallet", mass=value, env=env)
            elif key == "target_mass":
                self.world.set_body(self.TARGET, mass=value, env=env)
            elif key == "restitution":
                self.world.set_material(self.TARGET, "mallet", restitution=value, env=env)
            elif key == "table_friction":
                self.world.set_table(friction=value, env=env)

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
        w.set_state(positions=pos, angles=angles, velocities=np.zeros_like(pos),
                    omegas=np.zeros_like(angles), env=env)
        w.set_force("mallet", np.zeros((n, 2)), env=env)
        w.time[env] = 0.0
        return {}

    def step(self, actions):
        w = self.world
        cfg = self.cfg
        force = limit_force(actions, w.state.velocities[:, self.im], w.mass[:, self.im], cfg.dt,
                            cfg.max_force, cfg.max_speed)
        w.set_force("mallet", force)
        before = self._measure()
        contacts = w.step(cfg.dt)
        self._last_contacts = contacts
        after = self._measure()
        hit = np.zeros(self.batch_size, dtype=bool)
        hits = np.zeros(self.batch_size, dtype=np.int64)
        impulse = np.zeros(self.batch_size)
        if len(contacts):
            pair = ((contacts.body_a == self.im) & (contacts.body_b == self.it)) | (
                (contacts.body_a == self.it) & (contacts.body_b == self.im))
            np.add.at(hits, contacts.batch[pair], 1)
            np.add.at(impulse, contacts.batch[pair], contacts.impulse[pair])
            hit = hits > 0
        reward = np.where(hit, (after - before) / self.SCALE, 0.0)
        info = {"hits": hits, "hit_impulse": impulse, "force": force,
                "spin": w.state.omegas[:, self.it].copy(),
                "speed": np.sqrt((w.state.velocities[:, self.it] ** 2).sum(1)),
                "mallet_speed": np.sqrt((w.state.velocities[:, self.im] ** 2).sum(1)),
                "reward_hit": reward.copy(), "fallback": w.last_step.fallback.copy()}
        return reward, np.zeros(self.batch_size, dtype=bool), info

    def observe(self) -> np.ndarray:
        w = self.world
        hw = w.table_half_size
        p = w.state.positions
        v = w.state.velocities
        a = w.state.angles[:, self.it]
        return np.stack([
            p[:, self.im, 0] / hw[:, 0], p[:, self.im, 1] / hw[:, 1],
            v[:, self.im, 0] / self.cfg.max_speed, v[:, self.im, 1] / self.cfg.max_speed,
            p[:, self.it, 0] / hw[:, 0], p[:, self.it, 1] / hw[:, 1],
            np.cos(a), np.sin(a),
            v[:, self.it, 0] / SPEED_SCALE, v[:, self.it, 1] / SPEED_SCALE,
            w.state.omegas[:, self.it] / SPIN_SCALE,
        ], axis=1)

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
        c = self._last_contacts
        if decorate and c is not None and len(c):
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


class RodSpinControlTask(_ControlTask):
    TARGET = "rod"
    SCENE = "rod_control"
    SCALE = SPIN_SCALE
    LAYOUT = _COMMON_LAYOUT + (
        ObsField("rod_x", -1.0, 1.0, "rod x / table half width"),
        ObsField("rod_y", -1.0, 1.0, "rod y / table half height"),
        ObsField("rod_cos", -1.0, 1.0, "cos(rod angle)"),
        ObsField("rod_sin", -1.0, 1.0, "sin(rod angle)"),
        ObsField("rod_vx", -10.0, 10.0, f"rod vx / {SPEED_SCALE} m/s"),
        ObsField("rod_vy", -10.0, 10.0, f"rod vy / {SPEED_SCALE} m/s"),
        ObsField("rod_spin", -10.0, 10.0, f"rod spin / {SPIN_SCALE} rad/s (CCW > 0)"),
    )

    def _measure(self) -> np.ndarray:
        return np.abs(self.world.state.omegas[:, self.it])


class PuckSpeedControlTask(_ControlTask):
    TARGET = "puck"
    SCENE = "puck_control"
    SCALE = SPEED_SCALE
    LAYOUT = _COMMON_LAYOUT + (
        ObsField("puck_x", -1.0, 1.0, "puck x / table half width"),
        ObsField("puck_y", -1.0, 1.0, "puck y / table half height"),
        ObsField("puck_cos", -1.0, 1.0, "cos(puck angle) (turns only with contact friction)"),
        ObsField("puck_sin", -1.0, 1.0, "sin(puck angle)"),
        ObsField("puck_vx", -10.0, 10.0, f"puck vx / {SPEED_SCALE} m/s"),
        ObsField("puck_vy", -10.0, 10.0, f"puck vy / {SPEED_SCALE} m/s"),
        ObsField("puck_spin", -10.0, 10.0, f"puck spin / {SPIN_SCALE} rad/s"),
    )

    def _measure(self) -> np.ndarray:
        return np.sqrt((self.world.state.velocities[:, self.it] ** 2).sum(1))


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
