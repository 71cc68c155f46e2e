"""Analytic oracle policies, and a scripted chase-and-hit policy for the control envs.

* :class:`RodSpinOracle` inverts the closed form of a struck rod,
  ``|w| = (1+e) v_n l / (I (1/m_s + 1/m_r) + l^2)`` (the seed's §1 law seen from the striker),
  into a family of strikes that each give the target spin in a single impact: side hits at
  several levers and approach angles, and the seed's own end-cap strikes at several theta. A
  spinning rod can come round and hit the striker again, which no closed form covers, so the
  oracle tries the whole family at once in a scratch batched world (one vectorised strike) and
  keeps the best. It is the upper line of the results tables.
* :class:`PuckSpeedOracle`: a centred strike along the target heading at the speed the closed
  form ``v_puck = (1+e) m_s / (m_s + m_p) v`` asks for (exact: one impact, no slip), in either
  action parametrisation (``PuckSpeed-v0``: heading angle and speed; ``-v1``: velocity vector).
* :class:`ChaseAndHit`: the control envs' scripted baseline: go round behind the target, then
  drive through it.

Every policy is called as ``policy(env, obs) -> action`` on a single (possibly wrapped) env.
"""

from __future__ import annotations

import math

import numpy as np

from spinstrike.envs.control import RodSpinControlTask
from spinstrike.envs.strike import PuckSpeedTask, PuckSpeedVelocityTask, RodSpinTask

__all__ = ["ChaseAndHit", "PuckSpeedOracle", "RandomPolicy", "RodSpinOracle", "oracle_for"]


class RandomPolicy:
    """Uniform random actions from a seeded generator."""

    def __init__(self, seed: int = 0) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, env, obs) -> np.ndarray:
        space = env.action_space
        return self.rng.uniform(space.low, space.high).astype(np.float32)


class RodSpinOracle:
    """Closed-form strikes for a target spin, the best of them picked by simulation.

    Args:
        approaches: approach angles tried, as fractions of ``approach_max``.
        levers: levers tried for side hits, as fractions of the half-length.
        thetas: the seed's end-cap angles tried, degrees.
    """

    def __init__(self, approaches=None, levers=None, thetas=(0, 15, 30, 45, 60)) -> None:
        self.approaches = (np.linspace(-0.9, 0.9, 13) if approaches is None
                           else np.asarray(approaches, float))
        self.levers = np.linspace(0.3, 0.98, 8) if levers is None else np.asarray(levers, float)
        self.thetas = np.radians(np.asarray(thetas, float))
        self._scratch = None

    def candidates(self, task: RodSpinTask, b: int = 0, target: float | None = None):
        """Actions that give ``target`` spin in one impact, by the closed form (``[K, 3]``)."""
        w = task.world
        cfg = task.cfg
        h, rho = w.half_length[b, task.it], w.radius[b, task.it]
        rs = w.radius[b, task.js]
        reach = h + rho + rs
        inertia = w.inertia[b, task.it]
        k = 1.0 / w.mass[b, task.it] + 1.0 / w.mass[b, task.js]
        e = w.restitution("rod", "striker")[b]
        target = task.goal[b, 0] if target is None else target
        if cfg.goal == "max":
            target = task.analytic()["spin_max"][b] * (1.0 if target >= 0 else -1.0)
        sign = -1.0 if target >= 0 else 1.0  # a hit from +n at a positive lever spins CW
        a_max = math.radians(cfg.approach_max)
        lo, hi = cfg.speed_range
        out = []
        # side hits: contact lever xi, approach alpha; normal speed v cos(alpha)
        for frac in self.approaches:
            alpha = frac * a_max
            for lf in self.levers:
                lever = lf * h
                v = abs(target) * (inertia * k + lever**2) / ((1 + e) * lever * math.cos(alpha))
                xi = sign * lever
                offset = (xi + (rho + rs) * math.tan(alpha)) * math.cos(alpha)
                out.append((offset / reach, frac, 2 * (v - lo) / (hi - lo) - 1))
        # the seed's strike: the line through the tip's cap centre at theta from the normal,
        # approaching from beyond the tip, so the normal lies along the velocity (a positive
        # offset with a negative approach spins CW, like a side hit at a positive lever)
        for theta in self.thetas:
            lever = h * math.cos(theta)
            v = abs(target) * (inertia * k + lever**2) / ((1 + e) * lever)
            out.append((sign * lever / reach, -sign * theta / a_max, 2 * (v - lo) / (hi - lo) - 1))
        acts = np.clip(np.array(out), -1, 1)
        ok = (np.abs(np.array(out)) <= 1).all(axis=1)  # reachable without clipping
        return acts[ok] if ok.any() else acts

    def __call__(self, env, obs) -> np.ndarray:
        task = env.unwrapped.task
        acts = self.candidates(task)
        # a what-if copy of this env's task: rebuilt for another env's config (one oracle used
        # on two envs planned the second's strikes with the first's speed range and scene)
        if (self._scratch is None or self._scratch.batch_size != len(acts)
                or self._scratch.cfg is not task.cfg):
            self._scratch = RodSpinTask(task.cfg, len(acts))
        scratch = self._scratch
        scratch.world.load_element(task.world, 0)
        scratch.goal[:] = task.goal[0]
        reward, _, info = scratch.step(acts)
        return acts[int(np.argmax(reward))].astype(np.float32)


