"""One-strike envs: ``SpinStrike/RodSpin-v0`` and ``SpinStrike/PuckSpeed-v0``.

Each episode is one strike: the action launches a striker disk at a resting target (a rod or a
puck), the exact solver simulates until no further contact can happen (or ``time_cap``), and the
reward is computed from the target's spin or velocity after the last contact.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import ClassVar

import numpy as np

from spinstrike.envs import fast
from spinstrike.envs.config import PuckSpeedConfig, RodSpinConfig, build_scene
from spinstrike.envs.core import SpinStrikeEnv, SpinStrikeVectorEnv, Task, check_actions
from spinstrike.envs.layout import ObsField, layout_table
from spinstrike.envs.rendering import BodyDraw, Frame
from spinstrike.physics import SceneError, World

__all__ = ["PuckSpeedEnv", "PuckSpeedVectorEnv", "RodSpinEnv", "RodSpinVectorEnv",
           "rod_spin_after_strike", "rod_spin_max"]

#: simulated time per chunk of a strike, s (also the animation's frame interval)
CHUNK = 1.0 / 30.0
#: margin between the striker's start and the target's reach, m
START_MARGIN = 0.02


def rod_spin_after_strike(lever, speed, e, inv_mass_sum, inertia):
    """Spin of a resting rod struck with impulse lever ``lever`` (|r x n|, m) by a disk whose
    normal approach speed is ``speed``: ``(1+e) v l / (I (1/m_s + 1/m_r) + l^2)`` (rad/s).

    The seed's §1 closed form is the case ``I = m_r r^2 / 3``, ``l = r cos(theta)`` (seen from the
    striker's frame: the rod moves into a resting point mass).
    """
    return (1.0 + e) * speed * lever / (inertia * inv_mass_sum + lever**2)


def rod_spin_max(half_length, speed, e, inv_mass_sum, inertia):
    """Most spin one strike at ``speed`` can give: the lever ``min(h, sqrt(I K))`` (rad/s).

    It is at the tip (theta = 0 in the seed's terms) only when ``sqrt(I K) >= h``; otherwise a
    lever inside the rod (theta > 0) gives more.
    """
    lever = np.minimum(half_length, np.sqrt(inertia * inv_mass_sum))
    return rod_spin_after_strike(lever, speed, e, inv_mass_sum, inertia), lever


class _StrikeTask(Task):
    """A striker launched at a resting target, batched."""

    TARGET: ClassVar[str]
    SCENE: ClassVar[str]
    ACTIONS = ("offset", "approach", "speed")
    render_fps = 30

    def __init__(self, cfg, batch_size: int, single: bool = False) -> None:
        super().__init__(cfg, batch_size, single)
        scene = build_scene(self.SCENE, cfg, self._body_overrides(cfg))
        self.world = World(self._park_striker(scene), batch_size)
        w = self.world
        if "walls" in w.effects or "table_friction" in w.effects:
            self._free = False
        else:
            self._free = True
        self.it = w.index(self.TARGET)
        self.js = w.index("striker")
        B = batch_size
        self.goal = np.zeros((B, self.GOAL_WIDTH))
        self.record_trace = False
        # the compiled strike's buffers (envs.fast): outcome per element, constants, and the
        # poses and contacts of element 0 for the animation
        n_chunks = max(1, math.ceil(cfg.time_cap / CHUNK - 1e-9))
        self._sbuf = np.zeros((B, fast.S_COLUMNS))
        sc = np.zeros(fast.SC_SIZE)
        sc[[fast.SC_CHUNK, fast.SC_CHUNKS, fast.SC_TARGET, fast.SC_STRIKER]] = (
            CHUNK, n_chunks, self.it, self.js)
        sc[fast.SC_FREE] = self._free
        self._scfg = sc
        self._trace_buf = np.zeros((n_chunks + 1, w.n_bodies, len(fast.TRACE_POSE)))
        self._ctrace_buf = np.zeros((fast.TRACE_CONTACTS, len(fast.TRACE_CONTACT)))
        self._tcount = np.zeros(len(fast.TRACE_COUNT), dtype=np.int64)
        self._trace: list[tuple[np.ndarray, np.ndarray]] = []
        self._last: dict[str, np.ndarray] = {}
        self._contacts_b0: list[tuple[float, float, float, float, float]] = []
        self._zero_result()

    GOAL_WIDTH: ClassVar[int] = 1

    def _park_striker(self, scene):
        """The scene's striker position is only a parking place (every reset and strike places
        the striker): move it clear of the target's reach, which a large ``rod_length`` or
        ``rod_thickness`` can make overlap the scene's own placement."""
        bodies = list(scene.bodies)
        names = [b.name for b in bodies]
        target = bodies[names.index(self.TARGET)]
        k = names.index("striker")
        striker = bodies[k]
        clear = target.half_length + target.core_radius + striker.core_radius + START_MARGIN
        dx = striker.position[0] - target.position[0]
        dy = striker.position[1] - target.position[1]
        if math.hypot(dx, dy) >= clear:
            return scene
        bodies[k] = striker.model_copy(
            update={"position": (target.position[0], target.position[1] + clear)})
        return scene.model_copy(update={"bodies": tuple(bodies)})

    def _body_overrides(self, cfg) -> dict:
        return {"striker": {"mass": cfg.striker_mass}, self.TARGET: {"mass": cfg.target_mass}}

    def _zero_result(self) -> None:
        B = self.batch_size
        self.result_v = np.zeros((B, 2))
        self.result_w = np.zeros(B)
        self.result_vs = np.zeros((B, 2))

    # -- randomisation ------------------------------------------------------------------------
    def _set_random(self, edit, key, value) -> None:
        if key == "striker_mass":
            edit.set_body("striker", mass=value)
        elif key == "target_mass":
            edit.set_body(self.TARGET, mass=value)
        elif key == "rod_length":
            edit.set_body("rod", length=value)
        elif key == "restitution":
            edit.set_material(self.TARGET, "striker", restitution=value)
        elif key == "friction":
            edit.set_material(self.TARGET, "striker", friction=value)

    def _reach(self) -> np.ndarray:
        """[B] largest distance of the target's surface from its centre, m."""
        w = self.world
        return w.half_length[:, self.it] + w.radius[:, self.it]

    def reset(self, env: np.ndarray, uniforms: np.ndarray) -> dict[str, np.ndarray]:
        n_rand = len(self.CONFIG.RANDOMIZABLE)
        u = uniforms[:, n_rand:]
        w = self.world
        with w.edit(env) as e:
            self._apply_random(e, uniforms[:, :n_rand])
            angle = 2 * math.pi * u[:, 0] - math.pi
            centre = 0.1 * (2 * u[:, 1:3] - 1)
            # park the striker where a straight, centred strike would start: beyond the
            # target's reach, so nothing overlaps
            reach = e.half_length[:, self.it] + e.radius[:, self.it]
            dist = reach + e.radius[:, self.js] + START_MARGIN
            normal = np.stack([-np.sin(angle), np.cos(angle)], axis=1)
            pos = np.zeros((len(env), w.n_bodies, 2))
            pos[:, self.it] = centre
            pos[:, self.js] = centre + dist[:, None] * normal
            angles = np.zeros((len(env), w.n_bodies))
            angles[:, self.it] = angle
            e.set_state(positions=pos, angles=angles, velocities=0.0, omegas=0.0)
        self._sample_goal(env, u[:, 3:])
        self._zero_result_rows(env)
        if self.record_trace:
            self._trace = []
            self._contacts_b0 = []
        return self._reset_info(env)

    def _zero_result_rows(self, env) -> None:
        self.result_v[env] = 0.0
        self.result_w[env] = 0.0
        self.result_vs[env] = 0.0

    # -- the strike ---------------------------------------------------------------------------
    @abstractmethod
    def _launch(self, actions: np.ndarray) -> None:
        """Put the striker on its line, moving (subclasses: geometry of the action)."""

    def _put_striker(self, start: np.ndarray, velocity: np.ndarray) -> None:
        """Launch every element's striker from ``start`` [B, 2] at ``velocity`` [B, 2] (the
        compiled strike places it, every other body at rest, and refuses an overlap)."""
        sb = self._sbuf
        sb[:, fast.S_LAUNCH_X:fast.S_LAUNCH_Y + 1] = start
        sb[:, fast.S_LAUNCH_VX:fast.S_LAUNCH_VY + 1] = velocity

    def _speed(self, a: np.ndarray) -> np.ndarray:
        lo, hi = self.cfg.speed_range
        return lo + 0.5 * (a + 1.0) * (hi - lo)

    def _simulate(self) -> dict[str, np.ndarray]:
        """Run every element's strike to its end (``envs.fast.STRIKE``: compiled, each element
        only as long as it needs; pymunk: chunk by chunk from Python, booked by the same code)."""
        sc = self._scfg
        sc[fast.SC_RECORD] = self.record_trace
        sb = self._sbuf
        self._tcount[:] = 0
        w = self.world
        w.run(fast.STRIKE, sb, sc, self._trace_buf, self._ctrace_buf, self._tcount)
        refused = np.flatnonzero(sb[:, fast.S_OVERLAP_PAIR] != -1)
        if len(refused):
            b = refused[0]
            p = int(sb[b, fast.S_OVERLAP_PAIR])
            if p < 0:
                raise SceneError(f"strike: the striker's launch in element {b} is not finite")
            raise SceneError(
                f"strike: launching the striker in element {b} would make "
                f"{w.names[w.pair_a[p]]!r} and {w.names[w.pair_b[p]]!r} overlap by "
                f"{-sb[b, fast.S_OVERLAP_GAP]:.3g} m")
        self.result_v[:] = sb[:, fast.S_TARGET_VX:fast.S_TARGET_VY + 1]
        self.result_w[:] = sb[:, fast.S_TARGET_W]
        self.result_vs[:] = sb[:, fast.S_STRIKER_VX:fast.S_STRIKER_VY + 1]
        if self.record_trace:
            n = int(self._tcount[fast.TN_POSES])
            poses = self._trace_buf[:n]
            self._trace = [(t[:, fast.TP_X:fast.TP_Y + 1].copy(), t[:, fast.TP_ANGLE].copy())
                           for t in poses]
            m = int(self._tcount[fast.TN_CONTACTS])
            self._contacts_b0 = [tuple(r) for r in self._ctrace_buf[:m]]
        contacts = sb[:, fast.S_CONTACTS].astype(np.int64)
        return {"n_contacts": contacts, "impulse": sb[:, fast.S_IMPULSE].copy(),
                "first_contact_time": sb[:, fast.S_FIRST_TIME].copy(),
                "first_impulse": sb[:, fast.S_FIRST_J].copy(),
                "first_contact_point": sb[:, fast.S_FIRST_PX:fast.S_FIRST_PY + 1].copy(),
                "fallback": sb[:, fast.S_FALLBACK] != 0,
                "sim_time": sb[:, fast.S_SIM_TIME].copy(), "second_contact": contacts >= 2}

    def step(self, actions, batch_info: bool = True):
        a = check_actions(actions, self.action_shape)
        self._launch(a.reshape(self.batch_size, len(self.ACTIONS)))
        sim = self._simulate()
        reward, terms = self._reward()
        info = {**sim, **terms, **self._result_info()}
        self._last = info
        return reward, np.ones(self.batch_size, dtype=bool), info

    # -- snapshots ----------------------------------------------------------------------------
    def snapshot(self) -> dict:
        return {"goal": self.goal.copy(), "result_v": self.result_v.copy(),
                "result_w": self.result_w.copy(), "result_vs": self.result_vs.copy()}

    def restore(self, snap: dict) -> None:
        self.goal[:] = snap["goal"]
        self.result_v[:] = snap["result_v"]
        self.result_w[:] = snap["result_w"]
        self.result_vs[:] = snap["result_vs"]

    # -- rendering ----------------------------------------------------------------------------
    def _draw_bodies(self, b: int, pos=None, ang=None, omegas=None) -> list[BodyDraw]:
        w = self.world
        pos = w.state.positions[b] if pos is None else pos
        ang = w.state.angles[b] if ang is None else ang
        om = w.state.omegas[b] if omegas is None else omegas
        return [BodyDraw(w.names[i], *pos[i], ang[i], w.radius[b, i], w.half_length[b, i], om[i])
                for i in range(w.n_bodies)]

    def frame(self, b: int, decorate: bool = True) -> Frame:
        ghosts = []
        contacts: list = []
        if decorate and b == 0 and self._trace:
            step = max(1, len(self._trace) // 8)
            ghosts = [self._draw_bodies(0, p, a, np.zeros(len(a))) for p, a in self._trace[::step]]
            contacts = self._contacts_b0
        return Frame(self._draw_bodies(b), tuple(self.world.table_half_size[b]),
                     walls="walls" in self.world.effects, contacts=contacts, ghosts=ghosts,
                     text=self._caption(b))

    def strike_frames(self, b: int = 0) -> list[Frame]:
        """The last strike of element 0, one frame per ``CHUNK`` (for animated recordings)."""
        return [Frame(self._draw_bodies(0, p, a), tuple(self.world.table_half_size[0]),
                      walls="walls" in self.world.effects, text=self._caption(0))
                for p, a in self._trace]

    def view_half(self) -> tuple[float, float]:
        hw = self.world.table_half_size[0]
        if np.all(np.isfinite(hw)):
            return float(hw[0]) + 0.05, float(hw[1]) + 0.05
        r = float(self._reach()[0] + self.world.radius[0, self.js]) + START_MARGIN
        return 2.2 * r * 1.5, 2.2 * r


class RodSpinTask(_StrikeTask):
    TARGET = "rod"
    SCENE = "rod_spin"
    CONFIG = RodSpinConfig
    LAYOUT = (
        ObsField("target_spin", -1.0, 1.0,
                 "target spin / max of `target_spin` (CCW > 0); 0 when goal='max'"),
        ObsField("log_mass_ratio", -6.0, 6.0, "log10(striker mass / rod mass)"),
        ObsField("restitution", 0.0, 1.0, "e of the rod-striker pair"),
        ObsField("half_length", 0.0, 5.0, "the rod's half length, m"),
    )
    GOAL = slice(0, 1)
    ACHIEVED = (ObsField("spin", -5.0, 5.0, "rod spin after the strike / max target spin"),)
    UNIFORMS = len(RodSpinConfig.RANDOMIZABLE) + 4

    def _body_overrides(self, cfg) -> dict:
        out = super()._body_overrides(cfg)
        out["rod"].update(length=cfg.rod_length, thickness=cfg.rod_thickness)
        if cfg.rod_inertia != "capsule":
            out["rod"]["inertia"] = cfg.rod_inertia
        return out

    def _sample_goal(self, env, u) -> None:
        lo, hi = self.cfg.target_spin
        if self.cfg.goal == "target":
            sign = np.where(u[:, 0] < 0.5, -1.0, 1.0)
            self.goal[env, 0] = sign * (lo + (2 * np.abs(u[:, 0] - 0.5)) * (hi - lo))
        else:
            self.goal[env, 0] = 0.0

    def _reset_info(self, env) -> dict[str, np.ndarray]:
        return {"target_spin": self.goal[env, 0].copy()}

    def _launch(self, actions: np.ndarray) -> None:
        w = self.world
        reach = self._reach()
        rs = w.radius[:, self.js]
        offset = actions[:, 0] * (reach + rs)
        alpha = actions[:, 1] * math.radians(self.cfg.approach_max)
        speed = self._speed(actions[:, 2])
        phi = w.state.angles[:, self.it]
        u = np.stack([np.cos(phi), np.sin(phi)], 1)
        n = np.stack([-np.sin(phi), np.cos(phi)], 1)
        # in the rod's frame (xi along the rod, eta along its normal) the striker moves along
        # (sin a, -cos a) on the line whose point closest to the rod's centre is b (cos a, sin a)
        d = np.sin(alpha)[:, None] * u - np.cos(alpha)[:, None] * n
        c = (offset * np.cos(alpha))[:, None] * u + (offset * np.sin(alpha))[:, None] * n
        start = w.state.positions[:, self.it] + c - (reach + rs + START_MARGIN)[:, None] * d
        self._put_striker(start, speed[:, None] * d)

    def analytic(self) -> dict[str, np.ndarray]:
        """Closed-form optimum per element: the largest spin and the lever that gives it."""
        w = self.world
        k = 1.0 / w.mass[:, self.it] + 1.0 / w.mass[:, self.js]
        e = w.restitution("rod", "striker")
        spin_max, lever = rod_spin_max(w.half_length[:, self.it], self.cfg.speed_range[1], e, k,
                                       w.inertia[:, self.it])
        return {"spin_max": spin_max, "lever": lever, "inv_mass_sum": k, "restitution": e}

    def _reward(self):
        spin = self.result_w
        a = self.analytic()
        if self.cfg.goal == "target":
            target = self.goal[:, 0]
            width = self.cfg.reward_width * np.abs(target)
            reward = np.exp(-0.5 * ((spin - target) / width) ** 2)
            reachable = np.minimum(np.abs(target), a["spin_max"])
            best = np.exp(-0.5 * ((reachable - np.abs(target)) / width) ** 2)
        else:
            reward = np.abs(spin) / a["spin_max"]
            best = np.ones(self.batch_size)
        return reward, {"reward_spin": reward.copy(), "best_reward": best,
                        "analytic_max_spin": a["spin_max"], "analytic_best_lever": a["lever"]}

    def _result_info(self) -> dict[str, np.ndarray]:
        return {"spin": self.result_w.copy(), "target_spin": self.goal[:, 0].copy(),
                "rod_velocity": self.result_v.copy(),
                "speed": np.sqrt((self.result_v**2).sum(1)),
                "striker_speed": np.sqrt((self.result_vs**2).sum(1))}

    def observe(self) -> np.ndarray:
        w = self.world
        return self.by_layout(
            target_spin=self.goal[:, 0] / self.cfg.target_spin[1],
            log_mass_ratio=np.log10(w.mass[:, self.js] / w.mass[:, self.it]),
            restitution=w.restitution("rod", "striker"),
            half_length=w.half_length[:, self.it])

    def achieved(self) -> np.ndarray:
        return (self.result_w / self.cfg.target_spin[1])[:, None]

    @staticmethod
    def goal_reward(achieved, desired, cfg) -> np.ndarray:
        a = achieved[..., 0]
        d = desired[..., 0]
        width = np.maximum(cfg.reward_width * np.abs(d), 1e-12)
        return np.exp(-0.5 * ((a - d) / width) ** 2)

    def _caption(self, b: int) -> str:
        return (f"spin {self.world.state.omegas[b, self.it]:+.2f} rad/s   "
                f"target {self.goal[b, 0]:+.2f}")


class PuckSpeedTask(_StrikeTask):
    TARGET = "puck"
    SCENE = "puck_speed"
    CONFIG = PuckSpeedConfig
    LAYOUT = (
        ObsField("target_vx", -1.0, 1.0, "target velocity x / max of `target_speed`"),
        ObsField("target_vy", -1.0, 1.0, "target velocity y / max of `target_speed`"),
        ObsField("log_mass_ratio", -6.0, 6.0, "log10(striker mass / puck mass)"),
        ObsField("restitution", 0.0, 1.0, "e of the puck-striker pair"),
        ObsField("friction", 0.0, 5.0, "contact friction mu of the puck-striker pair"),
    )
    GOAL = slice(0, 2)
    ACHIEVED = (ObsField("vx", -5.0, 5.0, "puck velocity x / max target speed"),
                ObsField("vy", -5.0, 5.0, "puck velocity y / max target speed"))
    UNIFORMS = len(PuckSpeedConfig.RANDOMIZABLE) + 5
    GOAL_WIDTH = 2

    def _sample_goal(self, env, u) -> None:
        lo, hi = self.cfg.target_speed
        speed = lo + u[:, 0] * (hi - lo)
        heading = 2 * math.pi * u[:, 1] - math.pi
        self.goal[env, 0] = speed * np.cos(heading)
        self.goal[env, 1] = speed * np.sin(heading)

    def _reset_info(self, env) -> dict[str, np.ndarray]:
        return {"target_velocity": self.goal[env].copy()}

    def _launch(self, actions: np.ndarray) -> None:
        w = self.world
        reach = self._reach() + w.radius[:, self.js]
        offset = actions[:, 0] * reach
        heading = actions[:, 1] * math.pi
        speed = self._speed(actions[:, 2])
        d = np.stack([np.cos(heading), np.sin(heading)], 1)
        side = np.stack([-np.sin(heading), np.cos(heading)], 1)
        start = (w.state.positions[:, self.it] + offset[:, None] * side
                 - (reach + START_MARGIN)[:, None] * d)
        self._put_striker(start, speed[:, None] * d)

    def analytic(self) -> dict[str, np.ndarray]:
        """Closed form of a centred, frictionless strike: puck speed per unit striker speed."""
        w = self.world
        ms, mp = w.mass[:, self.js], w.mass[:, self.it]
        e = w.restitution("puck", "striker")
        gain = (1 + e) * ms / (ms + mp)
        return {"gain": gain, "speed_max": gain * self.cfg.speed_range[1],
                "speed_min": gain * self.cfg.speed_range[0]}

    def _reward(self):
        target = self.goal
        err = np.sqrt(((self.result_v - target) ** 2).sum(1))
        width = self.cfg.reward_width * np.sqrt((target**2).sum(1))
        reward = np.exp(-0.5 * (err / width) ** 2)
        a = self.analytic()
        t_speed = np.sqrt((target**2).sum(1))
        reach = np.clip(t_speed, a["speed_min"], a["speed_max"])
        best = np.exp(-0.5 * ((reach - t_speed) / width) ** 2)
        return reward, {"reward_velocity": reward.copy(), "best_reward": best,
                        "analytic_speed_gain": a["gain"]}

    def _result_info(self) -> dict[str, np.ndarray]:
        return {"velocity": self.result_v.copy(), "speed": np.sqrt((self.result_v**2).sum(1)),
                "spin": self.result_w.copy(), "target_velocity": self.goal.copy(),
                "striker_speed": np.sqrt((self.result_vs**2).sum(1))}

    def observe(self) -> np.ndarray:
        w = self.world
        hi = self.cfg.target_speed[1]
        return self.by_layout(
            target_vx=self.goal[:, 0] / hi, target_vy=self.goal[:, 1] / hi,
            log_mass_ratio=np.log10(w.mass[:, self.js] / w.mass[:, self.it]),
            restitution=w.restitution("puck", "striker"),
            friction=w.friction("puck", "striker"))

    def achieved(self) -> np.ndarray:
        return self.result_v / self.cfg.target_speed[1]

    @staticmethod
    def goal_reward(achieved, desired, cfg) -> np.ndarray:
        err = np.sqrt(((achieved - desired) ** 2).sum(-1))
        width = np.maximum(cfg.reward_width * np.sqrt((desired**2).sum(-1)), 1e-12)
        return np.exp(-0.5 * (err / width) ** 2)

    def _caption(self, b: int) -> str:
        v = self.world.state.velocities[b, self.it]
        return (f"puck ({v[0]:+.2f}, {v[1]:+.2f}) m/s   "
                f"target ({self.goal[b, 0]:+.2f}, {self.goal[b, 1]:+.2f})")


class _StrikeEnvMixin:
    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 30}

    def _after_init(self) -> None:
        self.task.record_trace = self.render_mode is not None


