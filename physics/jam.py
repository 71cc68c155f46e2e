"""Jams: a block solve of all touching pairs at once, when sequential impulses cannot converge.

The solvers resolve simultaneous contacts by sequential impulses swept in pair order
(``physics.solvers``). A light body pinned between a heavy one and a cushion loses only
``m_light / m_heavy`` of the approach per sweep, so at a mass ratio of 1e6 the sweeps would need
millions; after ``MAX_SWEEPS`` the solvers call :func:`jam_impulses` instead.

The normal impulses ``lam >= 0`` of all pairs within ``slop`` are found together as the solution
of the linear complementarity problem ``w = vn + A lam >= 0, lam . w = 0`` (A: the pairs' Delassus
matrix, from inverse masses and lever arms). That is the compression phase: the minimiser of
the kinetic energy over non-negative impulses, which leaves no pair approaching, a
non-negative least-squares problem, solved by Lawson and Hanson's active-set method
(:func:`_nnls`, up to ``MAX_JAM_PAIRS`` pairs; trying every active set, 2^n, took 10, and a
struck row of 50 touching pucks was left to the settle). Restitution follows Poisson's
hypothesis with the smallest ``e`` of the touching pairs: the impulses are ``(1 + e) lam``, which
change the kinetic energy by ``-(1 - e^2)/2 lam.A.lam <= 0`` (0 for e = 1). Friction is not part
of this block; where pairs have contact friction :func:`jam_friction_impulses` solves them with
it (up to ``MAX_FRICTION_PAIRS`` pairs; the solvers fall back on this block beyond, and flag the
step): without it a self-locking wedge squirted out.

Accuracy at extreme mass ratios: ``A`` is never formed. A light body jammed between heavy ones
makes it nearly singular (its entries ``1/m_light + 1/m_heavy`` lose the heavy bodies' terms to
rounding, and the squeeze the heavy bodies feel is exactly that part), so a solve of ``A`` got
``lam`` to ~1e-4 at a mass ratio of 1e12 and lost that much of the energy at e = 1. Instead
``A = B^T B`` with ``B`` the mass-weighted Jacobian (a row per coordinate of each body: the
mass-weighted normal and lever terms); a Householder QR of ``B`` gives ``A = R^T R`` without
rounding ``A``, and two steps of refinement with the residual computed from the bodies'
impulse sums (``A lam``, never ``A``) bring ``lam`` to round-off at ratios up to 1e18.
"""

from __future__ import annotations

import math

import numpy as np

from spinstrike.physics.events import pair_bodies, pair_geometry
from spinstrike.physics.impulse import relative_velocity
from spinstrike.physics.jit import jit
from spinstrike.physics.layout import (
    FRICTION,
    HALF_H,
    HALF_W,
    INV_INERTIA,
    INV_MASS,
    RESTITUTION,
    Table,
    X,
    Y,
)

__all__ = ["JAM_COLUMNS", "MAX_FRICTION_PAIRS", "MAX_JAM_PAIRS", "collect",
           "jam_friction_impulses", "jam_impulses"]


#: most touching pairs the block solve takes (a jam of 64 pairs costs ~50 ms: a QR of the
#: set's columns at each of its steps); a larger jam is settled (``solvers._settle``)
MAX_JAM_PAIRS = 64
#: the per-pair rows it returns: unit normal (a to b), lever terms r x n of a and b, contact
#: point (m), normal relative velocity (m/s); the lever terms r x t of a and b and the tangential
#: relative velocity (m/s) along t = (-n_y, n_x), for the friction block
JAM = Table("jam pair", "nx", "ny", "cross_a", "cross_b", "px", "py", "vn", "cross_ta", "cross_tb",
            "vt", prefix="JAM_")
(JAM_NX, JAM_NY, JAM_CROSS_A, JAM_CROSS_B, JAM_PX, JAM_PY, JAM_VN, JAM_CROSS_TA, JAM_CROSS_TB,
 JAM_VT) = JAM
JAM_COLUMNS = len(JAM)


