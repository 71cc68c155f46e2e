"""A sustained contact of one free pair is held (``solvers._hold``), not settled.

A disk resting on the side of a spinning rod, restitution 0, no force: the rod's turning pushes
the disk round, the exact loop makes a Zeno run of plastic impacts, and before the hold the
rest of every step was settled in fixed first-order substeps (``fallback``). Held, the contact
is integrated as a constraint (RATTLE): momentum and angular momentum kept to round-off, no
energy gained, no overlap; and the motion agrees with the settle, an independent integration,
at a substep of 1e-6 s (run on the same pair with a far-away puck added: two-pair worlds are
not held).
"""

import numpy as np
import pytest

from spinstrike import physics

TOL = 1e-9
DT = 1.0 / 30.0


def _scene(extra=False, settle_substep=1e-5, e=0.0, masses=(0.1, 0.1)):
    bodies = [{"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02,
               "mass": masses[0], "omega": 5.0},
              {"name": "disk", "shape": "disk", "radius": 0.03, "mass": masses[1],
               "position": [0.15, 0.04]}]
    if extra:
        bodies.append({"name": "far", "shape": "disk", "radius": 0.03, "mass": 0.1,
                       "position": [50.0, 50.0]})
    return {"effects": ["rotation"],
            "solver": {"mode": "exact", "tolerance": TOL, "settle_substep": settle_substep},
            "materials": {"restitution": e}, "bodies": bodies}


def _gap(world):
    (xr, yr), (xd, yd) = world.state.positions[0, :2]
    a = world.state.angles[0, 0]
    h = float(world.half_length[0, 0])
    s = np.clip((xd - xr) * np.cos(a) + (yd - yr) * np.sin(a), -h, h)
    d = np.hypot(xd - xr - s * np.cos(a), yd - yr - s * np.sin(a))
    return d - float(world.radius[0, 0] + world.radius[0, 1])


@pytest.mark.parametrize("masses", [(0.1, 0.1), (1e-9, 1e-9), (1e9, 1e9), (1.0, 1e-3),
                                    (1e-3, 1.0)])
def test_a_disk_pushed_round_by_a_spinning_rod_is_held_and_keeps_the_invariants(masses):
    """Also at mass scales where the energy guard's 4x4 system mixes numbers 1e18 apart."""
    world = physics.World(_scene(masses=masses))
    p0, l0, k0 = world.momentum()[0], world.angular_momentum()[0], world.kinetic_energy()[0]
    held = 0
    for _ in range(6):  # 0.2 s
        world.step(DT)
        s = world.last_step
        assert not s.fallback[0] and not s.capped[0]
        assert s.events[0] < 100  # the Zeno run is cut short, never max_events
        held += int(s.substeps[0])
        assert np.all(np.isfinite(world.state.positions))
        np.testing.assert_allclose(world.momentum()[0], p0, rtol=0, atol=1e-15)
        assert world.angular_momentum()[0] == pytest.approx(l0, rel=1e-12)
        assert world.kinetic_energy()[0] <= k0 * (1 + 1e-12)
        assert _gap(world) >= -TOL
    assert held > 0  # the contact was held


def test_the_held_contact_agrees_with_a_fine_settle():
    world = physics.World(_scene())
    ref = physics.World(_scene(extra=True, settle_substep=1e-6))
    for _ in range(3):
        world.step(DT)
        ref.step(DT)
        assert not world.last_step.fallback[0] and ref.last_step.fallback[0]
    got = world.get_state()["state"][0, :2]
    want = ref.get_state()["state"][0, :2]
    # positions (m) and angles (rad), velocities (m/s) and spins (rad/s): the settle at 1e-6 s
    # is itself ~1e-5 off its limit (first order)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-4)
