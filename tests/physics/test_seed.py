"""Seed §1 and the wall formula reproduced by simulation, not by calling the formula."""

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.physics.analytic import rod_strike, rod_strike_light_rod, rod_wall
from tests.physics.scenes import seed_strike

THETAS = [0.0, 30.0, 60.0, 85.0]
RATIOS = [1e-3, 1.0, 1e3]


@pytest.mark.parametrize("theta_deg", THETAS)
@pytest.mark.parametrize("ratio", RATIOS)
def test_seed_section1_by_simulation(theta_deg, ratio):
    theta = np.radians(theta_deg)
    m2 = 1.0
    m1 = ratio * m2
    r, V = 0.2, 1.0
    world = physics.World(seed_strike(theta, m1, m2, r=r, V=V))
    # just long enough for the one impact; the spinning rod may come round later
    contacts = world.step(0.06 / V)
    assert len(contacts) == 1
    v = world.state.velocities[0]
    w = world.state.omegas[0]
    V1, V2, W1 = rod_strike(m1, m2, r, theta, V)
    assert abs(v[0, 0] - V1) / V < 1e-9
    assert abs(v[1, 0] - V2) / V < 1e-9
    assert abs(v[0, 1]) / V < 1e-9 and abs(v[1, 1]) / V < 1e-9
    # the upper tip is pushed back (-x) above the centre: torque r x F > 0, CCW spin
    assert abs(w[0] - W1) / (V / r) < 1e-9
    assert w[1] == 0.0  # a frictionless disk never spins: r x n is exactly 0
    assert contacts.impulse[0] == pytest.approx(m2 * V2, rel=1e-12)
    np.testing.assert_allclose(contacts.normal[0], [1.0, 0.0], atol=1e-15)


def test_seed_light_rod_limit():
    """m1/m2 -> 0 (seed's limit formulas), simulated with m1/m2 = 1e-12."""
    theta = np.radians(40)
    world = physics.World(seed_strike(theta, 1e-12, 1.0))
    world.step(0.06)
    V1, V2, W1 = rod_strike_light_rod(theta, 1.0, 0.2)
    v = world.state.velocities[0]
    assert abs(v[0, 0] - V1) < 1e-9
    assert abs(v[1, 0] - V2) < 1e-9
    assert abs(world.state.omegas[0, 0] - W1) * 0.2 < 1e-9


@pytest.mark.parametrize("e", [0.0, 0.5, 1.0])
def test_restitution_scales_impulse(e):
    theta = np.radians(30)
    world = physics.World(seed_strike(theta, 1.0, 2.0, e=e))
    world.step(0.06)
    V1, V2, W1 = rod_strike(1.0, 2.0, 0.2, theta, 1.0, e=e)
    assert world.state.velocities[0, 1, 0] == pytest.approx(V2, abs=1e-12)
    assert world.state.velocities[0, 0, 0] == pytest.approx(V1, abs=1e-12)


@pytest.mark.parametrize("theta_deg", [0.0, 20.0, 45.0, 70.0])
@pytest.mark.parametrize("e", [0.3, 1.0])
def test_rod_strikes_wall_matches_seed_wall_formula(theta_deg, e):
    """A rod slides into the right cushion; its leading tip strikes at lever arm r cos(theta)."""
    theta = np.radians(theta_deg)
    r, m, V = 0.2, 0.7, 2.0
    angle = np.pi / 2 - theta  # axis (sin t, cos t): the upper tip leads toward +x
    tip_x = r * np.cos(angle)
    half_w = tip_x + 0.001 + 0.05  # tip cap 0.05 m from the cushion
    scene = {
        "effects": ["rotation", "walls"],
        "table": {"size": [2 * half_w, 2.0]},
        "materials": {"restitution": e},
        "bodies": [{"name": "rod", "shape": "rod", "length": 2 * r, "thickness": 0.002,
                    "mass": m, "angle": float(angle), "velocity": [V, 0.0]}],
    }
    world = physics.World(scene)
    inertia = world.inertia[0, 0]
    contacts = world.step(0.05 / V + 1e-3)
    assert len(contacts) == 1
    assert contacts.body_b[0] == world.index("wall_right")
    lever = r * np.cos(theta) if theta_deg > 0 else 0.0  # theta=0: rod flat on the cushion
    j, v_after, w_after = rod_wall(m, inertia, lever, V, e=e)
    assert contacts.impulse[0] == pytest.approx(j, rel=1e-10)
    assert world.state.velocities[0, 0, 0] == pytest.approx(v_after, abs=1e-10 * V)
    assert abs(world.state.omegas[0, 0]) == pytest.approx(w_after, abs=1e-10 * V / r)
    np.testing.assert_allclose(contacts.normal[0], [1.0, 0.0])
