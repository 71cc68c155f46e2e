"""A disk pushed into a cushion comes to rest on it (``solvers._rest_on_cushions``).

Its bounces under a constant force form a geometric series that ends in finite time; the exact
solver puts the disk at that limit once a bounce leaves it slower than ``zeno_speed``: no normal
velocity, the cushion holding back the force's normal component for the rest of the step, so
that the disk slides along the cushion in closed form. Before, each such step ran into the
resting-bounce limit and was settled by fixed substeps (``fallback``), which cost ~30x a plain
step and left a residual bounce of a few mm/s.

The motion along a frictionless cushion does not depend on the bounces at all: the tests check
it against the closed form, the normal coordinate against the cushion, and the seams (the
world's forces after a step, a reversed force, the control env through ``gym.make``).
"""

import gymnasium as gym
import numpy as np
import pytest

from spinstrike import physics

HALF_W, HALF_H = 0.6, 0.4
R, M = 0.04, 0.3
DT = 0.02
TOL = 1e-9


def _scene(e, position, velocity, effects=("rotation", "walls")):
    table = {"size": [2 * HALF_W, 2 * HALF_H]}
    if "table_friction" in effects:  # (a driven body is exempt: its force is the net force)
        table["friction"] = 0.05
    return {"table": table,
            "effects": list(effects),
            "materials": {"restitution": e},
            "bodies": [{"name": "mallet", "shape": "disk", "radius": R, "mass": M,
                        "driven": True, "position": list(position),
                        "velocity": list(velocity)}]}


@pytest.mark.parametrize("e", [0.0, 0.3, 0.9])
@pytest.mark.parametrize("effects", [("rotation", "walls"),
                                     ("rotation", "walls", "table_friction")])
def test_a_disk_driven_into_a_cushion_rests_on_it_and_slides_in_closed_form(e, effects):
    x0, y0, vx0, vy0 = 0.45, -0.1, 1.2, 0.4
    fx, fy = 6.0, -0.06  # along the cushion: stays clear of the corners
    world = physics.World(_scene(e, (x0, y0), (vx0, vy0), effects))
    world.set_force("mallet", (fx, fy))
    steps = 150  # 3 s: the bounces at e = 0.9 end after ~2.2 s
    for k in range(1, steps + 1):
        world.step(DT)
        assert not world.last_step.fallback.any(), f"step {k} was settled"
        np.testing.assert_array_equal(world.forces[0, 0], [fx, fy])  # handed back
        t = k * DT
        (x, y), (vx, vy) = world.state.positions[0, 0], world.state.velocities[0, 0]
        # along the frictionless cushion: the free parabola, whatever the bounces
        assert y == pytest.approx(y0 + vy0 * t + 0.5 * fy / M * t * t, abs=1e-12)
        assert vy == pytest.approx(vy0 + fy / M * t, abs=1e-12)
        assert x <= HALF_W - R + TOL  # never into the cushion
    # at rest on the cushion by the end
    assert x == pytest.approx(HALF_W - R, abs=TOL)
    assert vx == 0.0
    assert world.last_step.events[0] <= 2


def test_in_a_corner_the_disk_stops():
    world = physics.World(_scene(0.5, (0.4, 0.2), (1.0, 0.5)))
    world.set_force("mallet", (3.0, 2.0))
    for _ in range(60):
        world.step(DT)
        assert not world.last_step.fallback.any()
    np.testing.assert_allclose(world.state.positions[0, 0], [HALF_W - R, HALF_H - R], atol=TOL)
    np.testing.assert_array_equal(world.state.velocities[0, 0], [0.0, 0.0])


def test_a_reversed_force_pulls_the_disk_off_the_cushion():
    world = physics.World(_scene(0.3, (0.5, 0.0), (0.5, 0.0)))
    world.set_force("mallet", (4.0, 0.0))
    for _ in range(30):
        world.step(DT)
    x_wall = world.state.positions[0, 0, 0]
    assert x_wall == pytest.approx(HALF_W - R, abs=TOL)
    world.set_force("mallet", (-4.0, 0.0))  # the user's force, not what the cushion held back
    world.step(DT)
    x = world.state.positions[0, 0, 0]
    assert x == pytest.approx(x_wall - 0.5 * 4.0 / M * DT * DT, abs=1e-12)
    assert world.state.velocities[0, 0, 0] == pytest.approx(-4.0 / M * DT, abs=1e-12)


def test_resting_never_gains_energy():
    """Kinetic energy after a step never exceeds the energy before plus the force's work."""
    rng = np.random.default_rng(5)
    batch = 64
    world = physics.World(_scene(0.6, (0.0, 0.0), (0.0, 0.0)), batch_size=batch)
    pos = rng.uniform([-0.5, -0.3], [0.5, 0.3], (batch, 1, 2))
    world.set_state(positions=pos, velocities=rng.uniform(-2, 2, (batch, 1, 2)))
    for _ in range(80):
        force = rng.uniform(-6, 6, (batch, 2))
        world.set_force("mallet", force)
        x0 = world.state.positions[:, 0].copy()
        ke0 = 0.5 * M * (world.state.velocities[:, 0] ** 2).sum(1)
        world.step(DT)
        work = (force * (world.state.positions[:, 0] - x0)).sum(1)
        ke1 = 0.5 * M * (world.state.velocities[:, 0] ** 2).sum(1)
        assert (ke1 - ke0 - work <= 1e-9).all()
        assert not world.last_step.fallback.any()


def test_a_control_env_pushing_into_a_cushion_is_never_settled():
    """Through gym.make: a policy that drives the mallet into the left cushion (what an
    untrained agent often does) used to send every step to the fixed-step settling."""
    env = gym.make("SpinStrike/RodSpinControl-v0")
    env.reset(seed=3)
    settled = 0
    xs = []
    for _ in range(100):
        obs, _, _, _, info = env.step(np.array([-1.0, 0.3], dtype=np.float32))
        settled += bool(info["fallback"])
        xs.append(env.unwrapped.world.state.positions[0, 1, 0])
    env.close()
    assert settled == 0
    world = env.unwrapped.world
    assert world.names[1] == "mallet"
    half_w = world.table_half_size[0, 0]
    assert xs[-1] == pytest.approx(-half_w + world.radius[0, 1], abs=TOL)  # on the left cushion
