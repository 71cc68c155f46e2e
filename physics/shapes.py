"""Shapes and their mass properties (free helpers, like pymunk's ``moment_for_*``).

Every body is a *capsule*: a core segment of half-length ``h`` swept by a disk of radius ``rho``.
A disk is the capsule with ``h = 0``; a rod of ``length`` L and ``thickness`` d has ``h = L/2`` and
``rho = d/2``. Formulas work on floats and numpy arrays alike.
"""

from __future__ import annotations

import numpy as np

__all__ = ["capsule_area", "capsule_inertia", "disk_inertia", "radius_of_gyration"]


def disk_inertia(mass, radius):
    """Uniform disk about its centre: ``m R^2 / 2`` (kg m^2)."""
    return 0.5 * mass * radius**2


def capsule_area(length, radius):
    """Area of a capsule: rectangle ``length x 2 radius`` plus a disk of ``radius`` (m^2)."""
    return 2.0 * radius * length + np.pi * radius**2


def capsule_inertia(mass, length, radius):
    """Uniform capsule (segment ``length``, end-cap ``radius``) about its centre (kg m^2).

    The rectangle contributes ``m_r (L^2 + 4 rho^2) / 12``; the two half-disks, each with its
    centroid ``a = 4 rho / (3 pi)`` beyond the segment end, contribute
    ``m_c (rho^2 / 2 + L^2 / 4 + L a)`` by the parallel-axis theorem (``m_c`` their joint mass).
    With ``radius = 0`` this is the thin rod's ``m L^2 / 12`` (the seed's ``m r^2 / 3``, r = L/2).

    Note: the seed note writes ``I1 = m1 (r^2 - (d/2)^2) / 3`` for a rod of thickness d; the minus
    sign is a slip (thickness adds inertia), so it is not used here.
    """
    # the rectangle's share of the area, 2 rho L / (2 rho L + pi rho^2), with rho cancelled so a
    # zero-thickness rod (rho = 0) is the thin rod, not 0/0
    m_rect = mass * (2.0 * length) / (2.0 * length + np.pi * radius)
    m_caps = mass - m_rect
    a = 4.0 * radius / (3.0 * np.pi)
    return m_rect * (length**2 + 4.0 * radius**2) / 12.0 + m_caps * (
        0.5 * radius**2 + 0.25 * length**2 + length * a
    )


def radius_of_gyration(mass, inertia):
    """``k = sqrt(I / m)`` (m): the lever arm of the table-friction torque (see ``effects``)."""
    return np.sqrt(inertia / mass)
