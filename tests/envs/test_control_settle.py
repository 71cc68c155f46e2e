"""A settled step of a control env moves the bodies that meet nothing along their closed-form
paths (found by a new user: a rod sliding along a cushion at a slight tilt has every step
settled, and the settle's Euler substeps moved the mallet, touching nothing, 1.3e-4 m a step off
its constant-force parabola)."""

import math

import gymnasium as gym
import numpy as np

import spinstrike  # noqa: F401  (registers the ids)


def test_a_mallet_touching_nothing_keeps_its_path_through_settled_steps():
    env = gym.make("SpinStrike/RodSpinControl-v0")
    env.reset(seed=0)
    w = env.unwrapped.world
    assert w.names[:2] == ("rod", "mallet")
    tilt = 0.0014  # the rod's low end on the bottom cushion, sliding along it
    with w.edit() as e:
        e.set_state(positions=[[0.0, -0.4 + 0.01 + 0.15 * math.sin(tilt)], [-0.3, 0.1]],
                    velocities=[[0.3, -0.01], [0.5, 0.0]], angles=[tilt, 0.0], omegas=0.0)
    mass = float(w.mass[0, 1])
    settled = 0
    for _ in range(6):
        p, v = w.state.positions[0, 1].copy(), w.state.velocities[0, 1].copy()
        info = env.step(np.array([0.5, 0.3], np.float32))[-1]
        settled += bool(info["fallback"])
        force = np.asarray(info["force"])
        want = p + v * 0.02 + 0.5 * force / mass * 0.02 ** 2
        np.testing.assert_allclose(w.state.positions[0, 1], want, rtol=0, atol=1e-15)
        np.testing.assert_allclose(w.state.velocities[0, 1], v + force / mass * 0.02, rtol=0,
                                   atol=1e-14)
    assert settled >= 4  # the case: settled steps
