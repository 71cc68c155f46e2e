"""Settled steps (the exact solver's fixed-substep fallback) seen from the user's side: scenes
as a user writes them, checked for what the settle promises (no overlap beyond the tolerance,
no energy gain, pinned bodies stay put, no NaN)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from spinstrike import physics


def _pivot_flat(wall: str, omega: float) -> physics.World:
    """A pivoted rod lying flat on cushion ``wall`` (touching: legal), turning into it."""
    half = (0.6, 0.4)
    if wall in ("bottom", "top"):
        y = -half[1] + 0.01 if wall == "bottom" else half[1] - 0.01
        position, angle = [0.0, y], 0.0
    else:
        x = -half[0] + 0.01 if wall == "left" else half[0] - 0.01
        position, angle = [x, 0.0], np.pi / 2
    rod = dict(name="rod", shape="rod", length=0.6, thickness=0.02, mass=1.0,
               position=position, angle=angle, omega=omega, pivot=True)
    return physics.World(dict(table=dict(size=[1.2, 0.8]), effects=["rotation", "walls"],
                              materials=dict(restitution=0.5), bodies=[rod]))


@pytest.mark.parametrize("dt", [1e-4, 1e-2])
@pytest.mark.parametrize("wall,omega", [("bottom", 1.0), ("bottom", -1.0), ("top", 1.0),
                                        ("left", -3.0)])
def test_pivoted_rod_flat_on_a_cushion_is_not_left_inside_it(dt, wall, omega):
    # its flat contact's middle is its pivot, where neither an impulse nor a positional
    # correction acts: settled steps handed on ~3e-7 m of overlap (300x the tolerance) and the
    # rod kept its spin, pressed into the cushion
    w = _pivot_flat(wall, omega)
    pin = w.state.positions[0, 0].copy()
    energy = w.kinetic_energy()[0]
    for _ in range(60):
        w.step(dt)
        assert np.isfinite(w.state.positions).all() and np.isfinite(w.state.angles).all()
        assert w.gaps()[0].min() >= -w.tolerance
        assert np.array_equal(w.state.positions[0, 0], pin)
        e = w.kinetic_energy()[0]
        assert e <= energy * (1.0 + 1e-12)
        energy = e
    # locked (either way of turning drives an end into the cushion): the impacts at its ends
    # (e = 0.5) stop it
    assert abs(w.state.omegas[0, 0]) < 1e-6


def _far_post_worlds():
    """A rattling nine-body scene (rods, disks, e = 0.8) as a user writes it, and the same
    scene with a 0.1 mm static post in a far corner that no body ever reaches."""
    with open(Path(__file__).parent / "data" / "far_post_scene.json") as f:
        scene = json.load(f)
    post = dict(name="post", shape="disk", radius=1e-4, static=True, position=[0.5999, 0.3999])
    return (physics.World(scene), physics.World(dict(scene, bodies=scene["bodies"] + [post])),
            len(scene["bodies"]))


def test_a_far_unreachable_post_leaves_settled_steps_bit_for_bit_the_same():
    # the settle planned its substeps from every pair, the far post's included (its radii sum
    # set the bound however far apart): 7 substeps became 23 and the motion changed (1 mm in
    # that step, ~1 m after 3 s)
    a, b, n = _far_post_worlds()
    settled = 0
    for _ in range(60):
        a.step(0.01)
        cb = b.step(0.01)
        assert not np.isin(n, cb.body_a).any() and not np.isin(n, cb.body_b).any()
        settled += int(a.last_step.fallback[0] != 0)
        assert np.array_equal(a.last_step.substeps, b.last_step.substeps)
        assert np.array_equal(a.state.positions[0], b.state.positions[0, :n])
        assert np.array_equal(a.state.angles[0], b.state.angles[0, :n])
        assert np.array_equal(a.state.velocities[0], b.state.velocities[0, :n])
        assert np.array_equal(a.state.omegas[0], b.state.omegas[0, :n])
        assert a.gaps()[0].min() >= -a.tolerance and b.gaps()[0].min() >= -b.tolerance
    assert settled > 0  # the case this is about


@pytest.mark.parametrize("dt", [1e-4, 1e-2])
@pytest.mark.parametrize("base_length,omega", [(1.0, 1.0), (0.6, -1.0), (0.2, 1.0)])
def test_pivoted_rod_flat_on_a_static_rod_does_not_pass_through_it(dt, base_length, omega):
    # the flat contact's point was the middle of the overlap, the pivot, where neither body can
    # be moved by an impulse or a correction: the pivoted rod turned through a 0.2 m static rod
    # (0.117 m of overlap, cores crossed), and a 1 m one was left 2.9e-7 m inside
    rod = dict(name="rod", shape="rod", length=0.6, thickness=0.02, mass=1.0,
               position=[0.0, 0.0], angle=0.0, omega=omega, pivot=True)
    base = dict(name="base", shape="rod", length=base_length, thickness=0.02, static=True,
                position=[0.0, -0.02], angle=0.0)
    w = physics.World(dict(table=dict(size=[1.2, 0.8]), effects=["rotation", "walls"],
                           materials=dict(restitution=0.5), bodies=[rod, base]))
    energy = w.kinetic_energy()[0]
    for _ in range(60):
        w.step(dt)
        assert np.isfinite(w.state.angles).all() and np.isfinite(w.state.omegas).all()
        assert w.gaps()[0].min() >= -w.tolerance
        assert np.array_equal(w.state.positions[0], [[0.0, 0.0], [0.0, -0.02]])
        e = w.kinetic_energy()[0]
        assert e <= energy * (1.0 + 1e-12)
        energy = e
    assert abs(w.state.omegas[0, 0]) < 1e-6
