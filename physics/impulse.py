"""The impulse law of the seed note (§2.2), in inverse-mass form.

Sign convention (docs/design.md §2): the normal ``n`` points **from body a to body b**; lever arms
are ``r_a = p - x_a``, ``r_b = p - x_b``; point velocities ``v_ip = v_i + omega_i x r_i``. For an
approaching pair (``(v_bp - v_ap) . n < 0``)::

    j = -(1 + e) (v_bp - v_ap) . n / (1/m_a + 1/m_b + (r_a x n)^2 / I_a + (r_b x n)^2 / I_b)
    v_a -= j n / m_a     omega_a -= (r_a x n) j / I_a
    v_b += j n / m_b     omega_b += (r_b x n) j / I_b

which is the seed's formula with its ``n`` reversed. Everything uses inverse masses and inertias,
so static bodies and cushions (inverse mass and inertia 0), pivots (inverse mass 0) and mass
ratios of 1e-12..1e12 need no special case; ``m = inf`` never appears in arithmetic. Two places
where the code departs from the note: §2.2 writes ``I2 (w2' - w2) = r2p x J`` although body 2
receives ``-J`` (here the minus sign is kept), and the note's rod inertia (see ``shapes``).

A lever arm is passed as the core offset ``o`` (closest core point minus centre) and the distance
``k`` from the core to the contact point along n: ``r_a = o_a + k_a n``, ``r_b = o_b - k_b n``, so
``r x n = o x n`` exactly (0 for a disk, whose core is its centre) and ``r x t = o x t +/- k``.

Friction (``contact_friction``, not in the note) is sequential: after the normal impulse, a
tangential impulse along ``t = (-n_y, n_x)`` that stops the slip, clipped to ``|jt| <= mu j``; it
never reverses the slip, so it never adds energy (solving Newton restitution jointly with Coulomb
friction can add energy for rotating bodies). If its lever arms turn the contact into an
approaching one again, a last plastic normal impulse (e = 0) removes the approach. The ``-e`` law
along the normal thus holds exactly where the tangential impulse has no lever on the normal
direction (disks, or mu = 0).

The kernels take an element's state ``S [N, 6]`` and parameters ``Pm [N, 6]`` with body indices
``a`` and ``b`` (``b`` is ignored when it is a cushion): rows are read by index, not sliced.
"""

from __future__ import annotations

from spinstrike.physics.jit import jit, jit_counted, jit_inline
from spinstrike.physics.layout import INV_INERTIA, INV_MASS, OMEGA, VX, VY

__all__ = ["ROUNDOFF", "apply_impulse", "relative_velocity", "relative_velocity_of", "resolve",
           "resolve_flat"]



@jit
def relative_velocity_of(vxa, vya, wa, vxb, vyb, wb, is_wall, nx, ny, oax, oay, ka, obx, oby,
                         kb):
    """Relative velocity ``v_bp - v_ap`` at the contact point: (along n, along t, scale), from
    the two bodies' velocities and spins.

    ``scale`` (sum of the point velocities' absolute components) sizes the round-off of vn.
    """
    rax = oax + ka * nx
    ray = oay + ka * ny
    vax = vxa - wa * ray
    vay = vya + wa * rax
    if is_wall:
        vbx = 0.0
        vby = 0.0
    else:
        rbx = obx - kb * nx
        rby = oby - kb * ny
        vbx = vxb - wb * rby
        vby = vyb + wb * rbx
    dvx = vbx - vax
    dvy = vby - vay
    scale = abs(vax) + abs(vay) + abs(vbx) + abs(vby)
    return dvx * nx + dvy * ny, -dvx * ny + dvy * nx, scale


@jit_inline
def relative_velocity(S, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb):
    """:func:`relative_velocity_of` for bodies ``a`` and ``b`` of the state ``S``."""
    return relative_velocity_of(S[a, VX], S[a, VY], S[a, OMEGA], S[b, VX], S[b, VY], S[b, OMEGA],
                                is_wall, nx, ny, oax, oay, ka, obx, oby, kb)


@jit_inline
def apply_impulse(S, Pm, a, b, is_wall, j, dx, dy, cross_a, cross_b, rotation):
    """Apply impulse ``j d`` to body b and ``-j d`` to body a; ``cross_* = r_* x d``."""
    ima = Pm[a, INV_MASS]
    S[a, VX] -= j * dx * ima
    S[a, VY] -= j * dy * ima
    if rotation:
        S[a, OMEGA] -= cross_a * j * Pm[a, INV_INERTIA]
    if not is_wall:
        imb = Pm[b, INV_MASS]
        S[b, VX] += j * dx * imb
        S[b, VY] += j * dy * imb
        if rotation:
            S[b, OMEGA] += cross_b * j * Pm[b, INV_INERTIA]