class RodSpinEnv(_StrikeEnvMixin, SpinStrikeEnv):
    """Strike a free rod once and give it a target spin.

    ## Description
    A rod (a capsule, 0.4 m by default) rests on an unbounded frictionless table at a random
    pose. The agent launches a striker disk at it; the exact solver resolves the impact (and any
    later contact: a spinning rod can come round and hit the striker again) with the seed note's
    impulse law, until no further contact can happen or ``time_cap`` seconds. The reward depends
    on the rod's spin after the last contact.

    ## Action Space
    ``Box(-1, 1, (3,), float32)``, in the rod's frame (so the rod's random pose does not matter):

    * ``offset``: signed distance of the striker's line from the rod's centre, as a fraction of
      ``half_length + thickness/2 + striker radius`` (beyond 1 it misses);
    * ``approach``: angle of the striker's velocity from the rod's normal, as a fraction of
      ``approach_max`` (75 deg);
    * ``speed``: strike speed, mapped linearly onto ``speed_range`` (0.5..4 m/s).

    NaN or infinite actions raise ``ValueError``; finite values outside [-1, 1] are clipped.

    ## Observation Space
    ``Box(float32)`` with the layout below (``obs_mode='dict'``: goal-conditioned with
    ``achieved_goal`` = spin after the strike; ``'pixels'``: the rendered frame).

{layout}

    ## Rewards
    ``goal='target'`` (default): a target spin w* is drawn per episode (sign and magnitude in
    ``target_spin``) and ``reward = exp(-((w - w*) / (reward_width |w*|))^2 / 2)``: 1 at the
    target, 0.61 one width away; a miss scores ``exp(-1/(2 reward_width^2))``, what the formula
    gives for zero spin. ``goal='max'``: ``reward = |w| / w_max`` with ``w_max`` the analytic
    largest spin over all strikes (lever ``min(h, sqrt(I (1/m_s + 1/m_r)))``, not always at the
    tip). ``info['best_reward']`` is the best reward the closed forms allow.

    ## Starting State
    Rod at rest, angle uniform, centre within 0.1 m of the origin; striker parked beside it.

    ## Episode End
    Terminates after the one strike.

    ## Arguments
    See :class:`spinstrike.envs.config.RodSpinConfig` (masses, rod size and inertia,
    restitution, effects, solver, randomisation ranges, goal, obs_mode) and ``render_mode``; or
    one ``config`` dict.

    ## Info
    ``spin`` (rad/s), ``speed``/``rod_velocity`` (m/s), ``striker_speed``, ``n_contacts``,
    ``second_contact``, ``impulse`` (total, N s), ``first_impulse``, ``first_contact_point``,
    ``first_contact_time`` (s), ``sim_time``, ``analytic_max_spin``, ``analytic_best_lever``,
    ``best_reward``, ``reward_spin``, ``fallback`` (the solver settled a resting contact).

    ## Version History
    * v0: initial version.
    """

    TASK = RodSpinTask

    def __init__(self, render_mode=None, config=None, **kwargs):
        super().__init__(render_mode=render_mode, config=config, **kwargs)
        self._after_init()


