"""Contacts at one instant that share a body: sequential impulses in pair order (README,
"Simultaneous contacts"), so the outcome follows the bodies' order in the scene.

A rod struck at both ends at once by two equal pucks from opposite sides (point-symmetric, so
by symmetry its centre would stay put): the first pair's impulse is the single-hit closed form,
the second meets a rod already moving and turning, and the rod's centre leaves at 0.31 of the
pucks' speed toward the first puck's push; listed the other way round, the mirror image.
Momentum and energy are kept either way (walk W15, 2026-11-28).
"""

from __future__ import annotations

import numpy as np
import pytest

from spinstrike import physics


def _scene(first: str) -> dict:
    pucks = {"a": {"name": "a", "shape": "disk", "radius": 0.03, "mass": 1.0,
                   "position": [0.2, 0.5], "velocity": [0.0, -1.0]},
             "b": {"name": "b", "shape": "disk", "radius": 0.03, "mass": 1.0,
                   "position": [-0.2, -0.5], "velocity": [0.0, 1.0]}}
    second = "b" if first == "a" else "a"
    return {"effects": ["rotation"], "solver": {"mode": "exact", "tolerance": 1e-12},
            "bodies": [{"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02,
                        "mass": 1.0}, pucks[first], pucks[second]]}


def _sequential(world: physics.World, contacts) -> tuple[np.ndarray, np.ndarray]:
    """The impulse law (docs/design.md §2, e = 1, no friction) applied pair after pair at the
    reported contacts, computed here from the bodies' state before the step's impacts."""
    m = world.mass[0].copy()
    inertia = world.inertia[0].copy()
    v = world.state.velocities[0].copy()
    w = world.state.omegas[0].copy()
    x = world.state.positions[0] + v * contacts.time[0]  # free flight up to the impact
    for a, b, p, n in zip(contacts.body_a, contacts.body_b, contacts.point, contacts.normal,
                          strict=True):
        ra, rb = p - x[a], p - x[b]
        rna, rnb = ra[0] * n[1] - ra[1] * n[0], rb[0] * n[1] - rb[1] * n[0]
        va = v[a] + w[a] * np.array([-ra[1], ra[0]])
        vb = v[b] + w[b] * np.array([-rb[1], rb[0]])
        vn = (vb - va) @ n
        j = -2.0 * vn / (1 / m[a] + 1 / m[b] + rna**2 / inertia[a] + rnb**2 / inertia[b])
        v[a] -= j * n / m[a]
        v[b] += j * n / m[b]
        w[a] -= rna * j / inertia[a]
        w[b] += rnb * j / inertia[b]
    return v, w


@pytest.mark.parametrize("first", ["a", "b"])
def test_a_rod_struck_at_both_ends_at_once_follows_the_pair_order(first):
    world = physics.World(_scene(first))
    before = physics.World(_scene(first))
    p0, e0 = world.momentum()[0], world.kinetic_energy()[0]
    c = world.step(0.5)
    assert len(c) == 2 and c.time[0] == c.time[1] == pytest.approx(0.46)
    v, w = _sequential(before, c)
    np.testing.assert_allclose(world.state.velocities[0], v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(world.state.omegas[0], w, rtol=0, atol=1e-12)
    rod_v = world.state.velocities[0, 0]
    push = -1.0 if first == "a" else 1.0  # the first puck's direction of travel
    assert rod_v[1] == pytest.approx(0.31118 * push, abs=1e-5) and rod_v[0] == 0.0
    np.testing.assert_allclose(world.momentum()[0], p0, rtol=0, atol=1e-15)
    assert world.kinetic_energy()[0] == pytest.approx(e0, rel=1e-13)


def test_the_two_orders_are_mirror_images():
    one, other = physics.World(_scene("a")), physics.World(_scene("b"))
    one.step(0.5)
    other.step(0.5)
    np.testing.assert_array_equal(one.state.velocities[0, 0], -other.state.velocities[0, 0])
    assert one.state.omegas[0, 0] == other.state.omegas[0, 0]  # the same turn, either way
