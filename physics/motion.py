"""Free flight in closed form, and the conservative-advancement bound built on it.

Between contacts each body moves in closed form (docs/design.md §4):

* a free body without table friction: straight line at constant velocity;
* a driven body under a constant applied force F: parabola ``x + v t + F t^2 / (2 m)``
  (driven bodies are exempt from table friction: their force is the net force);
* a free body with ``table_friction``: decelerates at ``mu_t g`` along its (unchanging) direction
  until it stops: piecewise quadratic; its spin decelerates at ``mu_t g / k`` until it stops;
* static bodies do not move; a pivot only turns.

The conservative-advancement step (``ca_step``) bounds how fast the gap of a pair can close along
the current contact normal n: the bodies' projections on n form a separating plane; while every
point of body a moves less than ``delta_a`` along n and every point of b less than ``delta_b``
along -n, with ``delta_a + delta_b < gap``, they cannot touch. A body's translation projects
exactly (or, under friction, to at most ``max(v.n, 0) t``), and rotation moves a point of the core
segment at most ``h |omega| t``.
"""

from __future__ import annotations

import math

from spinstrike.physics.jit import jit, jit_inline
from spinstrike.physics.layout import (
    ANGLE,
    FRICTION_DECEL,
    FX,
    FY,
    INV_MASS,
    OMEGA,
    SPIN_DECEL,
    VX,
    VY,
    X,
    Y,
)

__all__ = ["ca_step", "flight", "slide", "spin_down"]



@jit
def slide(x, y, vx, vy, decel, t):
    """Coulomb sliding on the cloth: deceleration ``decel`` along the velocity until rest."""
    speed = math.sqrt(vx * vx + vy * vy)
    if speed == 0.0:
        return x, y, 0.0, 0.0
    t_stop = speed / decel
    if t >= t_stop:
        d = 0.5 * speed * t_stop
        return x + vx / speed * d, y + vy / speed * d, 0.0, 0.0
    d = speed * t - 0.5 * decel * t * t
    f = (speed - decel * t) / speed
    return x + vx / speed * d, y + vy / speed * d, vx * f, vy * f


@jit
def spin_down(angle, omega, decel, t):
    """Spin slowed by the cloth's torque: angular deceleration ``decel`` until it stops."""
    if omega == 0.0:
        return angle, 0.0
    w = abs(omega)
    sign = 1.0 if omega > 0.0 else -1.0
    t_stop = w / decel
    if t >= t_stop:
        return angle + sign * 0.5 * w * t_stop, 0.0
    return angle + sign * (w * t - 0.5 * decel * t * t), sign * (w - decel * t)


@jit_inline
def flight(S, Pm, F, i, t, rotation, table_friction):
    """Pose and velocity of body ``i`` ``t`` seconds ahead.

    Args:
        S, Pm, F: the element's state ``[N, 6]``, parameters ``[N, 6]`` and applied forces
            ``[N, 2]`` (see ``physics.layout``); rows are read by index, never sliced (a row view
            costs reference-count traffic in every call).
        i: the body.  t: time ahead, s (>= 0).

    Returns:
        (x, y, angle, vx, vy, omega)
    """
    x = S[i, X]
    y = S[i, Y]
    vx = S[i, VX]
    vy = S[i, VY]
    angle = S[i, ANGLE]
    omega = S[i, OMEGA]
    ima = Pm[i, INV_MASS]
    ax = F[i, FX] * ima
    ay = F[i, FY] * ima
    if table_friction and Pm[i, FRICTION_DECEL] > 0.0:
        x, y, vx, vy = slide(x, y, vx, vy, Pm[i, FRICTION_DECEL], t)
    else:
        x += (vx + 0.5 * ax * t) * t
        y += (vy + 0.5 * ay * t) * t
        vx += ax * t
        vy += ay * t
    if rotation and omega != 0.0:
        if table_friction and Pm[i, SPIN_DECEL] > 0.0:
            angle, omega = spin_down(angle, omega, Pm[i, SPIN_DECEL], t)
        else:
            angle += omega * t
    return x, y, angle, vx, vy, omega


@jit
def _closing(nx, ny, vx, vy, ax, ay, sliding):
    """Linear and quadratic coefficients of a body's displacement along n."""
    p = nx * vx + ny * vy
    if sliding:
        return max(p, 0.0), 0.0
    return p, nx * ax + ny * ay


@jit
def ca_step(delta, nx, ny, vxa, vya, axa, aya, slide_a, spin_a, vxb, vyb, axb, ayb, slide_b,
            spin_b):
    """Longest time over which the pair provably closes by less than ``delta`` along n.

    ``spin_*`` is the bound ``h |omega|`` on the speed of the core's points due to rotation;
    ``slide_*`` says the body decelerates on the cloth. Returns ``inf`` when the bound never
    reaches ``delta`` (e.g. the pair separates along n and does not turn).
    """
    pa, qa = _closing(nx, ny, vxa, vya, axa, aya, slide_a)
    pb, qb = _closing(-nx, -ny, vxb, vyb, axb, ayb, slide_b)
    p = pa + pb + spin_a + spin_b
    q = qa + qb
    if q == 0.0:
        return delta / p if p > 0.0 else math.inf
    disc = p * p + 2.0 * q * delta
    if disc < 0.0:
        return math.inf
    den = p + math.sqrt(disc)
    if den <= 0.0:
        return math.inf
    return 2.0 * delta / den
