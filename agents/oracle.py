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
        self.seed = seed
        self.rng = np.random.default_rng(seed)

    def for_episode(self, k: int) -> RandomPolicy:
        """The policy of the k-th of several episodes filmed (``record``): seeded ``seed + k``,
        as the episodes' envs are, so an episode's actions do not depend on the episodes
        before it or beside it (a grid)."""
        return RandomPolicy(self.seed + k)

    def __call__(self, env, obs) -> np.ndarray:
        space = env.action_space
        return self.rng.uniform(space.low, space.high).astype(np.float32)


def _strike_from(task, scratch, actions: np.ndarray):
    """What-if strikes: ``actions`` (one per element of ``scratch``, a task of the same config)
    struck from element 0 of ``task`` (its state and goal); ``scratch.step``'s result."""
    scratch.world.load_element(task.world, 0)
    scratch.goal[:] = task.goal[0]
    return scratch.step(actions)


#: a strike's reward the rod oracle looks no further from (1 up to the closed form's round-off)
PAID_IN_FULL = 1.0 - 1e-6


class RodSpinOracle:
    """Closed-form strikes for a target spin, the best of them picked by simulation, then
    refined by a local search where it falls short of reward 1.

    Args:
        approaches: approach angles tried, as fractions of ``approach_max``.
        levers: levers tried for side hits, as fractions of the half-length (the best lever,
            ``min(h, sqrt(I K))``, is always tried too).
        thetas: the seed's end-cap angles tried, degrees.
        refine: spreads (in action units) of the local search's rounds around the best strike
            so far, each of ``samples`` strikes from a generator seeded the same at every call;
            it runs where the best strike pays less than 1 (``goal='max'``, where the most spin
            one impact gives is struck square on and the rod comes round and hits the striker
            again; a target beyond what one impact gives) and keeps the best strike met.
        samples: strikes simulated at once (one batched what-if world).
    """

    def __init__(self, approaches=None, levers=None, thetas=(0, 15, 30, 45, 60),
                 refine=(0.1, 0.03, 0.01, 0.003), samples: int = 256) -> None:
        self.approaches = (np.linspace(-0.9, 0.9, 13) if approaches is None
                           else np.asarray(approaches, float))
        self.levers = np.linspace(0.3, 0.98, 8) if levers is None else np.asarray(levers, float)
        self.thetas = np.radians(np.asarray(thetas, float))
        self.refine = tuple(float(x) for x in refine)
        self.samples = int(samples)
        self._scratch = None

    def candidates(self, task: RodSpinTask, b: int = 0, target: float | None = None):
        """Actions that give ``target`` spin in one impact by the closed form (``[K, 3]``),
        and how many of them, first, need no clipping; the rest are clipped into the action
        box (they need more than its top speed)."""
        w = task.world
        cfg = task.cfg
        h, rho = w.half_length[b, task.it], w.radius[b, task.it]
        rs = w.radius[b, task.js]
        reach = h + rho + rs
        inertia = w.inertia[b, task.it]
        k = 1.0 / w.mass[b, task.it] + 1.0 / w.mass[b, task.js]
        e = w.restitution("rod", "striker")[b]
        target = task.goal[b, 0] if target is None else target
        best = task.analytic()
        spin_max = best["spin_max"][b]
        if cfg.goal == "max" or abs(target) > spin_max:
            # the most spin one impact gives (a target beyond it: the nearest spin reachable)
            target = spin_max * (1.0 if target >= 0 else -1.0)
        sign = -1.0 if target >= 0 else 1.0  # a hit from +n at a positive lever spins CW
        a_max = math.radians(cfg.approach_max)
        lo, hi = cfg.speed_range
        out = []
        # side hits: contact lever xi, approach alpha; normal speed v cos(alpha); the levers
        # tried and the best one, min(h, sqrt(I K)), where spin_max needs the top speed
        levers = np.append(self.levers, best["lever"][b] / h)
        for frac in self.approaches:
            alpha = frac * a_max
            for lf in levers:
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
        # every one, clipped into the box (those that need no clipping first): those a target
        # beyond them clips are tried too (a spinning rod can come round and hit the striker
        # again, which the closed form does not see: spin_max's own strike, square on, gets
        # all its spin taken back that way)
        out = np.array(out)
        inside = (np.abs(out) <= 1.0).all(axis=1)
        return np.clip(np.concatenate([out[inside], out[~inside]]), -1, 1), int(inside.sum())

    def _rewards(self, task: RodSpinTask, acts: np.ndarray) -> np.ndarray:
        """The reward of each strike of ``acts`` from element 0's state, simulated in chunks
        of ``samples`` in a what-if copy of the env's task (rebuilt for another env's config:
        one oracle used on two envs planned the second's strikes with the first's speed range
        and scene)."""
        if self._scratch is None or self._scratch[0] is not task.cfg:
            self._scratch = (task.cfg, {})
        scratches = self._scratch[1]
        out = np.empty(len(acts))
        for i in range(0, len(acts), self.samples):
            chunk = acts[i:i + self.samples]
            scratch = scratches.get(len(chunk))
            if scratch is None:
                scratch = scratches[len(chunk)] = type(task)(task.cfg, len(chunk))
            out[i:i + len(chunk)] = _strike_from(task, scratch, chunk)[0]
        return out

    def __call__(self, env, obs) -> np.ndarray:
        task = env.unwrapped.task
        acts, inside = self.candidates(task)
        # the strikes the closed form reaches first: one of them nearly always pays 1
        reward = self._rewards(task, acts[:inside]) if inside else np.zeros(0)
        if not inside or reward.max() < PAID_IN_FULL:
            reward = np.concatenate([reward, self._rewards(task, acts[inside:])])
        k = int(np.argmax(reward))
        best, best_reward = acts[k], reward[k]
        rng = np.random.default_rng(0)  # the same search at every call: a deterministic policy
        for spread in self.refine:
            if best_reward >= PAID_IN_FULL:
                break
            trial = np.clip(best + spread * rng.standard_normal((self.samples, 3)), -1, 1)
            reward = self._rewards(task, trial)
            k = int(np.argmax(reward))
            if reward[k] > best_reward:
                best, best_reward = trial[k], reward[k]
        return best.astype(np.float32)