@jit
def collect(S, Pm, hw, PA, PB, slop, idx, geo):
    """A jam's pairs, those within ``slop``: their indices and geometry rows (``JAM``) in the
    scratch ``idx`` and ``geo`` of ``MAX_JAM_PAIRS`` rows. Returns how many, -1 if there are
    too many. Both block solves take these rows; the solvers collect them once a jam."""
    n = S.shape[0]
    m = 0
    for p in range(PA.shape[0]):
        a, bb, wall = pair_bodies(p, PA, PB, n)
        g, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, bb, wall, hw[HALF_W],
                                                                  hw[HALF_H])
        if g <= slop:
            if m == MAX_JAM_PAIRS:
                return -1
            idx[m] = p
            geo[m, JAM_NX] = nx
            geo[m, JAM_NY] = ny
            geo[m, JAM_CROSS_A] = oax * ny - oay * nx
            geo[m, JAM_CROSS_B] = obx * ny - oby * nx
            geo[m, JAM_PX] = S[a, X] + oax + ka * nx
            geo[m, JAM_PY] = S[a, Y] + oay + ka * ny
            geo[m, JAM_VN] = vn
            geo[m, JAM_CROSS_TA] = oax * nx + oay * ny + ka
            geo[m, JAM_CROSS_TB] = obx * nx + oby * ny - kb
            geo[m, JAM_VT] = relative_velocity(S, a, bb, wall >= 0, nx, ny, oax, oay, ka, obx,
                                               oby, kb)[1]
            m += 1
    return m


@jit
def _side(PA, PB, idx, geo, i, side):
    """(body, sign, lever r x n) of one side of pair row i (side 0: a, 1: b)."""
    if side == 0:
        return PA[idx[i]], -1.0, geo[i, JAM_CROSS_A]
    return PB[idx[i]], 1.0, geo[i, JAM_CROSS_B]


@jit
def _solve_small(M, rhs, k):
    """Solve the k x k system ``M x = rhs`` in place (partial pivoting); False if singular.
    (``solvers._hold``'s constraint solve; the block solve here goes through QR.)"""
    scale = 0.0
    for i in range(k):
        scale = max(scale, abs(M[i, i]))
    for c in range(k):
        piv = c
        for r in range(c + 1, k):
            if abs(M[r, c]) > abs(M[piv, c]):
                piv = r
        if abs(M[piv, c]) <= 1e-13 * scale or M[piv, c] == 0.0:
            return False
        if piv != c:
            for q in range(k):
                M[c, q], M[piv, q] = M[piv, q], M[c, q]
            rhs[c], rhs[piv] = rhs[piv], rhs[c]
        for r in range(c + 1, k):
            f = M[r, c] / M[c, c]
            for q in range(c, k):
                M[r, q] -= f * M[c, q]
            rhs[r] -= f * rhs[c]
    for c in range(k - 1, -1, -1):
        acc = rhs[c]
        for q in range(c + 1, k):
            acc -= M[c, q] * rhs[q]
        rhs[c] = acc / M[c, c]
    return True


@jit
def _weighted_jacobian(Pm, PA, PB, n, idx, geo, m, rotation):
    """``B`` with ``B^T B = A`` (the Delassus matrix: ``A[i, k]``, the change of pair i's normal
    velocity per unit impulse on pair k): a column per pair row, three rows per body the rows
    touch (its x, y and turn, weighted by the square roots of its inverse mass and inertia).
    Also ``side[i, s]``, the local index of side s's body of row i (-1: a cushion), and the
    bodies' global indices."""
    side = np.full((m, 2), -1, np.int64)
    ids = np.empty(2 * m, np.int64)
    B = np.zeros((6 * m, m))
    nb = 0
    for i in range(m):
        for s in range(2):
            x, sgn, c = _side(PA, PB, idx, geo, i, s)
            if x >= n:
                continue
            j = 0
            while j < nb and ids[j] != x:
                j += 1
            if j == nb:
                ids[nb] = x
                nb += 1
            side[i, s] = j
            wm = math.sqrt(Pm[x, INV_MASS])
            B[3 * j, i] += sgn * wm * geo[i, JAM_NX]
            B[3 * j + 1, i] += sgn * wm * geo[i, JAM_NY]
            if rotation:
                B[3 * j + 2, i] += sgn * math.sqrt(Pm[x, INV_INERTIA]) * c
    return B[:3 * nb], side, ids[:nb]


