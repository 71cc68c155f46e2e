"""Time of impact: conservative advancement, then bracketing (DESIGN §5).

For one pair over ``[0, horizon]`` (times relative to the current state):

1. *Conservative advancement.* At time t take the gap g and normal n; advance by the longest time
   over which the pair provably closes by less than ``g - tol/2`` (``motion.ca_step``). The gap
   never drops below ``tol/2`` this way, so nothing is ever missed, at any speed.
2. *Bracketing.* A pair within ``tol`` (approaching or not: just after an impact, sliding past,
   or about to touch) may advance by ``g + tol/2``; if the gap then falls below zero, the entry is
   bracketed and located by the Illinois method to ``0 <= g <= tol`` while approaching. A pair is
   in contact there, or at once if it is already touching (``g <= 0``) and approaching.

Contact is where the gap *reaches zero* (located to ``tol``), not where it first comes within
``tol``: a pass that misses by less than ``tol``, or grazes at exactly zero gap with the velocity
along the surface, gets no impulse. (Declaring contact at ``g <= tol`` instead deflected an exact
tangential pass of two 5 cm disks by ~1e-4 of their speed, ``sqrt(2 tol / R)``.) The exception
is a pair of bodies whose radii sum to at most ``tol`` (two zero-thickness rods): their gap never
goes measurably below zero, so they are in contact at ``g <= tol`` while approaching.

A search that needs more than ``max_iterations`` steps returns a *checkpoint*: a time before
which the pair provably does not touch. The world advances to it and searches again, so a slow
grazing approach costs events, never correctness.
"""

from __future__ import annotations

import numba

from physics.contacts import capsule_capsule, capsule_wall
from physics.impulse import relative_velocity
from physics.layout import (
    CHECKPOINT,
    CONTACT,
    FRICTION_DECEL,
    HALF_LENGTH,
    INV_MASS,
    NONE,
    RADIUS,
)
from physics.motion import ca_step, flight

__all__ = ["ROUNDOFF", "pair_geometry", "time_of_impact"]

jit = numba.njit(cache=True, nogil=True)

_BRACKET_ITERATIONS = 200
#: relative size of round-off in a normal velocity: |vn| below this times the speeds counts as 0
ROUNDOFF = 1e-12


@jit
def pair_geometry(sa, pa, sb, pb, wall, half_w, half_h):
    """Geometry and normal relative velocity of a pair at the current state.

    ``wall`` is -1 for a body-body pair, else the cushion index (``sb``/``pb`` are then unused).

    Returns:
        (gap, nx, ny, oax, oay, ka, obx, oby, kb, vn): normal from a to b, lever arms as core
        offsets and distances along n (see ``impulse``), and ``(v_bp - v_ap) . n``, set to 0
        when it is below round-off (``ROUNDOFF`` times the point speeds): a pair is approaching
        only when ``vn < 0``.
    """
    if wall < 0:
        g, nx, ny, oax, oay, obx, oby = capsule_capsule(
            sa[0], sa[1], sa[2], pa[HALF_LENGTH], pa[RADIUS],
            sb[0], sb[1], sb[2], pb[HALF_LENGTH], pb[RADIUS])
        kb = pb[RADIUS] + 0.5 * g
    else:
        g, nx, ny, oax, oay, obx, oby = capsule_wall(sa[0], sa[1], sa[2], pa[HALF_LENGTH],
                                                     pa[RADIUS], wall, half_w, half_h)
        kb = 0.0
    ka = pa[RADIUS] + 0.5 * g
    vn, vt, scale = relative_velocity(sa, sb, wall >= 0, nx, ny, oax, oay, ka, obx, oby, kb)
    if abs(vn) <= ROUNDOFF * scale:
        vn = 0.0  # at rest along n to round-off (e.g. just after a plastic impact)
    return g, nx, ny, oax, oay, ka, obx, oby, kb, vn


@jit
def _probe(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, t, tmp_a, tmp_b, rotation,
           table_friction):
    """Flight of both bodies to time t (into the scratch rows), then their geometry."""
    ima = pa[INV_MASS]
    x, y, an, vx, vy, w = flight(sa, pa, fa[0] * ima, fa[1] * ima, t, rotation, table_friction)
    tmp_a[0] = x
    tmp_a[1] = y
    tmp_a[2] = an
    tmp_a[3] = vx
    tmp_a[4] = vy
    tmp_a[5] = w
    if wall < 0:
        imb = pb[INV_MASS]
        x, y, an, vx, vy, w = flight(sb, pb, fb[0] * imb, fb[1] * imb, t, rotation, table_friction)
        tmp_b[0] = x
        tmp_b[1] = y
        tmp_b[2] = an
        tmp_b[3] = vx
        tmp_b[4] = vy
        tmp_b[5] = w
    return pair_geometry(tmp_a, pa, tmp_b, pb, wall, half_w, half_h)