class PuckSpeedEnv(_StrikeEnvMixin, SpinStrikeEnv):
    """Strike a puck once and send it off at a target velocity.

    ## Description
    A puck rests on an unbounded table; the agent launches a striker disk at it. Reward from the
    puck's velocity after the strike against a target speed and heading drawn per episode. With
    ``contact_friction`` on (``friction > 0``) an off-centre strike also spins the puck
    (``info['spin']``).

    ## Action Space
    ``Box(-1, 1, (3,), float32)``: ``offset`` of the striker's line from the puck's centre (as a
    fraction of the sum of radii), ``heading`` of the strike (fraction of pi, CCW from +x),
    ``speed`` (mapped onto ``speed_range``). NaN raises; out-of-range values are clipped.

    ## Observation Space

{layout}

    ## Rewards
    ``reward = exp(-|v - v*|^2 / (2 (reward_width |v*|)^2))``.

    ## Starting State
    Puck at rest near the origin; striker parked beside it.

    ## Episode End
    Terminates after the one strike.

    ## Arguments
    See :class:`spinstrike.envs.config.PuckSpeedConfig`.

    ## Info
    ``velocity``, ``speed``, ``spin``, ``target_velocity``, ``n_contacts``, ``impulse``,
    ``first_contact_point``, ``best_reward``, ``analytic_speed_gain``, ``reward_velocity``.

    ## Version History
    * v0: initial version.
    """

    TASK = PuckSpeedTask

    def __init__(self, render_mode=None, config=None, **kwargs):
        super().__init__(render_mode=render_mode, config=config, **kwargs)
        self._after_init()


class RodSpinVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`RodSpinEnv` (one batched world)."""

    TASK = RodSpinTask
    metadata = dict(SpinStrikeVectorEnv.metadata, render_fps=30)


class PuckSpeedVectorEnv(SpinStrikeVectorEnv):
    """Native vector version of :class:`PuckSpeedEnv` (one batched world)."""

    TASK = PuckSpeedTask
    metadata = dict(SpinStrikeVectorEnv.metadata, render_fps=30)


RodSpinEnv.__doc__ = RodSpinEnv.__doc__.format(layout=layout_table(RodSpinTask.LAYOUT))
PuckSpeedEnv.__doc__ = PuckSpeedEnv.__doc__.format(layout=layout_table(PuckSpeedTask.LAYOUT))