@jit
def _impulse_sums(PA, PB, idx, geo, m, side, nb, lam):
    """Each body's net impulse (x, y) and angular impulse from impulses ``lam`` on the rows, in
    ``P[nb, 3]``, with ``Pabs``, the same sums of magnitudes (the scale of their round-off)."""
    P = np.zeros((nb, 3))
    Pabs = np.zeros((nb, 3))
    for i in range(m):
        for s in range(2):
            j = side[i, s]
            if j < 0:
                continue
            _, sgn, c = _side(PA, PB, idx, geo, i, s)
            P[j, 0] += sgn * lam[i] * geo[i, JAM_NX]
            P[j, 1] += sgn * lam[i] * geo[i, JAM_NY]
            P[j, 2] += sgn * lam[i] * c
            Pabs[j, 0] += abs(lam[i] * geo[i, JAM_NX])
            Pabs[j, 1] += abs(lam[i] * geo[i, JAM_NY])
            Pabs[j, 2] += abs(lam[i] * c)
    return P, Pabs


@jit
def _apply_delassus(Pm, PA, PB, idx, geo, m, side, ids, lam, rotation, out, scale):
    """``out = A lam``, from the bodies' impulse sums (``A`` itself would round a light body's
    terms into a heavy one's), and ``scale``, the size of the terms summed into each entry.
    Returns ``lam.A.lam`` as the kinetic-energy norm of those sums (never negative)."""
    nb = ids.shape[0]
    P, Pabs = _impulse_sums(PA, PB, idx, geo, m, side, nb, lam)
    for i in range(m):
        acc = 0.0
        mag = 0.0
        for s in range(2):
            j = side[i, s]
            if j < 0:
                continue
            x = ids[j]
            _, sgn, c = _side(PA, PB, idx, geo, i, s)
            ima = Pm[x, INV_MASS]
            acc += sgn * ima * (geo[i, JAM_NX] * P[j, 0] + geo[i, JAM_NY] * P[j, 1])
            mag += ima * (abs(geo[i, JAM_NX]) * Pabs[j, 0] + abs(geo[i, JAM_NY]) * Pabs[j, 1])
            if rotation:
                acc += sgn * Pm[x, INV_INERTIA] * c * P[j, 2]
                mag += Pm[x, INV_INERTIA] * abs(c) * Pabs[j, 2]
        out[i] = acc
        scale[i] = mag
    total = 0.0
    for j in range(nb):
        x = ids[j]
        total += Pm[x, INV_MASS] * (P[j, 0] * P[j, 0] + P[j, 1] * P[j, 1])
        if rotation:
            total += Pm[x, INV_INERTIA] * P[j, 2] * P[j, 2]
    return total


@jit
def _householder(M, k):
    """QR of ``M``'s first k columns (rows >= k) in place: ``R`` in its upper k x k triangle,
    and the reflectors applied to any columns after them (``Q^T`` times them). False if a
    column is (to round-off) a combination of the ones before it: no unique solution."""
    rows = M.shape[0]
    if rows < k:
        return False
    for c in range(k):
        norm2 = 0.0
        for r in range(rows):
            norm2 += M[r, c] * M[r, c]
        rest2 = 0.0  # below the diagonal (summed apart: x_c^2 may dwarf it)
        for r in range(c + 1, rows):
            rest2 += M[r, c] * M[r, c]
        below = math.sqrt(M[c, c] * M[c, c] + rest2)
        if below <= 1e-13 * math.sqrt(norm2) or below == 0.0:
            return False
        alpha = -below if M[c, c] >= 0.0 else below
        # the reflector v = x - alpha e_c, kept in column c below the diagonal (and v_c apart)
        vc = M[c, c] - alpha
        vnorm2 = vc * vc + rest2
        for q in range(c + 1, M.shape[1]):
            dot = vc * M[c, q]
            for r in range(c + 1, rows):
                dot += M[r, c] * M[r, q]
            f = 2.0 * dot / vnorm2
            M[c, q] -= f * vc
            for r in range(c + 1, rows):
                M[r, q] -= f * M[r, c]
        M[c, c] = alpha
    return True


