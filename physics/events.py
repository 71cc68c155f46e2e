"""Time of impact: conservative advancement, then bracketing (docs/design.md §4).

For one pair over ``[0, horizon]`` (times relative to the current state):

1. *Conservative advancement.* At time t take the gap g and normal n; advance by the longest time
   over which the pair provably closes by less than ``g - tol/2`` (``motion.ca_step``). The gap
   never drops below ``tol/2`` this way, so nothing is ever missed, at any speed.
2. *Bracketing.* A pair within ``tol`` (approaching or not: just after an impact, sliding past,
   or about to touch) may advance by ``g + tol/2``; if the gap then falls below zero, the entry is
   bracketed and located by the Illinois method to ``0 <= g <= tol`` while approaching. A pair is
   in contact there, or at once if it is already touching (``g <= 0``) and approaching. A flat
   pair (a rod parallel to a rod or a cushion, resolved at its two ends) is approaching when
   either end is (:func:`flat_approach`), not only when its middle is.

Contact is where the gap *reaches zero* (located to ``tol``), not where it first comes within
``tol``: a pass that misses by less than ``tol``, or grazes at exactly zero gap with the velocity
along the surface, gets no impulse. (Declaring contact at ``g <= tol`` instead deflected an exact
tangential pass of two 5 cm disks by ~1e-4 of their speed, ``sqrt(2 tol / R)``.) The exception
is a pair of bodies whose radii sum to at most ``tol`` (two zero-thickness rods): their gap goes
below zero only where their cores cross (``contacts.capsule_capsule`` gives crossed cores a
negative gap, their depth), so they are in contact at ``g <= tol`` while approaching, before the
cores meet; a step that would cross them anyway (within ``tol`` and not yet approaching, the
advancement may close by ``g + tol/2``) is bracketed like any other overlap.

The first-order bound takes a rod's spin as a closing speed ``h |w|`` (its end's speed). A pair
touching, or just apart, beside a fast-turning rod and leaving it slowly (a striker a rod at
10 rad/s leaves at 5e-5 m/s after a plastic impact) then gets steps of ``gap / (h |w|)``, ~1e-9 s,
and stalls. A search still going after ``max_iterations`` steps therefore goes on for up to
``max_iterations`` more with a *curved* bound as well (:func:`curved_step`, the longer step of
the two): each core end's distance from the other body's core, taken in that body's turning
frame, where the distance from its fixed core is convex, is at least ``d0 + vn t - A t^2 / 2``,
``vn`` the normal relative velocity and ``A`` bounding the relative acceleration there
(``w^2`` and Coriolis terms, applied forces, cloth friction). It keeps the same promise (the gap
stays above ``g - delta``), and a search that ends within ``max_iterations`` steps never uses
it, so it is unchanged bit for bit. A search that needs more than that returns a *checkpoint*: a
time before which the pair provably does not touch. The world advances to it and searches
again, so a slow grazing approach costs events, never correctness.
"""

from __future__ import annotations

import math

from spinstrike.physics.contacts import (
    capsule_capsule,
    capsule_wall,
    flat_points,
    wall_frame,
)
from spinstrike.physics.impulse import ROUNDOFF, relative_velocity_of
from spinstrike.physics.jit import jit, jit_counted, jit_inline, static_if
from spinstrike.physics.layout import (
    ANGLE,
    CHECKPOINT,
    CONTACT,
    FRICTION_DECEL,
    FX,
    FY,
    HALF_LENGTH,
    INV_MASS,
    NONE,
    OMEGA,
    RADIUS,
    SPIN_DECEL,
    VX,
    VY,
    X,
    Y,
)
from spinstrike.physics.motion import ca_step, flight

__all__ = ["ROUNDOFF", "far_apart", "flat_approach", "geometry", "pair_bodies", "pair_geometry",
           "time_of_impact"]


_BRACKET_ITERATIONS = 200


