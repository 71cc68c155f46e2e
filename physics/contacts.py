"""Contact geometry: closest points between capsules, and between a capsule and a cushion.

Every body is a capsule (a core segment swept by a disk of radius ``rho``; a disk has a segment of
length 0). The *gap* between two bodies is the distance between their core segments minus the two
radii; it is negative when they overlap. The contact normal is the unit vector from body a's
closest core point to body b's (from a to b, docs/design.md §2); where one of the points lies
inside its segment it is taken as that segment's perpendicular, well conditioned however close
the cores (``_normal``). The contact point lies midway between the two surfaces along it. Lever
arms are kept as (core offset, distance along n) so that ``r x n`` is exactly the core offset's,
i.e. exactly 0 for a disk.

Flat contacts: when two segments are parallel (sin^2 of the angle between them below
``PARALLEL``) and their projections overlap, or a rod lies parallel to a cushion, the contact point
is the middle of the overlap, so a flat impact gets one impulse through the middle, not one at an
arbitrary end; the gap stays the smallest distance (at an end), so it is continuous. Two flat rods
are resolved at both ends of their overlap instead (:func:`flat_ends`, ``impulse.resolve_flat``:
the end impacts a slightly tilted rod makes, in turn), so the outcome does not jump at the
threshold; all the callers share one parallel test (:func:`_parallel`). A free rod flat on a
cushion likewise, at its core's two ends (:func:`flat_wall_ends`, one test with
:func:`capsule_wall`'s: :func:`_flat_on_wall`).

Crossed cores: two rods whose core segments cross are at core distance 0, and the crossing gives
no normal. Their gap is instead minus their depth (the smallest translation that uncrosses them:
the least distance of an end of one from the other's line) less the radii, along that line's
normal (``_crossed``): a signed distance, continuous where the cores meet, so a crossing is never
read as touching (bare rods at a gap of 0) and the settle's impulses and positional correction
push the rods back apart.

All functions are numba kernels on scalars (no allocation).
"""

from __future__ import annotations

import math

from spinstrike.physics.jit import jit, jit_inline

__all__ = ["capsule_capsule", "capsule_wall", "closest_segment_params", "core_segment",
           "cores_cross", "flat_ends", "flat_points", "flat_wall_ends", "wall_frame"]

#: squared sine of the angle below which two segments count as parallel
PARALLEL = 1e-12
_TINY = 1e-300



@jit
def core_segment(x, y, angle, h):
    """End points of a body's core segment (a disk's two ends coincide at its centre)."""
    if h == 0.0:
        return x, y, x, y
    c = h * math.cos(angle)
    s = h * math.sin(angle)
    return x - c, y - s, x + c, y + s


@jit
def _parallel(ux, uy, vx, vy):
    """Whether two segments of directions u and v count as parallel: the same test, written the
    same way, as :func:`closest_segment_params`' (which then picks the middle of the overlap), so
    that every caller agrees on which pairs are flat, down to round-off at the threshold."""
    a = ux * ux + uy * uy
    e = vx * vx + vy * vy
    b = ux * vx + uy * vy
    return not (a * e - b * b > PARALLEL * a * e)


@jit
def _clamp01(v):
    return 0.0 if v < 0.0 else (1.0 if v > 1.0 else v)


