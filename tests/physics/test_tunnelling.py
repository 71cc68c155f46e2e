"""The exact solver cannot tunnel; the fixed solver can (that is its documented price)."""

import numpy as np
import pytest

from spinstrike import physics


def _scene(speed):
    return {
        "effects": ["rotation"],
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.001, "mass": 0.1,
             "angle": float(np.pi / 2)},
            {"name": "puck", "shape": "disk", "radius": 0.01, "mass": 0.05,
             "position": [-0.5, 0.05], "velocity": [speed, 0.0]},
        ],
    }


@pytest.mark.parametrize("factor", [1.0, 1e2, 1e4, 1e6])
def test_exact_hits_thin_rod_at_any_speed(factor):
    """Moving ``factor`` x (its radius) per step, the puck still hits the 1 mm rod."""
    dt = 0.01
    speed = factor * 0.01 / dt
    world = physics.World(_scene(speed))
    contacts = world.step(2.0 * 0.5 / speed + dt)
    assert len(contacts) >= 1
    assert contacts.body_a[0] == 0 and contacts.body_b[0] == 1
    # the puck bounced back: it is left of the rod, moving left
    assert world.state.positions[0, 1, 0] < 0.0
    assert world.state.velocities[0, 1, 0] < 0.0
    # momentum along x conserved to round-off
    p = world.momentum()[0]
    assert abs(p[0] - 0.05 * speed) <= 1e-12 * 0.05 * speed


def test_fixed_solver_tunnels_when_too_fast():
    speed = 1e4 * 0.01 / 0.01
    world = physics.World(_scene(speed), solver={"mode": "fixed", "substeps": 1})
    contacts = world.step(0.01)
    assert len(contacts) == 0
    assert world.state.positions[0, 1, 0] > 0.0  # passed straight through