class PuckSpeedOracle:
    """A centred strike along the target heading, at the closed form's speed."""

    def __call__(self, env, obs) -> np.ndarray:
        task: PuckSpeedTask = env.unwrapped.task
        target = task.goal[0]
        gain = task.analytic()["gain"][0]
        lo, hi = task.cfg.speed_range
        speed = float(np.clip(math.hypot(*target) / gain, lo, hi))
        heading = math.atan2(target[1], target[0])
        if isinstance(task, PuckSpeedVelocityTask):
            return np.clip(np.concatenate([[0.0], task.action_for(heading, speed, (lo, hi))]),
                           -1, 1).astype(np.float32)
        return np.clip(np.array([0.0, heading / math.pi, 2 * (speed - lo) / (hi - lo) - 1]),
                       -1, 1).astype(np.float32)


class ChaseAndHit:
    """Scripted control: reach a point behind the target, then drive through it.

    Rod: aim at 0.8 of the half-length from the centre, perpendicular to the rod (maximum
    lever), on the side facing the mallet. Puck: aim through its centre toward the table's centre.

    Args:
        gain: proportional gain of the approach (1/s); damping keeps it from overshooting.
        standoff: distance behind the contact point of the approach waypoint, m.
    """

    def __init__(self, gain: float = 12.0, standoff: float = 0.06) -> None:
        self.gain = gain
        self.standoff = standoff

    def __call__(self, env, obs) -> np.ndarray:
        task = env.unwrapped.task
        w = task.world
        pm = w.state.positions[0, task.im]
        vm = w.state.velocities[0, task.im]
        pt = w.state.positions[0, task.it]
        rm = w.radius[0, task.im]
        if isinstance(task, RodSpinControlTask):
            phi = w.state.angles[0, task.it]
            u = np.array([math.cos(phi), math.sin(phi)])
            n = np.array([-u[1], u[0]])
            if np.dot(pm - pt, n) < 0:
                n = -n
            aim = pt + 0.8 * w.half_length[0, task.it] * u
            drive = -n
            contact = aim + n * (w.radius[0, task.it] + rm)
        else:
            d = -pt / max(np.linalg.norm(pt), 1e-9)
            drive = d
            contact = pt - d * (w.radius[0, task.it] + rm)
        waypoint = contact - drive * self.standoff
        behind = np.dot(pm - contact, drive) < -0.5 * self.standoff
        if behind and np.linalg.norm(pm - waypoint) < 0.03:
            force = drive
        else:
            desired = self.gain * (waypoint - pm)
            force = (desired - vm) / max(task.cfg.max_speed, 1e-9)
            norm = np.linalg.norm(force)
            if norm > 1:
                force = force / norm
        return np.clip(force, -1, 1).astype(np.float32)


def oracle_for(env_id: str):
    """The reference policy of an env: the analytic oracle, or chase-and-hit for control."""
    return {"SpinStrike/RodSpin-v0": RodSpinOracle, "SpinStrike/PuckSpeed-v0": PuckSpeedOracle,
            "SpinStrike/PuckSpeed-v1": PuckSpeedOracle,
            "SpinStrike/RodSpinControl-v0": ChaseAndHit,
            "SpinStrike/PuckSpeedControl-v0": ChaseAndHit}[env_id]()