@jit
def _rtr_solve(M, k, rhs):
    """Solve ``R^T R x = rhs`` in place, ``R`` the upper triangle of ``M``
    (:func:`_householder`)."""
    for c in range(k):  # R^T z = rhs
        acc = rhs[c]
        for q in range(c):
            acc -= M[q, c] * rhs[q]
        rhs[c] = acc / M[c, c]
    _r_solve(M, k, rhs)


@jit
def _r_solve(M, k, rhs):
    """Solve ``R x = rhs`` in place, ``R`` the upper triangle of ``M``."""
    for c in range(k - 1, -1, -1):
        acc = rhs[c]
        for q in range(c + 1, k):
            acc -= M[c, q] * rhs[q]
        rhs[c] = acc / M[c, c]


@jit
def _poisson(Pm, PA, PB, idx, geo, rows, side, ids, lam, rotation, e):
    """The factor ``k`` of Poisson's restitution on the compression impulses ``lam`` of the
    rows: ``1 + e``, capped by the energy guard; 0 where ``lam`` does not compress
    (``lam.v >= 0`` or ``lam.A.lam <= 0``: nothing to apply).

    ``k lam`` changes the kinetic energy by ``k lam.v + k^2/2 lam.A.lam``. With exact
    arithmetic ``lam.v = lam.w - lam.A.lam``, ``lam.w = 0`` without friction and ``<= 0`` with
    it (it only dissipates), so the change is ``<= 0`` up to ``k = 2``. What round-off is left
    in ``lam`` could add energy at e = 1, so ``k`` is capped where the change computed from
    this ``lam`` is zero, ``-2 lam.v / lam.A.lam`` (the cap loses what the round-off would
    have added)."""
    lv = 0.0
    for r in range(rows):
        lv += lam[r] * geo[r, JAM_VN]
    lal = _apply_delassus(Pm, PA, PB, idx, geo, rows, side, ids, lam, rotation, np.empty(rows),
                          np.empty(rows))
    if not (lv < 0.0 and lal > 0.0):
        return 0.0
    return min(1.0 + e, -2.0 * lv / lal)


#: refinement steps of an active set's solution (each: the residual from the impulse sums, one
#: more pair of triangular solves)
_REFINEMENTS = 2


@jit
def _solve_set(Pm, PA, PB, idx, geo, m, B, side, ids, vn, active, lam, rotation):
    """Solve ``A_SS lam_S = -vn_S`` for the set S of rows marked in ``active`` (QR of their
    columns of ``B``, then refinement from the impulse sums), into ``lam`` (0 off S); False if
    a column of S is a combination of the others (no unique solution)."""
    sel = np.empty(m, np.int64)
    k = 0
    for i in range(m):
        if active[i]:
            sel[k] = i
            k += 1
    M = np.empty((B.shape[0], k))
    for q in range(k):
        M[:, q] = B[:, sel[q]]
    if not _householder(M, k):
        return False
    x = np.empty(k)
    for r in range(k):
        x[r] = -vn[sel[r]]
    _rtr_solve(M, k, x)
    w = np.empty(m)
    scale = np.empty(m)
    d = np.empty(k)
    for _ in range(_REFINEMENTS):
        lam[:] = 0.0
        for r in range(k):
            lam[sel[r]] = x[r]
        _apply_delassus(Pm, PA, PB, idx, geo, m, side, ids, lam, rotation, w, scale)
        for r in range(k):
            d[r] = -vn[sel[r]] - w[sel[r]]
        _rtr_solve(M, k, d)
        for r in range(k):
            x[r] += d[r]
    lam[:] = 0.0
    for r in range(k):
        lam[sel[r]] = x[r]
    return True