@jit
def geometry(xa, ya, anga, vxa, vya, wa, ha, ra, xb, yb, angb, vxb, vyb, wb, hb, rb, wall,
             half_w, half_h, pinned_a=False, pinned_b=False):
    """Geometry and normal relative velocity of a pair given both bodies' poses and velocities.

    ``wall`` is -1 for a body-body pair, else the cushion index (body b's values are unused).
    ``pinned_a``: body a cannot translate (``capsule_wall``'s ``pinned``).

    Returns:
        (gap, nx, ny, oax, oay, ka, obx, oby, kb, vn): normal from a to b, lever arms as core
        offsets and distances along n (see ``impulse``), and ``(v_bp - v_ap) . n``, set to 0
        when it is below round-off (``ROUNDOFF`` times the point speeds): a pair is approaching
        only when ``vn < 0``.
    """
    # lever arms reach the contact point midway between the two chosen surface points, the same
    # point for both bodies (for a flat contact it is not the gap's nearer end)
    if wall < 0:
        g, nx, ny, oax, oay, obx, oby, sep = capsule_capsule(xa, ya, anga, ha, ra,
                                                             xb, yb, angb, hb, rb,
                                                             pinned_a and pinned_b)
        kb = rb + 0.5 * sep
    else:
        g, nx, ny, oax, oay, obx, oby, sep = capsule_wall(xa, ya, anga, ha, ra, wall, half_w,
                                                          half_h, pinned_a)
        kb = 0.0
    ka = ra + 0.5 * sep
    vn, vt, scale = relative_velocity_of(vxa, vya, wa, vxb, vyb, wb, wall >= 0, nx, ny, oax, oay,
                                         ka, obx, oby, kb)
    if abs(vn) <= ROUNDOFF * scale:
        vn = 0.0  # at rest along n to round-off (e.g. just after a plastic impact)
    return g, nx, ny, oax, oay, ka, obx, oby, kb, vn


@jit_inline
def pair_bodies(p, PA, PB, n):
    """Bodies of contact pair p in an element of n bodies: ``(a, b, wall)`` with ``wall`` the
    cushion index (``b`` is then ``a``, a stand-in the kernels ignore) or -1 for two bodies."""
    a = PA[p]
    b = PB[p]
    if b >= n:
        return a, a, b - n
    return a, b, -1


@jit_inline
def pair_geometry(S, Pm, a, b, wall, half_w, half_h):
    """:func:`geometry` of bodies ``a`` and ``b`` (``b`` unused for a cushion) at the current
    state ``S`` of an element with parameters ``Pm``."""
    return geometry(S[a, X], S[a, Y], S[a, ANGLE], S[a, VX], S[a, VY], S[a, OMEGA],
                    Pm[a, HALF_LENGTH], Pm[a, RADIUS],
                    S[b, X], S[b, Y], S[b, ANGLE], S[b, VX], S[b, VY], S[b, OMEGA],
                    Pm[b, HALF_LENGTH], Pm[b, RADIUS], wall, half_w, half_h,
                    Pm[a, INV_MASS] == 0.0, Pm[b, INV_MASS] == 0.0)


@jit
def flat_approach(xa, ya, anga, vxa, vya, wa, ha, ra, xb, yb, angb, vxb, vyb, wb, hb, rb, wall,
                  half_w, half_h, pinned_a, pinned_b, nx, ny, vn):
    """The normal velocity by which a pair counts as approaching: :func:`geometry`'s ``vn``
    (its contact point's), except for a flat pair that the solvers resolve at its two ends
    (``contacts.flat_ends``, ``contacts.flat_wall_ends``: not both bodies pinned, a pinned
    body not on a cushion), where it is the more approaching end's, each 0 below round-off.

    A flat pair's contact point is the middle of the overlap; a pair lying flat and turning has
    its middle at rest along n while one end goes in, and the contact, which the solvers
    resolve as soon as an end approaches, went unseen by the time of impact until the tilt left
    the flat band (a 1 m rod flat on a cushion at 1 rad/s: 5e-4 m deep at a 1 ms step's end,
    settled).
    """
    flat, o1ax, o1ay, o1bx, o1by, _, o2ax, o2ay, o2bx, o2by, _ = flat_points(
        xa, ya, anga, ha, ra, pinned_a, xb, yb, angb, hb, rb, pinned_b, wall, half_w, half_h,
        nx, ny)
    if not flat:
        return vn
    v1, _, s1 = relative_velocity_of(vxa, vya, wa, vxb, vyb, wb, wall >= 0, nx, ny, o1ax, o1ay,
                                     0.0, o1bx, o1by, 0.0)
    v2, _, s2 = relative_velocity_of(vxa, vya, wa, vxb, vyb, wb, wall >= 0, nx, ny, o2ax, o2ay,
                                     0.0, o2bx, o2by, 0.0)
    if abs(v1) <= ROUNDOFF * s1:
        v1 = 0.0
    if abs(v2) <= ROUNDOFF * s2:
        v2 = 0.0
    return min(v1, v2)