@jit_inline
def _coupling(Pm, a, b, is_wall, c1a, c1b, c2a, c2b, rotation):
    """Off-diagonal term of two contact points' effective inverse mass along one normal: the
    normal velocity at point 1 per unit impulse at point 2 (``c* = r* x n`` at each point)."""
    k = Pm[a, INV_MASS]
    if rotation:
        k += c1a * c2a * Pm[a, INV_INERTIA]
    if not is_wall:
        k += Pm[b, INV_MASS]
        if rotation:
            k += c1b * c2b * Pm[b, INV_INERTIA]
    return k


@jit_inline
def _effective_inverse_mass(Pm, a, b, is_wall, cross_a, cross_b, rotation):
    """``1/m_a + 1/m_b + (r_a x d)^2 / I_a + (r_b x d)^2 / I_b``."""
    return _coupling(Pm, a, b, is_wall, cross_a, cross_b, cross_a, cross_b, rotation)


@jit_counted
def _friction(S, Pm, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb, rna, rnb, mu, j, k_n,
              rotation):
    """Sequential Coulomb stage; returns (tangential impulse, extra plastic normal impulse)."""
    vn, vt, _ = relative_velocity(S, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb)
    if vt == 0.0:
        return 0.0, 0.0
    tx = -ny
    ty = nx
    rta = oax * ty - oay * tx + ka
    rtb = obx * ty - oby * tx - kb
    k_t = _effective_inverse_mass(Pm, a, b, is_wall, rta, rtb, rotation)
    jt = -vt / k_t
    limit = mu * j
    if jt > limit:
        jt = limit
    elif jt < -limit:
        jt = -limit
    apply_impulse(S, Pm, a, b, is_wall, jt, tx, ty, rta, rtb, rotation)
    vn, vt, _ = relative_velocity(S, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb)
    if vn < 0.0:
        j2 = -vn / k_n
        apply_impulse(S, Pm, a, b, is_wall, j2, nx, ny, rna, rnb, rotation)
        return jt, j2
    return jt, 0.0


@jit_counted
def resolve(S, Pm, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb, e, mu, rotation,
            contact_friction):
    """Resolve one contact in place.

    Args:
        S, Pm: the element's state and parameters; a, b: the bodies (b ignored for a cushion).
        is_wall: body b is a cushion.
        nx, ny: unit normal from a to b.
        oax, oay, ka / obx, oby, kb: lever arms as core offset and distance along n.
        e: restitution in [0, 1].  mu: friction coefficient.

    Returns:
        (j, jt, vn): normal impulse magnitude (>= 0, including any plastic correction after
        friction), tangential impulse along t = (-n_y, n_x), and the normal relative velocity
        before (negative when approaching; nothing is applied otherwise).
    """
    vn, vt, _ = relative_velocity(S, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb)
    if vn >= 0.0:
        return 0.0, 0.0, vn
    rna = oax * ny - oay * nx
    rnb = obx * ny - oby * nx
    k_n = _effective_inverse_mass(Pm, a, b, is_wall, rna, rnb, rotation)
    if k_n <= 0.0:
        return 0.0, 0.0, vn
    j = -(1.0 + e) * vn / k_n
    apply_impulse(S, Pm, a, b, is_wall, j, nx, ny, rna, rnb, rotation)
    jt = 0.0
    if contact_friction and mu > 0.0:
        jt, j2 = _friction(S, Pm, a, b, is_wall, nx, ny, oax, oay, ka, obx, oby, kb, rna, rnb,
                           mu, j, k_n, rotation)
        j += j2
    return j, jt, vn


#: relative round-off of a normal velocity: below it times the point speeds, a pair neither
#: approaches nor separates (also ``events.ROUNDOFF``)
ROUNDOFF = 1e-12
#: end impacts of one flat contact before the rest is left to the next sweep
FLAT_IMPACTS = 64


@jit_inline
def _end_velocity(S, a, b, is_wall, nx, ny, oax, oay, obx, oby):
    """Normal relative velocity at a point given relative to both centres, 0 below round-off."""
    vn, _, scale = relative_velocity(S, a, b, is_wall, nx, ny, oax, oay, 0.0, obx, oby, 0.0)
    return 0.0 if abs(vn) <= ROUNDOFF * scale else vn


@jit_inline
def _end_impact(S, Pm, a, b, is_wall, nx, ny, oax, oay, obx, oby, ca, cb, k, e, rotation):
    """The ``-e`` impact at one end of a flat contact if it approaches (``k``: its effective
    inverse mass, ``ca``/``cb``: the lever arms across n); returns its impulse, 0 if none."""
    vn = _end_velocity(S, a, b, is_wall, nx, ny, oax, oay, obx, oby)
    if not vn < 0.0:
        return 0.0
    j = -(1.0 + e) * vn / k
    apply_impulse(S, Pm, a, b, is_wall, j, nx, ny, ca, cb, rotation)
    return j


