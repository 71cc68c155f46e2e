"""The packaged break (``configs/scenes/break.yaml``: a rack of 15 pucks and a striker), loaded
as a user loads a scene and stepped for 3 s on the exact solver's event calendar: the rack
breaks (the apex ball flies off, nearly every ball moves), no two bodies ever overlap,
momentum is conserved until the first cushion contact, and the kinetic energy never grows
(e = 0.95)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spinstrike import physics
from spinstrike.envs.config import load_packaged_scene
from spinstrike.physics import layout

PATH = Path(__file__).resolve().parents[2] / "configs" / "scenes" / "break.yaml"
SCENE = physics.load_scene(PATH)


def test_the_break_is_the_packaged_scene():
    assert physics.load_scene(load_packaged_scene("break")) == SCENE
    assert len(SCENE.bodies) == 16


def test_the_break_keeps_momentum_and_never_gains_energy():
    world = physics.World(SCENE)
    assert world.flags.jam == layout.LEVEL_MANY_BODIES
    n = world.n_bodies
    start = world.state.positions[0].copy()
    p0 = world.momentum()[0].copy()
    e_prev = world.kinetic_energy()[0]
    cushions = False
    contacts = 0
    for _ in range(150):
        c = world.step(0.02)
        contacts += len(c.impulse)
        assert not world.last_step.fallback.any()
        assert world.gaps().min() >= -world.tolerance
        e = world.kinetic_energy()[0]
        assert e <= e_prev * (1 + 1e-12)
        e_prev = e
        cushions = cushions or bool((c.body_b >= n).any())
        if not cushions:
            np.testing.assert_allclose(world.momentum()[0], p0, rtol=0, atol=1e-12 * abs(p0).max())
    moved = np.linalg.norm(world.state.positions[0] - start, axis=1)
    assert moved[1] > 0.3 and (moved > 0.01).sum() >= 13  # the apex flies, the rack breaks
    assert contacts > 30
    assert e_prev < 0.9 * 0.5 * 0.17 * 6.0**2  # the bounces and cushions took their share