@jit_inline
def _mid_approach(xa, ya, anga, vxa, vya, wa, ha, ra, xb, yb, angb, vxb, vyb, wb, hb, rb, wall,
                  half_w, half_h, pinned_a, pinned_b, nx, ny, vn):
    """What :func:`flat_approach` returns for a pair that is never resolved flat: ``vn``."""
    return vn


#: :func:`flat_approach` where the world has a pair that can lie flat (the ``flat`` flag,
#: ``kernels.FLAGS``), else :func:`geometry`'s ``vn`` with no flat code compiled
_approach_if = static_if(flat_approach, otherwise=_mid_approach)


@jit_inline
def _probe(S, Pm, F, a, b, wall, half_w, half_h, t, rotation, flat, table_friction, tol):
    """Flight of both bodies to time t, then their geometry; also the flown velocities and
    spins, for the advancement bound: (geometry..., vxa, vya, wa, vxb, vyb, wb).

    At t = 0 the state is read as it is: the closed-form flight by 0 returns it bit for bit.
    Within ``tol``, where it decides contact, ``vn`` is :func:`flat_approach`'s.
    """
    if t == 0.0:
        xa, ya, anga, vxa, vya, wa = S[a, X], S[a, Y], S[a, ANGLE], S[a, VX], S[a, VY], S[a, OMEGA]
        xb, yb, angb, vxb, vyb, wb = S[b, X], S[b, Y], S[b, ANGLE], S[b, VX], S[b, VY], S[b, OMEGA]
    else:
        xa, ya, anga, vxa, vya, wa = flight(S, Pm, F, a, t, rotation, table_friction)
        if wall < 0:
            xb, yb, angb, vxb, vyb, wb = flight(S, Pm, F, b, t, rotation, table_friction)
        else:
            xb, yb, angb, vxb, vyb, wb = xa, ya, anga, vxa, vya, wa
    pinned_a = Pm[a, INV_MASS] == 0.0
    pinned_b = Pm[b, INV_MASS] == 0.0
    g, nx, ny, oax, oay, ka, obx, oby, kb, vn = geometry(
        xa, ya, anga, vxa, vya, wa, Pm[a, HALF_LENGTH], Pm[a, RADIUS],
        xb, yb, angb, vxb, vyb, wb, Pm[b, HALF_LENGTH], Pm[b, RADIUS], wall, half_w, half_h,
        pinned_a, pinned_b)
    if g <= tol:
        vn = _approach_if(flat, xa, ya, anga, vxa, vya, wa, Pm[a, HALF_LENGTH], Pm[a, RADIUS],
                          xb, yb, angb, vxb, vyb, wb, Pm[b, HALF_LENGTH], Pm[b, RADIUS], wall,
                          half_w, half_h, pinned_a, pinned_b, nx, ny, vn)
    return g, nx, ny, vn, vxa, vya, wa, vxb, vyb, wb


@jit_inline
def _step_bound(delta, nx, ny, S, Pm, F, a, b, wall, vxa, vya, wa, vxb, vyb, wb, rotation,
                table_friction):
    ima = Pm[a, INV_MASS]
    slide_a = table_friction and Pm[a, FRICTION_DECEL] > 0.0
    spin_a = Pm[a, HALF_LENGTH] * abs(wa) if rotation else 0.0
    if wall >= 0:
        # the cushion does not slide: wall < 0, False here, as a run-time bool (a literal False
        # compiled ca_step and its callees a second time)
        return ca_step(delta, nx, ny, vxa, vya, F[a, FX] * ima, F[a, FY] * ima, slide_a, spin_a,
                       0.0, 0.0, 0.0, 0.0, wall < 0, 0.0)
    imb = Pm[b, INV_MASS]
    slide_b = table_friction and Pm[b, FRICTION_DECEL] > 0.0
    spin_b = Pm[b, HALF_LENGTH] * abs(wb) if rotation else 0.0
    return ca_step(delta, nx, ny, vxa, vya, F[a, FX] * ima, F[a, FY] * ima, slide_a, spin_a,
                   vxb, vyb, F[b, FX] * imb, F[b, FY] * imb, slide_b, spin_b)


#: round-off allowance of the curved bound's distances, relative to the lengths involved
_CURVED_ROUNDOFF = 1e-14