@jit
def closest_segment_params(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):
    """Parameters (s, t) in [0, 1] of the closest points P(s), Q(t) of two segments.

    Ericson, *Real-Time Collision Detection* §5.1.9, with degenerate segments handled and, for
    parallel overlapping segments, the middle of the overlap chosen.
    """
    d1x = p1x - p0x
    d1y = p1y - p0y
    d2x = q1x - q0x
    d2y = q1y - q0y
    rx = p0x - q0x
    ry = p0y - q0y
    a = d1x * d1x + d1y * d1y
    e = d2x * d2x + d2y * d2y
    f = d2x * rx + d2y * ry
    if a <= _TINY and e <= _TINY:
        return 0.0, 0.0
    if a <= _TINY:
        return 0.0, _clamp01(f / e)
    c = d1x * rx + d1y * ry
    if e <= _TINY:
        return _clamp01(-c / a), 0.0
    b = d1x * d2x + d1y * d2y
    denom = a * e - b * b
    if denom > PARALLEL * a * e:
        s = _clamp01((b * f - c * e) / denom)
    else:
        # parallel: the middle of the overlap of Q's projection onto P, if they overlap
        s0 = -c / a
        s1 = (b - c) / a
        lo = max(0.0, min(s0, s1))
        hi = min(1.0, max(s0, s1))
        if lo <= hi:
            s = 0.5 * (lo + hi)
            t = _clamp01((b * s + f) / e)
            return s, t
        s = 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t = 0.0
        s = _clamp01(-c / a)
    elif t > 1.0:
        t = 1.0
        s = _clamp01((b - c) / a)
    return s, t


@jit
def capsule_capsule(xa, ya, anga, ha, ra, xb, yb, angb, hb, rb, pinned=False):
    """Gap, unit normal (a to b) and closest core points of two capsules.

    ``pinned``: neither body can translate (pivots or static bodies). A flat contact's middle
    can then be a pivot, where neither an impulse nor a positional correction acts, so its
    points are the nearest end and its foot on the other core (:func:`_nearest_ends`): a
    pivoted rod flat on a 0.2 m static rod turned through it (cores crossed by 0.117 m).

    Returns:
        (gap, nx, ny, oax, oay, obx, oby, separation): the closest core points relative to each
        centre, and the distance between the two chosen surface points (the gap itself, except
        for a flat contact, whose points are the middle of the overlap while the gap is the
        nearer end's); the contact point is ``centre_a + o_a + (ra + separation/2) n``, the same
        point seen from both bodies.
    """
    p0x, p0y, p1x, p1y = core_segment(xa, ya, anga, ha)
    q0x, q0y, q1x, q1y = core_segment(xb, yb, angb, hb)
    if ha > 0.0 and hb > 0.0:
        crossed = _crossed(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y, xa, ya, ra, xb, yb, rb)
        if crossed[0] < 0.0:
            return crossed
    s, t = closest_segment_params(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y)
    if pinned and ha > 0.0 and hb > 0.0:
        s, t = _nearest_ends(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y, s, t)
    cax = p0x + s * (p1x - p0x)
    cay = p0y + s * (p1y - p0y)
    cbx = q0x + t * (q1x - q0x)
    cby = q0y + t * (q1y - q0y)
    dx = cbx - cax
    dy = cby - cay
    d = math.sqrt(dx * dx + dy * dy)
    if d > _TINY:
        nx, ny = _normal(dx, dy, d, s, anga, ha, t, angb, hb)
    else:
        # cores touch: fall back to the line of centres, then to +x
        dx = xb - xa
        dy = yb - ya
        dc = math.sqrt(dx * dx + dy * dy)
        if dc > _TINY:
            nx = dx / dc
            ny = dy / dc
        else:
            nx = 1.0
            ny = 0.0
    separation = d - ra - rb
    if ha > 0.0 and hb > 0.0:
        # nearly parallel segments: the contact point is the middle of their overlap (a flat
        # impact), but the gap is the smallest distance, at an end of the overlap, so that it
        # does not jump when the segments turn out of parallel (the middle's distance hid up to
        # sqrt(PARALLEL) x length of penetration)
        if _parallel(p1x - p0x, p1y - p0y, q1x - q0x, q1y - q0y):
            d = min(d, _point_segment(p0x, p0y, q0x, q0y, q1x, q1y),
                    _point_segment(p1x, p1y, q0x, q0y, q1x, q1y),
                    _point_segment(q0x, q0y, p0x, p0y, p1x, p1y),
                    _point_segment(q1x, q1y, p0x, p0y, p1x, p1y))
    return d - ra - rb, nx, ny, cax - xa, cay - ya, cbx - xb, cby - yb, separation