@jit
def _complementary(Pm, PA, PB, idx, geo, m, side, ids, vn, lam, eps, rotation, w, scale):
    """Whether ``lam`` solves the LCP: ``lam >= 0`` and every pair's ``w = vn + A lam >= -eps``
    (allowing for the round-off of the terms ``A lam`` sums). Leaves ``A lam`` in ``w``."""
    for i in range(m):
        if lam[i] < 0.0:
            return False
    _apply_delassus(Pm, PA, PB, idx, geo, m, side, ids, lam, rotation, w, scale)
    for i in range(m):
        if vn[i] + w[i] < -(eps + 1e-14 * scale[i]):
            return False
    return True


@jit
def _entering(m, vn, w, scale, active, skip, eps):
    """The pair outside the set that approaches most (``vn + A lam`` most negative, beyond
    ``eps`` and round-off), -1 if none does."""
    t = -1
    for i in range(m):
        wi = vn[i] + w[i]
        if (not active[i] and not skip[i] and wi < -(eps + 1e-14 * scale[i])
                and (t < 0 or wi < vn[t] + w[t])):
            t = i
    return t


@jit
def _nnls_add(Pm, PA, PB, idx, geo, m, B, side, ids, vn, lam, rotation, active, skip, t, s):
    """One outer step of :func:`_nnls`: pair ``t`` enters the set, whose solution ``s`` is
    taken where every impulse in it is positive, else ``lam`` steps towards it up to the first
    impulse that reaches zero, that pair leaves, and the set is solved again. Returns False on
    round-off that leaves no way on (a set of once independent columns no longer solves)."""
    active[t] = True
    for inner in range(m + 1):
        if not _solve_set(Pm, PA, PB, idx, geo, m, B, side, ids, vn, active, s, rotation):
            if inner > 0:  # a subset of columns that were independent: round-off
                return False
            active[t] = False  # a redundant contact: passed over until the set changes
            skip[t] = True
            return True
        if inner == 0 and s[t] <= 0.0:  # round-off: the pair cannot enter
            active[t] = False
            skip[t] = True
            return True
        alpha = 1.0
        drop = -1
        for i in range(m):
            if active[i] and s[i] <= 0.0:
                a = lam[i] / (lam[i] - s[i])
                if a < alpha:
                    alpha = a
                    drop = i
        if drop < 0:
            lam[:] = s
            skip[:] = False
            return True
        for i in range(m):
            if active[i]:
                lam[i] += alpha * (s[i] - lam[i])
        lam[drop] = 0.0
        active[drop] = False
        for i in range(m):
            if active[i] and lam[i] <= 0.0:
                lam[i] = 0.0
                active[i] = False
    return False


@jit
def _nnls(Pm, PA, PB, idx, geo, m, B, side, ids, vn, lam, eps, rotation):
    """The LCP's solution by Lawson and Hanson's active-set method for non-negative least
    squares: the compression impulses minimise the kinetic energy ``|c + B lam|^2 / 2`` over
    ``lam >= 0`` (``B^T c = vn``), whose optimality conditions are the LCP's. From ``lam = 0``
    it adds the most approaching pair to the set (:func:`_entering`) and solves the set,
    stepping back where an impulse would turn negative (:func:`_nnls_add`); each set's energy
    is lower than the last, so no set comes back and it ends after a few passes per pair, where
    trying every set took 2^n solves. True if it ends on a solution (:func:`_complementary`)."""
    active = np.zeros(m, np.bool_)
    skip = np.zeros(m, np.bool_)
    s = np.zeros(m)
    w = np.zeros(m)
    scale = np.zeros(m)
    lam[:] = 0.0
    for _ in range(3 * m + 10):
        t = _entering(m, vn, w, scale, active, skip, eps)
        if t < 0:
            return _complementary(Pm, PA, PB, idx, geo, m, side, ids, vn, lam, eps, rotation,
                                  w, scale)
        if not _nnls_add(Pm, PA, PB, idx, geo, m, B, side, ids, vn, lam, rotation, active, skip,
                         t, s):
            return False
        _apply_delassus(Pm, PA, PB, idx, geo, m, side, ids, lam, rotation, w, scale)
    return False


