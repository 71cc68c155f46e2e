"""Scene builders shared by the physics tests."""

from __future__ import annotations

import numpy as np


def seed_strike(theta: float, m1: float, m2: float, r: float = 0.2, V: float = 1.0,
                gap: float = 0.05, thickness: float = 1e-3, radius: float = 0.005,
                e: float = 1.0) -> dict:
    """Seed §1: a thin rod (I = m r^2/3) slides at V along +x into a small resting disk.

    The rod's axis is ``u = (sin theta, cos theta)``, so the lever arm of an impulse along x at
    its upper tip is ``r cos theta``; the disk's centre lies on the velocity line through the
    centre of that tip's end cap, ``gap`` ahead of contact.
    """
    angle = np.pi / 2 - theta
    tip = np.array([r * np.cos(angle), r * np.sin(angle)])
    disk_x = tip[0] + thickness / 2 + radius + gap
    return {
        "effects": ["rotation"],
        "materials": {"restitution": e},
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 2 * r, "thickness": thickness, "mass": m1,
             "inertia": "thin_rod", "angle": float(angle), "velocity": [V, 0.0]},
            {"name": "disk", "shape": "disk", "radius": radius, "mass": m2,
             "position": [float(disk_x), float(tip[1])]},
        ],
    }
