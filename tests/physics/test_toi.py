"""Time of impact with rotation, checked against an independent root finder.

A free rod translates and spins, sweeping its end into a resting disk. The reference contact time
is found here by dense sampling and bisection of the analytic gap
function; the reference post-impact velocities by the impulse law written out in this file.
"""

import math

import numpy as np

from spinstrike import physics

R, THICK, RAD = 0.2, 0.004, 0.02
M_ROD, M_DISK, OMEGA0, V_ROD = 0.3, 0.1, 7.0, (0.4, -0.1)
DISK = (0.05, 0.17)


def _scene(tolerance):
    return {
        "effects": ["rotation"],
        "solver": {"mode": "exact", "tolerance": tolerance},
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 2 * R, "thickness": THICK, "mass": M_ROD,
             "angle": 0.0, "omega": OMEGA0, "velocity": list(V_ROD)},
            {"name": "disk", "shape": "disk", "radius": RAD, "mass": M_DISK,
             "position": list(DISK)},
        ],
    }


def _gap(t):
    """Analytic gap of the rod (translating, spinning) and the disk at time t."""
    cx, cy = V_ROD[0] * t, V_ROD[1] * t
    a = OMEGA0 * t
    ux, uy = math.cos(a), math.sin(a)
    dx, dy = DISK[0] - cx, DISK[1] - cy
    s = max(-R, min(R, dx * ux + dy * uy))
    px, py = cx + s * ux, cy + s * uy
    return math.hypot(DISK[0] - px, DISK[1] - py) - THICK / 2 - RAD


def _reference():
    ts = np.linspace(0.0, 1.0, 100001)
    g = np.array([_gap(t) for t in ts])
    assert np.any(g <= 0), "the set-up must produce a contact within 1 s"
    k = int(np.argmax(g <= 0))
    assert k > 0
    lo, hi = ts[k - 1], ts[k]
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if _gap(mid) > 0:
            lo = mid
        else:
            hi = mid
    t = 0.5 * (lo + hi)
    # impulse law at that geometry
    cx, cy = V_ROD[0] * t, V_ROD[1] * t
    a = OMEGA0 * t
    ux, uy = math.cos(a), math.sin(a)
    s = max(-R, min(R, (DISK[0] - cx) * ux + (DISK[1] - cy) * uy))
    qx, qy = cx + s * ux, cy + s * uy
    d = math.hypot(DISK[0] - qx, DISK[1] - qy)
    nx, ny = (DISK[0] - qx) / d, (DISK[1] - qy) / d
    px, py = qx + THICK / 2 * nx, qy + THICK / 2 * ny
    rax, ray = px - cx, py - cy
    inertia = physics.World(_scene(1e-9)).inertia[0, 0]
    vpx, vpy = V_ROD[0] - OMEGA0 * ray, V_ROD[1] + OMEGA0 * rax
    vn = (0 - vpx) * nx + (0 - vpy) * ny
    rn = rax * ny - ray * nx
    j = -2.0 * vn / (1 / M_ROD + 1 / M_DISK + rn**2 / inertia)
    v_rod = (V_ROD[0] - j * nx / M_ROD, V_ROD[1] - j * ny / M_ROD)
    w_rod = OMEGA0 - rn * j / inertia
    v_disk = (j * nx / M_DISK, j * ny / M_DISK)
    return t, v_rod, w_rod, v_disk


REF = _reference()


def _simulate(tolerance):
    world = physics.World(_scene(tolerance))
    contacts = world.step(REF[0] + 1e-3)
    return world, contacts


def test_contact_time_and_velocities_match_independent_reference():
    t_ref, v_rod, w_rod, v_disk = REF
    world, contacts = _simulate(1e-12)
    assert len(contacts) == 1
    assert abs(contacts.time[0] - t_ref) < 1e-7
    v = world.state.velocities[0]
    assert np.allclose(v[0], v_rod, atol=1e-7)
    assert np.allclose(v[1], v_disk, atol=1e-7)
    assert abs(world.state.omegas[0, 0] - w_rod) < 1e-7 * OMEGA0


def test_error_shrinks_with_tolerance():
    t_ref, v_rod, w_rod, v_disk = REF
    errors = []
    for tol in (1e-2, 1e-3, 1e-5, 1e-7, 1e-9, 1e-11):
        world, contacts = _simulate(tol)
        errors.append(abs(world.state.velocities[0, 1] - v_disk).max())
    assert errors[0] > 1e-5  # the coarse tolerance is visibly off...
    for coarse, fine in zip(errors, errors[1:], strict=False):
        assert fine < coarse or fine < 1e-12  # ...and every tenfold-finer setting is better
    assert errors[-1] < 1e-9