#: most pairs whose sets :func:`_enumerate` tries, where :func:`_nnls` ends on no solution
MAX_ENUMERATED_PAIRS = 10


@jit
def _enumerate(Pm, PA, PB, idx, geo, m, B, side, ids, vn, lam, eps, rotation):
    """The LCP's solution by trying every set of pairs in turn (2^m solves, only up to
    ``MAX_ENUMERATED_PAIRS``): the first whose solution is complementary. The fallback of
    :func:`_nnls`, which a degenerate jam (redundant contacts) can leave without one."""
    if m > MAX_ENUMERATED_PAIRS:
        return False
    active = np.zeros(m, np.bool_)
    w = np.empty(m)
    scale = np.empty(m)
    for mask in range(1, 1 << m):
        for i in range(m):
            active[i] = (mask >> i & 1) == 1
        if _solve_set(Pm, PA, PB, idx, geo, m, B, side, ids, vn, active, lam, rotation) and \
                _complementary(Pm, PA, PB, idx, geo, m, side, ids, vn, lam, eps, rotation, w,
                               scale):
            return True
    return False


@jit
def jam_impulses(n, Pm, PA, PB, MAT, rotation, m, idx, geo, lam):
    """Impulses of the block solve (see the module docstring), not yet applied.

    Args:
        n: the number of bodies.
        m, idx, geo: the jam's pairs, as :func:`collect` returns them (m < 0: too many).
        lam: scratch of ``MAX_JAM_PAIRS`` impulses, filled for the first m rows.

    Returns:
        m, the number of rows to apply (0: nothing to do, or more than ``MAX_JAM_PAIRS`` pairs
        touching, or no solution found).
    """
    if m <= 0:
        return 0
    vn = geo[:m, JAM_VN].copy()
    vmax = np.abs(vn).max()
    if vmax == 0.0:
        return 0
    e = 1.0
    for i in range(m):
        e = min(e, MAT[idx[i], RESTITUTION])
    B, side, ids = _weighted_jacobian(Pm, PA, PB, n, idx, geo, m, rotation)
    sol = np.zeros(m)
    eps = 1e-12 * vmax
    if not (_nnls(Pm, PA, PB, idx, geo, m, B, side, ids, vn, sol, eps, rotation)
            or _enumerate(Pm, PA, PB, idx, geo, m, B, side, ids, vn, sol, eps, rotation)):
        return 0
    k = _poisson(Pm, PA, PB, idx, geo, m, side, ids, sol, rotation, e)
    if k == 0.0:
        return 0
    for i in range(m):
        lam[i] = k * sol[i]
    return m


#: most touching pairs the friction block takes (each pair stuck, sliding either way, or apart:
#: it tries up to 4^n sets); a larger jam with friction is solved without it, and flagged
MAX_FRICTION_PAIRS = 5
#: a frictional pair's states in the friction block: apart, stuck, sliding along +t (its
#: friction impulse -mu lam_n), sliding along -t (+mu lam_n). A frictionless pair: apart, on.
OFF, STICK, SLIDE_POS, SLIDE_NEG = 0, 1, 2, 3


@jit
def _rows(idx, geo, m):
    """The friction block's 2m rows: the m normal rows of ``geo`` and after them a tangential
    row per pair (its direction t = (-n_y, n_x), lever terms r x t and tangential velocity in
    the normal row's columns), so that ``_weighted_jacobian`` and ``_apply_delassus`` serve
    both."""
    idx2 = np.empty(2 * m, np.int64)
    geo2 = np.empty((2 * m, JAM_COLUMNS))
    for i in range(m):
        idx2[i] = idx[i]
        idx2[m + i] = idx[i]
        geo2[i] = geo[i]
        geo2[m + i] = geo[i]
        geo2[m + i, JAM_NX] = -geo[i, JAM_NY]
        geo2[m + i, JAM_NY] = geo[i, JAM_NX]
        geo2[m + i, JAM_CROSS_A] = geo[i, JAM_CROSS_TA]
        geo2[m + i, JAM_CROSS_B] = geo[i, JAM_CROSS_TB]
        geo2[m + i, JAM_VN] = geo[i, JAM_VT]
    return idx2, geo2


