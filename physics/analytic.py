"""Closed forms: the seed note's §1 rod strike, its limits, and the wall limit.

They are the test oracles and the analytic (oracle) policy. Conventions: the seed's set-up has a
rod (body 1, mass ``m1``, half-length ``r``, inertia ``I1 = m1 r^2 / 3``) moving at speed ``V``
whose tip strikes a point mass ``m2`` at rest; the impulse is along the velocity and its lever arm
about the rod's centre is ``r cos(theta)`` (``theta = 0``: the impulse is perpendicular to the rod
at its tip). Elastic (e = 1) unless ``e`` is given.

Note on the seed's energy line: it writes ``1/2 m1 V2^2`` for the struck body's energy; it must be
``1/2 m2 V2^2`` (the closed forms below, which are the seed's, are consistent with ``m2``).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "rod_strike",
    "rod_strike_light_rod",
    "rod_wall",
    "impulse_two_body",
]


def rod_strike(m1, m2, r, theta, V, e=1.0):
    """Seed §1: rod tip (mass m1, half-length r, I1 = m1 r^2/3) strikes a resting point mass m2.

    Returns:
        (V1, V2, omega1): the rod's velocity along V after, the point mass's velocity along V,
        and the magnitude of the rod's spin, rad/s. For ``e = 1`` these are the seed's
        ``V1 = (m1 + (3 cos^2 - 1) m2) / (m1 + (3 cos^2 + 1) m2) V``,
        ``V2 = 2 m1 / (m1 + (3 cos^2 + 1) m2) V`` and
        ``|w1| = 6 m2 cos(theta) V / ((m1 + (3 cos^2 + 1) m2) r)``.
    """
    c = np.cos(theta)
    den = m1 + (3.0 * c**2 + 1.0) * m2
    j_over = (1.0 + e) / 2.0  # the impulse scales with (1 + e)
    V2 = 2.0 * j_over * m1 / den * V
    V1 = V - m2 / m1 * V2
    omega1 = 6.0 * j_over * m2 * c * V / (den * r)
    return V1, V2, np.abs(omega1)


def rod_strike_light_rod(theta, V, r):
    """Seed §1 limits for m1/m2 -> 0.

    Returns:
        (V1, V2, |omega1|) = ((3c^2-1)/(3c^2+1) V, 0, 6cV/((3c^2+1)r)), c = cos(theta).
    """
    c = np.cos(theta)
    return (3 * c**2 - 1) / (3 * c**2 + 1) * V, 0.0 * V, np.abs(6 * c * V / ((3 * c**2 + 1) * r))


def rod_wall(m, inertia, lever, V, e=1.0):
    """A body hits a static wall (m2, I2 -> infinity): seed §2.2's wall formula.

    Args:
        m, inertia: mass and moment of inertia of the moving body.
        lever: |r x n|, the lever arm of the contact point about its centre, m.
        V: normal approach speed of the centre (m/s, > 0 toward the wall), no spin before.

    Returns:
        (j, V_after, |omega_after|): impulse magnitude, the centre's normal velocity after
        (negative = away from the wall) and the spin picked up.
    """
    j = (1.0 + e) * V / (1.0 / m + lever**2 / inertia)
    return j, V - j / m, np.abs(j * lever / inertia)


def impulse_two_body(vn, inv_m1, inv_m2, rn1, rn2, inv_i1, inv_i2, e=1.0):
    """Seed §2.2: ``j = -(1+e) vn / (1/m1 + 1/m2 + (r1 x n)^2/I1 + (r2 x n)^2/I2)``.

    ``vn`` is the normal relative point velocity ``(v2p - v1p) . n`` (negative when approaching),
    with n from body 1 to body 2.
    """
    return -(1.0 + e) * vn / (inv_m1 + inv_m2 + rn1**2 * inv_i1 + rn2**2 * inv_i2)