@jit_counted
def resolve_flat(S, Pm, a, b, is_wall, nx, ny, o1ax, o1ay, o1bx, o1by, o2ax, o2ay, o2bx, o2by,
                 tie, e, mu, rotation, contact_friction):
    """Resolve a flat rod-rod contact (``contacts.flat_ends``), or a rod flat on a cushion
    (``is_wall``: ``contacts.flat_wall_ends``, b's points unused), in place: the limit of the
    event-driven end impacts as the tilt goes to 0.

    A rod landing at a small tilt hits at its lower end (point 1, the nearer), turns, hits at
    the other (point 2), and so on until neither end approaches; the sequence, and so the
    outcome, does not depend on the tilt as it goes to 0 (the time between impacts does). It is
    applied here at once, each impact by the ``-e`` law at its end: momentum exact, no energy
    gained. Points at an exact tie (``tie``: parallel to round-off, where neither end comes
    first) are solved as one simultaneous two-point impact, ``-e`` at both, if both impulses come
    out >= 0 (the symmetric outcome: a rod dropped exactly flat bounces without spin), else as
    the sequence. Friction, if any, acts after the normal impulses at their centre of pressure.

    Returns:
        (j, jt, vn, ox_a, oy_a): total normal impulse, tangential impulse, the most approaching
        end's normal velocity before (nothing applied unless < 0) and the centre of pressure
        relative to a's centre.
    """
    vn1 = _end_velocity(S, a, b, is_wall, nx, ny, o1ax, o1ay, o1bx, o1by)
    vn2 = _end_velocity(S, a, b, is_wall, nx, ny, o2ax, o2ay, o2bx, o2by)
    vn0 = min(vn1, vn2)
    if vn0 >= 0.0:
        return 0.0, 0.0, vn0, 0.0, 0.0
    c1a = o1ax * ny - o1ay * nx
    c1b = o1bx * ny - o1by * nx
    c2a = o2ax * ny - o2ay * nx
    c2b = o2bx * ny - o2by * nx
    k11 = _effective_inverse_mass(Pm, a, b, is_wall, c1a, c1b, rotation)
    k22 = _effective_inverse_mass(Pm, a, b, is_wall, c2a, c2b, rotation)
    if k11 <= 0.0 or k22 <= 0.0:
        return 0.0, 0.0, vn0, 0.0, 0.0
    j1 = 0.0
    j2 = 0.0
    done = False
    if tie and vn1 < 0.0 and vn2 < 0.0:
        k12 = _coupling(Pm, a, b, is_wall, c1a, c1b, c2a, c2b, rotation)
        det = k11 * k22 - k12 * k12
        if det > 1e-9 * k11 * k22:
            x1 = -(1.0 + e) * (k22 * vn1 - k12 * vn2) / det
            x2 = -(1.0 + e) * (k11 * vn2 - k12 * vn1) / det
            if x1 >= 0.0 and x2 >= 0.0:
                apply_impulse(S, Pm, a, b, is_wall, x1, nx, ny, c1a, c1b, rotation)
                apply_impulse(S, Pm, a, b, is_wall, x2, nx, ny, c2a, c2b, rotation)
                j1 = x1
                j2 = x2
                done = True
    if not done:
        # the nearer end first if it approaches, then each end in turn while one approaches
        second = vn1 >= 0.0
        quiet = 0
        for _ in range(FLAT_IMPACTS):
            if second:
                j = _end_impact(S, Pm, a, b, is_wall, nx, ny, o2ax, o2ay, o2bx, o2by, c2a, c2b,
                                k22, e, rotation)
                j2 += j
            else:
                j = _end_impact(S, Pm, a, b, is_wall, nx, ny, o1ax, o1ay, o1bx, o1by, c1a, c1b,
                                k11, e, rotation)
                j1 += j
            quiet = 0 if j > 0.0 else quiet + 1
            if quiet == 2:
                break
            second = not second
    j = j1 + j2
    w1 = j1 / j if j > 0.0 else 0.5
    oax = w1 * o1ax + (1.0 - w1) * o2ax
    oay = w1 * o1ay + (1.0 - w1) * o2ay
    jt = 0.0
    if contact_friction and mu > 0.0 and j > 0.0:
        obx = w1 * o1bx + (1.0 - w1) * o2bx
        oby = w1 * o1by + (1.0 - w1) * o2by
        rna = oax * ny - oay * nx
        rnb = obx * ny - oby * nx
        k_n = _effective_inverse_mass(Pm, a, b, is_wall, rna, rnb, rotation)
        if k_n > 0.0:
            jt, jp = _friction(S, Pm, a, b, is_wall, nx, ny, oax, oay, 0.0, obx, oby, 0.0, rna,
                               rnb, mu, j, k_n, rotation)
            j += jp
    return j, jt, vn0, oax, oay
