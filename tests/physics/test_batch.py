"""Batch parity: B copies with different parameters and states, stepped together, equal each
stepped alone, bit for bit (serial and parallel kernels alike)."""

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.physics.world import PARALLEL_BATCH

SCENE = {
    "table": {"size": [1.2, 0.8], "friction": 0.05},
    "effects": ["rotation", "walls", "contact_friction", "table_friction"],
    "materials": {"restitution": 0.9, "friction": 0.3},
    "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1},
        {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05, "position": [-0.4, 0.2]},
        {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.2, "driven": True,
         "position": [0.4, -0.25]},
    ],
}


def _randomise(world, rng, env):
    n = len(env)
    world.set_body("rod", mass=rng.uniform(0.05, 0.5, n), length=rng.uniform(0.2, 0.45, n), env=env)
    world.set_body("puck", mass=rng.uniform(0.01, 0.2, n), env=env)
    world.set_material("rod", "puck", restitution=rng.uniform(0.3, 1.0, n), env=env)
    world.set_material("puck", "walls", friction=rng.uniform(0.0, 0.6, n), env=env)
    world.set_table(friction=rng.uniform(0.0, 0.1, n), env=env)
    vel = np.zeros((n, 3, 2))
    vel[:, 1] = rng.uniform(-3, 3, (n, 2))
    vel[:, 2] = rng.uniform(-1, 1, (n, 2))
    world.set_state(velocities=vel, omegas=np.c_[rng.uniform(-10, 10, n), np.zeros((n, 2))],
                    env=env)


@pytest.mark.parametrize("batch", [6, PARALLEL_BATCH + 3])
def test_batch_equals_singles_bit_for_bit(batch):
    rng = np.random.default_rng(0)
    world = physics.World(SCENE, batch_size=batch)
    _randomise(world, rng, np.arange(batch))
    forces = rng.uniform(-1, 1, (30, batch, 2))
    check = [0, 1, batch // 2, batch - 1]
    singles = []
    for b in check:
        single = physics.World(SCENE)
        single.set_body("rod", mass=world.mass[b, 0], length=2 * world.half_length[b, 0])
        single.set_body("puck", mass=world.mass[b, 1])
        single.set_material("rod", "puck", restitution=world.restitution("rod", "puck")[b])
        single.set_material("puck", "walls", friction=world.friction("puck", "wall_left")[b])
        single.set_table(friction=world.table_mu[b])
        single.set_state(velocities=world.state.velocities[b:b + 1],
                         omegas=world.state.omegas[b:b + 1])
        singles.append(single)
    n_contacts = 0
    for k in range(30):
        world.set_force("mallet", forces[k])
        contacts = world.step(0.02)
        n_contacts += len(contacts)
        for b, single in zip(check, singles, strict=True):
            single.set_force("mallet", forces[k, b])
            c1 = single.step(0.02)
            mine = contacts.batch == b
            assert np.array_equal(world.get_state()["state"][b], single.get_state()["state"][0])
            assert np.array_equal(contacts.impulse[mine], c1.impulse)
            assert np.array_equal(contacts.time[mine], c1.time)
    assert n_contacts > 0