@jit
def _root(c, vn, acc):
    """Longest s with ``c + vn t - acc t^2 / 2 > 0`` on all of [0, s] (``c > 0``, ``acc >= 0``):
    the positive root, in the form that does not cancel."""
    if acc <= 0.0:
        return c / -vn if vn < 0.0 else math.inf
    disc = math.sqrt(vn * vn + 2.0 * acc * c)
    if vn > 0.0:
        return (vn + disc) / acc
    return 2.0 * c / (disc - vn)


@jit
def _point_segment_step(px, py, pvx, pvy, pacc, fx, fy, fang, fvx, fvy, fw, facc, fwdot, h,
                        low, span):
    """Curved bound for a point moving relative to a body's core segment (``2h`` long along the
    body's axis): the longest time, at most ``span``, over which the point's distance from the
    segment provably stays above ``low``; 0 when the point is not farther than ``low``.

    In the body's own (turning) frame the segment is fixed, and the distance from a fixed convex
    set is a convex function of the point ``q``: ``d(q) >= d(q0) + n . (q - q0)`` with ``n`` the
    unit normal at ``q0``. With ``r`` the point's offset from the body's centre in the table's
    frame, ``q = R(-angle) r`` and ``q'' = R(-angle) (r'' - w' J r - 2 w J r' - w^2 r)``, so
    ``d(t) >= d0 + vn t - A t^2 / 2`` with ``vn = n . q'(0)`` (the normal relative velocity: the
    body's own spin is no closing speed in its frame) and ``A`` bounding ``|q''|`` over the span
    from ``|r''| <= pacc + facc``, ``|w| <= |fw|`` (cloth friction only slows a spin) and
    ``|w'| <= fwdot``.
    """
    ux = math.cos(fang)
    uy = math.sin(fang)
    rx = px - fx
    ry = py - fy
    qx = rx * ux + ry * uy
    qy = ry * ux - rx * uy
    sx = min(max(qx, -h), h)
    dx = qx - sx
    d = math.sqrt(dx * dx + qy * qy)
    r = math.sqrt(rx * rx + ry * ry)
    c = d - low - _CURVED_ROUNDOFF * (r + h)
    if not c > 0.0:
        return 0.0
    wvx = pvx - fvx
    wvy = pvy - fvy
    v = math.sqrt(wvx * wvx + wvy * wvy)
    vn = (dx * (wvx * ux + wvy * uy + fw * qy) + qy * (wvy * ux - wvx * uy - fw * qx)) / d
    ar = pacc + facc
    speed = v + ar * span  # |r'| over the span
    reach = r + (v + 0.5 * ar * span) * span  # |r| over the span
    acc = ar + (fwdot + fw * fw) * reach + 2.0 * abs(fw) * speed
    return min(_root(c, vn, acc), span)


@jit
def _body_motion(S, Pm, F, i, t, rotation, table_friction):
    """Body i flown to t, with bounds on its centre's acceleration and its spin's rate of change
    from then on: (x, y, angle, vx, vy, w, acc, wdot)."""
    if t == 0.0:
        x, y, ang, vx, vy, w = S[i, X], S[i, Y], S[i, ANGLE], S[i, VX], S[i, VY], S[i, OMEGA]
    else:
        x, y, ang, vx, vy, w = flight(S, Pm, F, i, t, rotation, table_friction)
    acc = math.sqrt(F[i, FX] ** 2 + F[i, FY] ** 2) * Pm[i, INV_MASS]
    wdot = 0.0
    if table_friction:
        acc += Pm[i, FRICTION_DECEL]
        if rotation:
            wdot = Pm[i, SPIN_DECEL]
    if not rotation:
        w = 0.0
    return x, y, ang, vx, vy, w, acc, wdot


@jit
def _ends_step(x, y, ang, vx, vy, w, acc, wdot, h, fx, fy, fang, fvx, fvy, fw, facc, fwdot,
               fh, low, span):
    """:func:`_point_segment_step` for each end of a core (one point if ``h`` is 0) against
    another body's core: the shorter of the two."""
    ux = math.cos(ang)
    uy = math.sin(ang)
    pacc = acc + h * (w * w + wdot)  # an end's acceleration
    s = _point_segment_step(x + h * ux, y + h * uy, vx - h * w * uy, vy + h * w * ux, pacc,
                            fx, fy, fang, fvx, fvy, fw, facc, fwdot, fh, low, span)
    if h > 0.0 and s > 0.0:
        s = min(s, _point_segment_step(x - h * ux, y - h * uy, vx + h * w * uy,
                                       vy - h * w * ux, pacc, fx, fy, fang, fvx, fvy, fw, facc,
                                       fwdot, fh, low, span))
    return s