@jit
def flat_ends(xa, ya, anga, ha, ra, xb, yb, angb, hb, rb, nx, ny):
    """The two ends of a flat (parallel, ``PARALLEL``) rod-rod contact's overlap, as contact
    points: an end of one core over the other core, the points a slightly tilted pair would
    touch at (the event-driven solver's end impacts).

    ``(nx, ny)`` is the pair's normal (:func:`capsule_capsule`'s, a to b). Each point lies on
    that normal midway between the surfaces at its end, given relative to each centre (the same
    point from both bodies, so the impulse there keeps angular momentum).

    Returns:
        (flat, p1ax, p1ay, p1bx, p1by, d1, p2ax, p2ay, p2bx, p2by, d2): ``flat`` is False when
        the cores are not parallel, a core is a point, or their projections do not overlap;
        else the two points (1 the nearer end: core distance ``d1 <= d2``).
    """
    if not (ha > 0.0 and hb > 0.0):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    p0x, p0y, p1x, p1y = core_segment(xa, ya, anga, ha)
    q0x, q0y, q1x, q1y = core_segment(xb, yb, angb, hb)
    ux = p1x - p0x
    uy = p1y - p0y
    vx = q1x - q0x
    vy = q1y - q0y
    if not _parallel(ux, uy, vx, vy):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    aa = ux * ux + uy * uy
    ee = vx * vx + vy * vy
    rx = p0x - q0x
    ry = p0y - q0y
    bb = ux * vx + uy * vy
    c = ux * rx + uy * ry
    f = vx * rx + vy * ry
    s0 = -c / aa
    s1 = (bb - c) / aa
    lo = max(0.0, min(s0, s1))
    hi = min(1.0, max(s0, s1))
    if lo > hi:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # the overlap's ends on P and their feet on Q
    alx = p0x + lo * ux
    aly = p0y + lo * uy
    tl = _clamp01((bb * lo + f) / ee)
    blx = q0x + tl * vx
    bly = q0y + tl * vy
    ahx = p0x + hi * ux
    ahy = p0y + hi * uy
    th = _clamp01((bb * hi + f) / ee)
    bhx = q0x + th * vx
    bhy = q0y + th * vy
    dl = math.sqrt((blx - alx) ** 2 + (bly - aly) ** 2)
    dh = math.sqrt((bhx - ahx) ** 2 + (bhy - ahy) ** 2)
    # each point on the normal, midway between the surfaces: a's surface at ra along n from its
    # core point, b's at rb back from its own (their distance along n is that end's gap)
    kl = ra + 0.5 * ((blx - alx) * nx + (bly - aly) * ny - ra - rb)
    kh = ra + 0.5 * ((bhx - ahx) * nx + (bhy - ahy) * ny - ra - rb)
    mlx = alx + kl * nx
    mly = aly + kl * ny
    mhx = ahx + kh * nx
    mhy = ahy + kh * ny
    if dl <= dh:
        return True, mlx - xa, mly - ya, mlx - xb, mly - yb, dl, mhx - xa, mhy - ya, mhx - xb, \
            mhy - yb, dh
    return True, mhx - xa, mhy - ya, mhx - xb, mhy - yb, dh, mlx - xa, mly - ya, mlx - xb, \
        mly - yb, dl


@jit
def _segment_param(px, py, ax, ay, bx, by):
    """Parameter in [0, 1] of the point of segment a-b nearest to p, and its distance."""
    ux = bx - ax
    uy = by - ay
    uu = ux * ux + uy * uy
    f = _clamp01(((px - ax) * ux + (py - ay) * uy) / uu) if uu > _TINY else 0.0
    dx = px - ax - f * ux
    dy = py - ay - f * uy
    return f, math.sqrt(dx * dx + dy * dy)