@jit
def _lu_solve(G, k, rhs):
    """Solve ``G^T y = rhs`` (G: k x k) in place in ``rhs``, on a copy of G; False if
    singular."""
    M = np.empty((k, k))
    for r in range(k):
        for c in range(k):
            M[r, c] = G[c, r]
    return _solve_small(M, rhs, k)


@jit
def _unknowns(m, mu, state):
    """The unknowns of a set of pair states: each pair on has its normal impulse, whose column
    (``col``, a row of ``lam2``) also carries ``sig`` times it as friction on row ``m + i`` (a
    sliding pair's ``-/+ mu``); a stuck pair with friction also its friction impulse (row
    ``m + i``). Returns (col, sig, k)."""
    col = np.empty(2 * m, np.int64)
    sig = np.zeros(2 * m)
    k = 0
    for i in range(m):
        if state[i] == OFF:
            continue
        col[k] = i
        if state[i] == SLIDE_POS:
            sig[k] = -mu[i]
        elif state[i] == SLIDE_NEG:
            sig[k] = mu[i]
        k += 1
        if state[i] == STICK and mu[i] > 0.0:
            col[k] = m + i
            k += 1
    return col, sig, k


@jit
def _consistent(m, mu, state, geo2, lam2, w, scale, eps):
    """Whether a set's impulses ``lam2`` (``w = A lam2``) keep its states: normal impulses >= 0,
    a stuck pair's friction inside its cone, a sliding pair still slipping its way, a pair off
    not approaching (each to ``eps`` and the round-off of its sums)."""
    for i in range(m):
        if state[i] == OFF:
            if geo2[i, JAM_VN] + w[i] < -(eps + 1e-14 * scale[i]):
                return False
            continue
        if lam2[i] < 0.0:
            return False
        vt = geo2[m + i, JAM_VN] + w[m + i]
        tol_t = eps + 1e-14 * scale[m + i]
        if state[i] == STICK and abs(lam2[m + i]) > mu[i] * lam2[i] * (1.0 + 1e-12):
            return False
        if (state[i] == SLIDE_POS and vt < -tol_t) or (state[i] == SLIDE_NEG and vt > tol_t):
            return False
    return True


@jit
def _friction_set(Pm, PA, PB, m, idx2, geo2, B, side, ids, mu, state, lam2, w, scale, eps,
                  rotation):
    """Solve the friction block for one set of pair states (``state``): every pair on has no
    normal velocity left, a stuck pair no tangential velocity, and a sliding pair's friction is
    ``mu`` times its normal impulse against its slip. True if the solution keeps the states
    (:func:`_consistent`). Impulses in ``lam2`` (normal rows, then tangential),
    ``w = A lam2``.

    The unknowns' impulse columns (a sliding pair's: ``n -/+ mu t``) and the rows their
    velocities are measured on differ, so the system ``Br^T Bc x = -v`` is not symmetric. A
    Householder QR of the mass-weighted ``Bc`` with its reflectors applied to ``Br`` gives it
    as ``G^T R x`` without forming ``Br^T Bc`` (``G``: the top of ``Q^T Br``; ``G = R`` when
    nothing slides, the frictionless block's ``R^T R``), then two refinements with the residual
    from the bodies' impulse sums."""
    col, sig, k = _unknowns(m, mu, state)
    rows = B.shape[0]
    if rows < k:
        return False
    Mx = np.empty((rows, 2 * k))
    for u in range(k):
        c = col[u]
        for r in range(rows):
            Mx[r, k + u] = B[r, c]
            Mx[r, u] = B[r, c] + (sig[u] * B[r, c + m] if sig[u] != 0.0 else 0.0)
    if not _householder(Mx, k):
        return False
    rhs = np.empty(k)
    for u in range(k):
        rhs[u] = -geo2[col[u], JAM_VN]
    x = np.zeros(k)
    d = rhs.copy()
    for _ in range(_REFINEMENTS + 1):
        if not _lu_solve(Mx[:k, k:], k, d):
            return False
        _r_solve(Mx, k, d)
        lam2[:] = 0.0
        for u in range(k):
            x[u] += d[u]
            lam2[col[u]] += x[u]
            if sig[u] != 0.0:
                lam2[col[u] + m] += sig[u] * x[u]
        _apply_delassus(Pm, PA, PB, idx2, geo2, 2 * m, side, ids, lam2, rotation, w, scale)
        for u in range(k):
            d[u] = rhs[u] - w[col[u]]
    return _consistent(m, mu, state, geo2, lam2, w, scale, eps)