@jit
def curved_step(S, Pm, F, a, b, wall, half_w, half_h, t, span, low, rotation, table_friction):
    """Longest time from ``t`` (at most ``span``) over which the pair's gap provably stays above
    ``low``, by a second-order bound that sees a body's spin only through its square and the
    relative motion (0 where it does not apply). It complements :func:`_step_bound`, whose
    ``h |w|`` closing speed is the speed of a rod's end: a pair touching and separating slowly
    beside a fast-turning rod gets steps of ``gap / (h |w|)`` there, and stalls.

    * Two bodies: the distance of two cores that do not cross is the least distance of an end
      of one from the other's core (crossing cores meet at an end first), each bounded in the
      other body's turning frame (:func:`_point_segment_step`); the gap is that less the radii.
      Cores that would come within ``low`` plus the radii (crossed, or zero-thickness rods near
      crossing) get 0.
    * A cushion: the gap is the nearer end's distance from it less the radius; each end's
      distance is linear in the end's position, whose acceleration is bounded by the centre's
      and ``h (w^2 + |w'|)``.
    """
    x, y, ang, vx, vy, w, acc, wdot = _body_motion(S, Pm, F, a, t, rotation, table_friction)
    ha = Pm[a, HALF_LENGTH]
    if wall >= 0:
        ix, iy, off = wall_frame(wall, half_w, half_h)
        ux = math.cos(ang)
        uy = math.sin(ang)
        pacc = acc + ha * (w * w + wdot)
        low_end = low + Pm[a, RADIUS] + _CURVED_ROUNDOFF * (abs(x) + abs(y) + ha + off)
        s = span
        for sign in (1.0, -1.0):
            c = ix * (x + sign * ha * ux) + iy * (y + sign * ha * uy) + off - low_end
            if not c > 0.0:
                return 0.0
            rate = ix * (vx - sign * ha * w * uy) + iy * (vy + sign * ha * w * ux)
            s = min(s, _root(c, rate, pacc))
        return s
    xb, yb, angb, vxb, vyb, wb, accb, wdotb = _body_motion(S, Pm, F, b, t, rotation,
                                                           table_friction)
    hb = Pm[b, HALF_LENGTH]
    low_core = low + Pm[a, RADIUS] + Pm[b, RADIUS]
    if not low_core > 0.0:
        return 0.0
    # a disk's centre against the other's core is their distance; a rod's ends against a disk's
    # centre add nothing (they are never nearer than the rod's core)
    s = span
    if hb == 0.0 or ha > 0.0:
        s = _ends_step(xb, yb, angb, vxb, vyb, wb, accb, wdotb, hb, x, y, ang, vx, vy, w, acc,
                       wdot, ha, low_core, span)
    if hb > 0.0 and s > 0.0:
        s = min(s, _ends_step(x, y, ang, vx, vy, w, acc, wdot, ha, xb, yb, angb, vxb, vyb, wb,
                              accb, wdotb, hb, low_core, span))
    return s


@jit_inline
def far_apart(S, Pm, F, a, b, wall, half_w, half_h, horizon, tol, rotation):
    """A cheap test that the pair cannot close within ``horizon``, which implies that the
    search's first iteration finds exactly that (so it may be skipped, bit for bit).

    ``lower``, the centres' distance less the bodies' reaches, is at most the gap, and
    ``P = |v_a| + h_a |w_a| (+ the same for b)``, ``Q = |a_a| (+ |a_b|)`` bound the closing
    speed and acceleration along any normal from above; with a margin of 2 the first
    conservative-advancement step is then longer than the horizon whatever the normal, and
    ``motion.ca_step``'s rounding cannot bring it back under.
    """
    ra = Pm[a, HALF_LENGTH] + Pm[a, RADIUS]
    if wall >= 0:
        ix, iy, off = wall_frame(wall, half_w, half_h)
        lower = ix * S[a, X] + iy * S[a, Y] + off - ra
    else:
        dx = S[b, X] - S[a, X]
        dy = S[b, Y] - S[a, Y]
        lower = math.sqrt(dx * dx + dy * dy) - ra - (Pm[b, HALF_LENGTH] + Pm[b, RADIUS])
    if not lower > tol:
        return False
    p = math.sqrt(S[a, VX] ** 2 + S[a, VY] ** 2)
    q = math.sqrt(F[a, FX] ** 2 + F[a, FY] ** 2) * Pm[a, INV_MASS]
    if rotation:
        p += Pm[a, HALF_LENGTH] * abs(S[a, OMEGA])
    if wall < 0:
        p += math.sqrt(S[b, VX] ** 2 + S[b, VY] ** 2)
        q += math.sqrt(F[b, FX] ** 2 + F[b, FY] ** 2) * Pm[b, INV_MASS]
        if rotation:
            p += Pm[b, HALF_LENGTH] * abs(S[b, OMEGA])
    return (p + 0.5 * q * horizon) * horizon < 0.5 * (lower - 0.5 * tol)