@jit
def _nearest_ends(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y, s, t):
    """(s, t) of a parallel pair's nearest end and its foot on the other segment (the first on
    a tie), else (s, t) unchanged."""
    if not _parallel(p1x - p0x, p1y - p0y, q1x - q0x, q1y - q0y):
        return s, t
    f, d = _segment_param(p0x, p0y, q0x, q0y, q1x, q1y)
    best, bs, bt = d, 0.0, f
    f, d = _segment_param(p1x, p1y, q0x, q0y, q1x, q1y)
    if d < best:
        best, bs, bt = d, 1.0, f
    f, d = _segment_param(q0x, q0y, p0x, p0y, p1x, p1y)
    if d < best:
        best, bs, bt = d, f, 0.0
    f, d = _segment_param(q1x, q1y, p0x, p0y, p1x, p1y)
    if d < best:
        best, bs, bt = d, f, 1.0
    return bs, bt


@jit
def _side(ax, ay, bx, by, px, py):
    """Twice the signed area of (a, b, p): > 0 where p lies left of the line from a to b."""
    return (bx - ax) * (py - ay) - (by - ay) * (px - ax)


@jit
def _sides(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):
    """Signed distances (times the other's length) of P's ends from Q's line and of Q's ends
    from P's, and whether the segments cross: each one's ends strictly on either side of the
    other's line."""
    sp0 = _side(q0x, q0y, q1x, q1y, p0x, p0y)
    sp1 = _side(q0x, q0y, q1x, q1y, p1x, p1y)
    sq0 = _side(p0x, p0y, p1x, p1y, q0x, q0y)
    sq1 = _side(p0x, p0y, p1x, p1y, q1x, q1y)
    return sp0, sp1, sq0, sq1, sp0 * sp1 < 0.0 and sq0 * sq1 < 0.0


@jit
def cores_cross(xa, ya, anga, ha, xb, yb, angb, hb):
    """Whether two rods' core segments cross (their capsules overlap by the whole thickness)."""
    if not (ha > 0.0 and hb > 0.0):
        return False
    p0x, p0y, p1x, p1y = core_segment(xa, ya, anga, ha)
    q0x, q0y, q1x, q1y = core_segment(xb, yb, angb, hb)
    return _sides(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y)[4]


@jit
def _crossed(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y, xa, ya, ra, xb, yb, rb):
    """:func:`capsule_capsule`'s result for core segments P (body a) and Q (body b) that cross
    (each one's ends strictly on either side of the other's line); else a result whose gap is
    0.0, which the caller ignores.

    Crossed cores are at distance 0, and their closest points (the crossing) give no normal:
    reported so, crossed rods read as touching (bare rods at a gap of 0) and cannot be pushed
    apart. Their depth is the smallest translation that uncrosses them: the least distance of
    one's end from the other's line (the edges of their Minkowski difference, a parallelogram
    holding the origin), taken along that line's normal, from a to b. The gap is ``-depth``
    less the radii, so it goes on continuously from the touching cores' ``-(ra + rb)``; the
    closest points are that end and its foot on the line, so the contact point lies midway.
    """
    sp0, sp1, sq0, sq1, crossed = _sides(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y)
    if not crossed:
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    ux = p1x - p0x
    uy = p1y - p0y
    vx = q1x - q0x
    vy = q1y - q0y
    lv = math.sqrt(vx * vx + vy * vy)
    lu = math.sqrt(ux * ux + uy * uy)
    # the shallowest end: one of P's (moved back across Q's line, a moves along -n) or of Q's
    dp = min(abs(sp0), abs(sp1)) / lv
    dq = min(abs(sq0), abs(sq1)) / lu
    if dp <= dq:
        sp = sp0 if abs(sp0) <= abs(sp1) else sp1
        ex, ey = (p0x, p0y) if abs(sp0) <= abs(sp1) else (p1x, p1y)
        # Q's left normal is (-vy, vx) / lv; the end lies on the side of sp's sign
        sign = 1.0 if sp > 0.0 else -1.0
        nx = -vy / lv * sign
        ny = vx / lv * sign
        depth = dp
        cax, cay = ex, ey
        cbx = ex - depth * nx
        cby = ey - depth * ny
    else:
        sq = sq0 if abs(sq0) <= abs(sq1) else sq1
        ex, ey = (q0x, q0y) if abs(sq0) <= abs(sq1) else (q1x, q1y)
        # Q's end goes back across P's line: b moves along n, away from the end's side
        sign = -1.0 if sq > 0.0 else 1.0
        nx = -uy / lu * sign
        ny = ux / lu * sign
        depth = dq
        cbx, cby = ex, ey
        cax = ex + depth * nx
        cay = ey + depth * ny
    gap = -depth - ra - rb
    return gap, nx, ny, cax - xa, cay - ya, cbx - xb, cby - yb, gap