class PuckSpeedOracle:
    """A strike along the target heading at the closed form's speed; a target slower than the
    slowest centred strike sends the puck, an off-centre strike at the slowest speed.

    Centred (frictionless or not: no slip): ``v_puck = (1+e) m_s / (m_s + m_p) v``. Off centre
    by ``sin(theta)`` of the sum of radii, a frictionless strike sends the puck along the line
    of centres, ``theta`` from the strike, at ``cos(theta)`` of that speed; with contact
    friction the tangential impulse turns and slows it a little, which a few what-if strikes
    from the env's own state correct (``corrections``).
    """

    def __init__(self, corrections: int = 6) -> None:
        self.corrections = int(corrections)
        self._scratch = None

    @staticmethod
    def _action(task, offset: float, heading: float, speed: float) -> np.ndarray:
        lo, hi = task.cfg.speed_range
        heading = math.remainder(heading, 2 * math.pi)
        if isinstance(task, PuckSpeedVelocityTask):
            rest = task.action_for(heading, speed, (lo, hi))
        else:
            rest = [heading / math.pi, 2 * (speed - lo) / (hi - lo) - 1]
        return np.clip(np.concatenate([[offset], rest]), -1, 1).astype(np.float32)

    def __call__(self, env, obs) -> np.ndarray:
        task: PuckSpeedTask = env.unwrapped.task
        target = task.goal[0]
        t_speed = math.hypot(*target)
        t_heading = math.atan2(target[1], target[0])
        gain = task.analytic()["gain"][0]
        lo, hi = task.cfg.speed_range
        if t_speed >= gain * lo:  # centred
            return self._action(task, 0.0, t_heading, min(t_speed / gain, hi))
        # off centre at the slowest speed: cos(theta) = t_speed / (gain lo); a positive offset
        # sends the puck theta clockwise of the strike
        theta = math.acos(t_speed / (gain * lo))
        heading = t_heading + theta
        act = self._action(task, math.sin(theta), heading, lo)
        if task.world.friction("puck", "striker")[0] == 0.0:
            return act
        if self._scratch is None or self._scratch.cfg is not task.cfg:
            self._scratch = type(task)(task.cfg, 1)
        scratch = self._scratch
        for _ in range(self.corrections):
            reward, _, info = _strike_from(task, scratch, act[None])
            v = info["velocity"][0]
            speed = math.hypot(*v)
            if reward[0] >= 1.0 - 1e-9 or speed == 0.0:
                break
            # the speed by the offset (cos theta scales it), the direction by the heading
            theta = math.acos(min(math.cos(theta) * t_speed / speed, 1.0))
            heading += math.remainder(t_heading - math.atan2(v[1], v[0]), 2 * math.pi)
            act = self._action(task, math.sin(theta), heading, lo)
        return act


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
    """The reference policy of an env (or of a variant registered with one's env class): the
    analytic oracle, or chase-and-hit for control."""
    from spinstrike.envs import base_id

    return {"SpinStrike/RodSpin-v0": RodSpinOracle, "SpinStrike/PuckSpeed-v0": PuckSpeedOracle,
            "SpinStrike/PuckSpeed-v1": PuckSpeedOracle,
            "SpinStrike/RodSpinControl-v0": ChaseAndHit,
            "SpinStrike/PuckSpeedControl-v0": ChaseAndHit}[base_id(env_id)]()

