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


def _pushed_on_cushions(n, e, solver):
    """n driven disks in a row above the bottom cushion (n >= 8: the exact solver's event
    calendar), a puck coming in from the left to knock the first off mid-step, pressed down
    (and the last into the right cushion too: a corner) by their forces."""
    bodies = [{"name": f"d{k}", "shape": "disk", "radius": R, "mass": M * (1 + 0.2 * k),
               "driven": True, "position": [0.55 - 0.1 * (n - 1 - k), -0.3]}
              for k in range(n)]
    bodies.append({"name": "puck", "shape": "disk", "radius": R, "mass": 0.1,
                   "position": [-0.55, -HALF_H + R], "velocity": [1.5, 0.0]})
    return physics.World({"table": {"size": [2 * HALF_W, 2 * HALF_H]},
                          "effects": ["rotation", "walls"], "materials": {"restitution": e},
                          "solver": solver, "bodies": bodies}, max_contacts=20000)


@pytest.mark.parametrize("n", [2, 9])
@pytest.mark.parametrize("e", [0.0, 0.5])
@pytest.mark.parametrize("solver", [{"mode": "exact"}, {"mode": "fixed", "substeps": 20}])
def test_the_cushions_push_on_a_resting_disk_is_in_the_contacts(n, e, solver):
    """Walk W24a F1: a researcher summing ``contacts`` (or ``watched_impulse``) for the force on
    a cushion, or checking m dv = F dt + the impulses, found the exact solver's rests left out:
    a 0.5 kg ball held on a cushion by 4.9 N recorded 6e-11 N s a step where the fixed solver
    and pymunk recorded F dt = 0.049. Every step, for every body, the recorded impulses account
    for its momentum change, as on the fixed solver; the watched pair's sum is F dt once the
    disk rests (of two disks; nine press on each other)."""
    world = _pushed_on_cushions(n, e, solver)
    force = np.zeros((n + 1, 2))
    force[:n, 1] = -3.0
    force[n - 1, 0] = 2.0  # the last one into the bottom-right corner
    for k in range(n):
        world.set_force(f"d{k}", force[k])
    world.watch("d0", "wall_bottom")
    mass = world.mass[0]
    for step in range(60):
        v0 = world.state.velocities[0].copy()
        c = world.step(DT)
        assert c.dropped[0] == 0
        got = np.zeros((n + 1, 2))  # the impulses each body received, as the records say
        for a, b, nrm, j in zip(c.body_a, c.body_b, c.normal, c.impulse, strict=True):
            got[a] -= j * nrm
            if b < n + 1:
                got[b] += j * nrm
        np.testing.assert_allclose(mass[:, None] * (world.state.velocities[0] - v0),
                                   force * DT + got, rtol=0, atol=1e-12,
                                   err_msg=f"step {step}")
        if step >= 40 and n == 2:  # at rest, the knock over: the cushion holds the force (in
            # the row of nine, its neighbours press on d0 at a slant at e = 0)
            assert world.last_step.watched_impulse[0] == pytest.approx(3.0 * DT, rel=1e-12)
    if solver["mode"] == "exact" and n == 2:  # the holds' records are marked, not impacts
        assert c.held.sum() >= 2 and (c.body_b[c.held] >= n + 1).all()
        assert c.impulse[c.held & (c.body_a == 0)].sum() == pytest.approx(3.0 * DT, rel=1e-4)
    else:
        assert not c.held.any() or solver["mode"] == "exact"
    np.testing.assert_allclose(world.state.positions[0, :n, 1], -HALF_H + R, atol=TOL)
    if e == 0.0 or (solver["mode"] == "exact" and not world.last_step.fallback[0]):  # (fixed
        assert (world.state.velocities[0, :n, 1] == 0.0).all()  # substeps at e > 0 leave a
        # bounce of e F h / m, walk W24a F6)