@jit
def _normal(dx, dy, d, s, anga, ha, t, angb, hb):
    """Unit normal along the core offset (dx, dy) of length d > 0, the closest points at
    parameters s (on a) and t (on b).

    Where one closest point lies strictly inside its segment, the offset is perpendicular to that
    segment, so the normal is the segment's perpendicular (from its angle, exact to round-off),
    signed by the offset. Dividing the offset by d instead divides the closest points' round-off
    (~1e-17 m) by d, which for two zero-thickness rods at contact is the gap (the tolerance or
    less): a tip striking the side of a bare rod at tolerance 1e-12 m had its normal off by 6e-5
    rad. End-end contacts (and crossing or parallel cores, where both points are inside) keep the
    offset's direction.
    """
    inside_a = ha > 0.0 and 0.0 < s < 1.0
    inside_b = hb > 0.0 and 0.0 < t < 1.0
    if inside_a != inside_b:
        ang = angb if inside_b else anga
        px = -math.sin(ang)
        py = math.cos(ang)
        side = dx * px + dy * py
        if side > 0.0:
            return px, py
        if side < 0.0:
            return -px, -py
    return dx / d, dy / d


@jit
def _point_segment(px, py, ax, ay, bx, by):
    """Distance from a point to a segment."""
    return _segment_param(px, py, ax, ay, bx, by)[1]


@jit
def wall_frame(wall, half_w, half_h):
    """Inward unit normal and offset of cushion ``wall``: a point p lies ``ix px + iy py + off``
    inside it (0 left, 1 right, 2 bottom, 3 top)."""
    if wall == 0:
        return 1.0, 0.0, half_w
    if wall == 1:
        return -1.0, 0.0, half_w
    if wall == 2:
        return 0.0, 1.0, half_h
    return 0.0, -1.0, half_h


@jit
def _flat_on_wall(d0, d1, h):
    """Whether a rod of half-length ``h`` whose core ends lie ``d0``, ``d1`` from a cushion
    lies flat on it (parallel to ``PARALLEL``): the one test of :func:`capsule_wall` and
    :func:`flat_wall_ends`, so that they agree on which contacts are flat down to round-off."""
    diff = d0 - d1
    return h > 0.0 and diff * diff <= PARALLEL * 4.0 * h * h


@jit
def flat_wall_ends(x, y, angle, h, r, wall, half_w, half_h):
    """The two ends of a rod lying flat on cushion ``wall`` (:func:`capsule_wall`'s flat case),
    as contact points: the points a slightly tilted rod touches at (the event-driven solver's
    end impacts), each on the cushion's normal midway between the rod's surface and the
    cushion, relative to the rod's centre.

    Returns:
        (flat, o1x, o1y, d1, o2x, o2y, d2): ``flat`` is False when the rod is not flat on the
        cushion (or is a disk); else the two points, 1 the nearer end (core distance from the
        cushion ``d1 <= d2``; the first end on a tie).
    """
    p0x, p0y, p1x, p1y = core_segment(x, y, angle, h)
    ix, iy, off = wall_frame(wall, half_w, half_h)
    d0 = ix * p0x + iy * p0y + off
    d1 = ix * p1x + iy * p1y + off
    if not _flat_on_wall(d0, d1, h):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # the normal from the rod to the cushion is -i; the point lies r + (d - r) / 2 along it
    k0 = r + 0.5 * (d0 - r)
    k1 = r + 0.5 * (d1 - r)
    o0x = p0x - k0 * ix - x
    o0y = p0y - k0 * iy - y
    o1x = p1x - k1 * ix - x
    o1y = p1y - k1 * iy - y
    if d0 <= d1:
        return True, o0x, o0y, d0, o1x, o1y, d1
    return True, o1x, o1y, d1, o0x, o0y, d0