@jit
def _step_bound(delta, nx, ny, ta, pa, fa, tb, pb, fb, wall, rotation, table_friction):
    ima = pa[INV_MASS]
    slide_a = table_friction and pa[FRICTION_DECEL] > 0.0
    spin_a = pa[HALF_LENGTH] * abs(ta[5]) if rotation else 0.0
    if wall >= 0:
        return ca_step(delta, nx, ny, ta[3], ta[4], fa[0] * ima, fa[1] * ima, slide_a, spin_a,
                       0.0, 0.0, 0.0, 0.0, False, 0.0)
    imb = pb[INV_MASS]
    slide_b = table_friction and pb[FRICTION_DECEL] > 0.0
    spin_b = pb[HALF_LENGTH] * abs(tb[5]) if rotation else 0.0
    return ca_step(delta, nx, ny, ta[3], ta[4], fa[0] * ima, fa[1] * ima, slide_a, spin_a,
                   tb[3], tb[4], fb[0] * imb, fb[1] * imb, slide_b, spin_b)


@jit
def time_of_impact(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, horizon, tol, max_iterations,
                   tmp_a, tmp_b, rotation, table_friction):
    """First time in ``[0, horizon]`` at which the pair touches while approaching: its gap
    reaches zero, the time located to a gap in ``[0, tol]`` (or ``g <= 0`` already).

    Args:
        sa, pa, fa: state row, parameter row and applied force of body a (b likewise).
        wall: -1 for two bodies, else the cushion index of b.
        horizon: end of the search window, s.
        tol: contact gap tolerance, m.
        tmp_a, tmp_b: scratch rows of 6 floats.

    Returns:
        (t, kind, iterations) with kind ``CONTACT``, ``NONE`` (t = horizon) or ``CHECKPOINT``.
    """
    # Two bodies whose radii sum to at most tol (zero-thickness rods) cannot overlap by more
    # than that: their gap is a distance between segments, >= -(ra + rb), and a crossing would
    # not show as a negative gap. For them contact stays at ``g <= tol`` while approaching.
    thin = wall < 0 and pa[RADIUS] + pb[RADIUS] <= tol
    t = 0.0
    for it in range(max_iterations):
        g, nx, ny, _, _, _, _, _, _, vn = _probe(sa, pa, fa, sb, pb, fb, wall, half_w, half_h,
                                                 t, tmp_a, tmp_b, rotation, table_friction)
        if g <= tol:
            if vn < 0.0 and (g <= 0.0 or thin):
                return t, CONTACT, it + 1
            floor = min(g, 0.0)
            delta = g - floor + 0.5 * tol
        else:
            floor = 0.0
            delta = g - 0.5 * tol
        s = _step_bound(delta, nx, ny, tmp_a, pa, fa, tmp_b, pb, fb, wall, rotation,
                        table_friction)
        t_new = t + s if t + s < horizon else horizon
        if g <= tol:
            g_new = _probe(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, t_new, tmp_a, tmp_b,
                           rotation, table_friction)[0]
            if g_new < floor:
                tc, kind, k = _bracket(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, t, g - floor,
                                       t_new, g_new - floor, floor, tol, tmp_a, tmp_b, rotation,
                                       table_friction)
                return tc, kind, it + 1 + k
        if t_new >= horizon:
            return horizon, NONE, it + 1
        if t_new == t:
            return t, CHECKPOINT, it + 1
        t = t_new
    return t, CHECKPOINT, max_iterations


@jit
def _bracket(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, lo, f_lo, hi, f_hi, floor, tol, tmp_a,
             tmp_b, rotation, table_friction):
    """Illinois method on f = gap - floor, f(lo) >= 0 > f(hi), to 0 <= f <= tol approaching."""
    side = 0
    for k in range(_BRACKET_ITERATIONS):
        if f_lo != f_hi:
            tm = lo - f_lo * (hi - lo) / (f_hi - f_lo)
        else:
            tm = 0.5 * (lo + hi)
        if not (lo < tm < hi):
            tm = 0.5 * (lo + hi)
            if not (lo < tm < hi):
                break
        g, _, _, _, _, _, _, _, _, vn = _probe(sa, pa, fa, sb, pb, fb, wall, half_w, half_h, tm,
                                               tmp_a, tmp_b, rotation, table_friction)
        fm = g - floor
        if 0.0 <= fm <= tol and vn < 0.0:
            return tm, CONTACT, k + 1
        if fm >= 0.0:
            lo = tm
            f_lo = fm
            if side == 1:
                f_hi *= 0.5
            side = 1
        else:
            hi = tm
            f_hi = fm
            if side == -1:
                f_lo *= 0.5
            side = -1
    # the interval cannot shrink further: lo is a safe time (the pair does not overlap there)
    return lo, CHECKPOINT, _BRACKET_ITERATIONS