@jit_counted
def time_of_impact(S, Pm, F, a, b, wall, half_w, half_h, horizon, tol, max_iterations, rotation,
                   flat, table_friction):
    """First time in ``[0, horizon]`` at which the pair touches while approaching: its gap
    reaches zero, the time located to a gap in ``[0, tol]`` (or ``g <= 0`` already).

    Callers first try :func:`far_apart`, which settles most pairs without this call.

    Args:
        S, Pm, F: the element's state, parameters and applied forces.
        a, b: the bodies (``b`` unused for a cushion); wall: -1 for two bodies, else the
            cushion index of b.
        horizon: end of the search window, s.
        tol: contact gap tolerance, m.

    Returns:
        (t, kind, iterations) with kind ``CONTACT``, ``NONE`` (t = horizon) or ``CHECKPOINT``.
    """
    # Two bodies whose radii sum to at most tol (zero-thickness rods) overlap only where their
    # cores cross: contact is at ``g <= tol`` while approaching, before the cores meet.
    thin = wall < 0 and Pm[a, RADIUS] + Pm[b, RADIUS] <= tol
    t = 0.0
    for it in range(2 * max_iterations):
        g, nx, ny, vn, vxa, vya, wa, vxb, vyb, wb = _probe(S, Pm, F, a, b, wall, half_w, half_h,
                                                           t, rotation, flat, table_friction, tol)
        if g <= tol:
            if vn < 0.0 and (g <= 0.0 or thin):
                return t, CONTACT, it + 1
            floor = min(g, 0.0)
            delta = g - floor + 0.5 * tol
        else:
            floor = 0.0
            delta = g - 0.5 * tol
        s = _step_bound(delta, nx, ny, S, Pm, F, a, b, wall, vxa, vya, wa, vxb, vyb, wb,
                        rotation, table_friction)
        if (it >= max_iterations or (g <= tol and not vn < 0.0)) and s < horizon - t:
            # stalled, or touching and not approaching (where a plastic impact leaves its pair:
            # separating at second order, it stalled the first-order bound, 272-682 iterations
            # and 2-4 events at tolerance 1e-9 m, a settled step at 1e-10): the curved bound as
            # well. Other searches never get here, so they are what they were bit for bit.
            s = max(s, curved_step(S, Pm, F, a, b, wall, half_w, half_h, t, horizon - t,
                                   g - delta, rotation, table_friction))
        t_new = t + s if t + s < horizon else horizon
        if g <= tol:
            g_new = _probe(S, Pm, F, a, b, wall, half_w, half_h, t_new, rotation, flat,
                           table_friction, tol)[0]
            if g_new < floor:
                tc, kind, k = _bracket(S, Pm, F, a, b, wall, half_w, half_h, t, g - floor,
                                       t_new, g_new - floor, floor, tol, rotation, flat,
                                       table_friction)
                return tc, kind, it + 1 + k
        if t_new >= horizon:
            return horizon, NONE, it + 1
        if t_new == t:
            return t, CHECKPOINT, it + 1
        t = t_new
    return t, CHECKPOINT, 2 * max_iterations


@jit_counted
def _bracket(S, Pm, F, a, b, wall, half_w, half_h, lo, f_lo, hi, f_hi, floor, tol, rotation, flat,
             table_friction):
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
        g, _, _, vn, _, _, _, _, _, _ = _probe(S, Pm, F, a, b, wall, half_w, half_h, tm, rotation,
                                               flat, table_friction, tol)
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