@jit
def jam_friction_impulses(n, Pm, PA, PB, MAT, rotation, m, idx, geo, lam, lamt):
    """The block solve of a jam with contact friction: normal and tangential impulses of all
    touching pairs at once, not yet applied (the frictionless :func:`jam_impulses` loses the
    friction, and a self-locking wedge squirts out).

    Compression: every set of pair states is tried (``OFF``..``SLIDE_NEG``, the first pair
    fastest, a pair stuck before sliding) until one is consistent (:func:`_friction_set`):
    Coulomb's law at every pair, no pair left approaching. Restitution follows Poisson's
    hypothesis on the whole impulse, with the smallest ``e`` of the pairs: the impulses are
    ``(1 + e) lam``, so every pair's normal velocity, and a stuck pair's tangential one, comes
    out ``-e`` times what it was, and a sliding pair's friction stays ``mu`` times its normal
    impulse (as a lone contact's). Repeating only the normal impulses instead (a lone contact's
    stuck friction is not repeated) kicked a locked wedge's 1 kg puck out at 25 m/s at e = 1:
    the stuck friction that balanced the heavy disk's push was missing. No energy is gained:
    the frictionless block's guard, :func:`_poisson`.

    Args:
        n: the number of bodies.
        m, idx, geo: the jam's pairs, as :func:`collect` returns them (m < 0: too many).
        lam, lamt: scratch of ``MAX_JAM_PAIRS`` normal and tangential impulses, filled for the
            first m rows.

    Returns:
        m, the number of rows to apply (0: nothing to do); -1 where this solve does not apply
        (no pair with friction, more than ``MAX_FRICTION_PAIRS`` pairs, no consistent set):
        the frictionless block is the caller's fallback.
    """
    if m <= 0 or m > MAX_FRICTION_PAIRS:
        return -1
    mu = np.empty(m)
    radix = np.empty(m, np.int64)
    sets = 1
    e = 1.0
    for i in range(m):
        mu[i] = MAT[idx[i], FRICTION]
        radix[i] = 4 if mu[i] > 0.0 else 2
        sets *= radix[i]
        e = min(e, MAT[idx[i], RESTITUTION])
    if sets == 1 << m:
        return -1
    idx2, geo2 = _rows(idx, geo, m)
    vmax = 0.0
    for r in range(2 * m):
        vmax = max(vmax, abs(geo2[r, JAM_VN]))
    if vmax == 0.0:
        return 0
    B, side, ids = _weighted_jacobian(Pm, PA, PB, n, idx2, geo2, 2 * m, rotation)
    state = np.zeros(m, np.int64)
    lam2 = np.zeros(2 * m)
    w = np.empty(2 * m)
    scale = np.empty(2 * m)
    found = False
    for code in range(1, sets):
        rest = code
        for i in range(m):
            state[i] = rest % radix[i]
            rest //= radix[i]
        if _friction_set(Pm, PA, PB, m, idx2, geo2, B, side, ids, mu, state, lam2, w, scale,
                         1e-12 * vmax, rotation):
            found = True
            break
    if not found:
        return -1
    k = _poisson(Pm, PA, PB, idx2, geo2, 2 * m, side, ids, lam2, rotation, e)
    if k == 0.0:
        return -1
    for r in range(2 * m):
        lam2[r] *= k
    for i in range(m):
        lam[i] = lam2[i]
        lamt[i] = lam2[m + i]
    return m