@jit
def capsule_wall(x, y, angle, h, r, wall, half_w, half_h, pinned=False):
    """Gap, unit normal (body to cushion) and closest core point of a capsule and a cushion.

    Cushions: 0 left (x = -half_w), 1 right (x = +half_w), 2 bottom (y = -half_h), 3 top.

    ``pinned``: the body cannot translate (a pivot, pinned at its centre). A flat contact's
    middle is then its pivot, where neither an impulse nor a positional correction can act, so
    its contact point is the nearer end (the first on a tie) as for a tilted rod: a pivoted rod
    flat on a cushion and turning into it was left 3e-7 m inside it at every settled step's
    end, 300x the tolerance, spinning on unchecked.

    Returns:
        (gap, nx, ny, ox, oy, 0, 0, separation): the closest core point relative to the centre,
        and its distance from the cushion less the radius (the gap, except flat on the cushion,
        where the point is the middle and the gap the nearer end's).
    """
    p0x, p0y, p1x, p1y = core_segment(x, y, angle, h)
    ix, iy, off = wall_frame(wall, half_w, half_h)
    # distance of each core end from the cushion, measured into the table
    d0 = ix * p0x + iy * p0y + off
    d1 = ix * p1x + iy * p1y + off
    if not pinned and _flat_on_wall(d0, d1, h):
        # flat on the cushion: the contact point is the middle (an impact through the middle),
        # the gap the nearer end's, so that it does not jump when the rod turns out of parallel
        # (the middle's distance hid up to sqrt(PARALLEL) h of penetration)
        cx = 0.5 * (p0x + p1x)
        cy = 0.5 * (p0y + p1y)
        d = min(d0, d1)
        separation = 0.5 * (d0 + d1) - r
    elif d0 <= d1:
        cx, cy, d = p0x, p0y, d0
        separation = d - r
    else:
        cx, cy, d = p1x, p1y, d1
        separation = d - r
    return d - r, -ix, -iy, cx - x, cy - y, 0.0, 0.0, separation


@jit_inline
def flat_points(xa, ya, anga, ha, ra, pinned_a, xb, yb, angb, hb, rb, pinned_b, wall, half_w,
                half_h, nx, ny):
    """The two contact points of a pair the solvers resolve flat, or ``flat`` False: a flat
    rod-rod pair not both pinned (:func:`flat_ends`), or a rod flat on cushion ``wall`` that is
    not pinned (:func:`flat_wall_ends`; a pinned one keeps :func:`capsule_wall`'s nearer end,
    its middle being its pivot; b's points are then a's, b unused). One decision for the
    contact's resolution and the time of impact's approach test, so that they agree.

    Returns:
        (flat, o1ax, o1ay, o1bx, o1by, d1, o2ax, o2ay, o2bx, o2by, d2), as :func:`flat_ends`.
    """
    if wall < 0:
        if pinned_a and pinned_b:
            return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        return flat_ends(xa, ya, anga, ha, ra, xb, yb, angb, hb, rb, nx, ny)
    if pinned_a:
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    flat, o1x, o1y, d1, o2x, o2y, d2 = flat_wall_ends(xa, ya, anga, ha, ra, wall, half_w, half_h)
    return flat, o1x, o1y, o1x, o1y, d1, o2x, o2y, o2x, o2y, d2
