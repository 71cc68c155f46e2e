"""Jams: a block solve of all touching pairs at once, when sequential impulses cannot converge.

The solvers resolve simultaneous contacts by sequential impulses swept in pair order
(``physics.solvers``). A light body pinned between a heavy one and a cushion loses only
``m_light / m_heavy`` of the approach per sweep, so at a mass ratio of 1e6 the sweeps would need
millions; after ``MAX_SWEEPS`` the solvers call :func:`jam_impulses` instead.

The normal impulses ``lam >= 0`` of all pairs within ``slop`` are found together as the solution
of the linear complementarity problem ``w = vn + A lam >= 0, lam . w = 0`` (A: the pairs' Delassus
matrix, from inverse masses and lever arms), by trying active sets (up to ``MAX_JAM_PAIRS``
pairs, 2^n sets). That is the compression phase: the minimiser of the kinetic energy over
non-negative impulses, which leaves no pair approaching. Restitution follows Poisson's
hypothesis with the smallest ``e`` of the touching pairs: the impulses are ``(1 + e) lam``, which
change the kinetic energy by ``-(1 - e^2)/2 lam.A.lam <= 0`` (0 for e = 1). Friction is not part
of the block (the sweeps before it applied it).
"""

from __future__ import annotations

import numpy as np

from spinstrike.physics.events import pair_bodies, pair_geometry
from spinstrike.physics.jit import jit
from spinstrike.physics.layout import (
    HALF_H,
    HALF_W,
    INV_INERTIA,
    INV_MASS,
    RESTITUTION,
    Table,
    X,
    Y,
)

__all__ = ["JAM_COLUMNS", "MAX_JAM_PAIRS", "jam_impulses"]


#: most touching pairs the block solve takes (it tries up to 2^n active sets)
MAX_JAM_PAIRS = 10
#: the per-pair rows it returns: unit normal (a to b), lever terms r x n of a and b, contact
#: point (m), normal relative velocity (m/s)
JAM = Table("jam pair", "nx", "ny", "cross_a", "cross_b", "px", "py", "vn", prefix="JAM_")
JAM_NX, JAM_NY, JAM_CROSS_A, JAM_CROSS_B, JAM_PX, JAM_PY, JAM_VN = JAM
JAM_COLUMNS = len(JAM)


@jit
def _collect(S, Pm, hw, PA, PB, slop, idx, geo):
    """The pairs within ``slop``: their indices and geometry rows. -1 if there are too many."""
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
            m += 1
    return m


@jit
def _side(PA, PB, idx, geo, i, side):
    """(body, sign, lever r x n) of one side of pair row i (side 0: a, 1: b)."""
    if side == 0:
        return PA[idx[i]], -1.0, geo[i, JAM_CROSS_A]
    return PB[idx[i]], 1.0, geo[i, JAM_CROSS_B]


@jit
def _delassus(Pm, PA, PB, n, idx, geo, m, rotation):
    """``A[i, k]``: change of pair i's normal velocity per unit impulse on pair k."""
    A = np.zeros((m, m))
    for i in range(m):
        for k in range(m):
            acc = 0.0
            for si in range(2):
                x, sgn_i, ci = _side(PA, PB, idx, geo, i, si)
                if x >= n:
                    continue
                for sk in range(2):
                    y, sgn_k, ck = _side(PA, PB, idx, geo, k, sk)
                    if y != x:
                        continue
                    term = Pm[x, INV_MASS] * (geo[i, JAM_NX] * geo[k, JAM_NX]
                                              + geo[i, JAM_NY] * geo[k, JAM_NY])
                    if rotation:
                        term += Pm[x, INV_INERTIA] * ci * ck
                    acc += sgn_i * sgn_k * term
            A[i, k] = acc
    return A


@jit
def _solve_small(M, rhs, k):
    """Solve the k x k system ``M x = rhs`` in place (partial pivoting); False if singular."""
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
def _try_active_set(A, vn, mask, m, lam, eps):
    """Solve ``A_SS lam_S = -vn_S`` for the set S in ``mask``; True if lam >= 0 and w >= -eps."""
    sel = np.empty(m, np.int64)
    k = 0
    for i in range(m):
        if mask >> i & 1:
            sel[k] = i
            k += 1
    M = np.empty((k, k))
    rhs = np.empty(k)
    for r in range(k):
        rhs[r] = -vn[sel[r]]
        for q in range(k):
            M[r, q] = A[sel[r], sel[q]]
    # (k's size passed as len(rhs): k itself, a literal 0 at the first pass of numba's type
    # inference, compiled _solve_small twice)
    if not _solve_small(M, rhs, len(rhs)):
        return False
    for r in range(k):
        if rhs[r] < 0.0:
            return False
    lam[:] = 0.0
    for r in range(k):
        lam[sel[r]] = rhs[r]
    for i in range(m):
        w = vn[i]
        for q in range(m):
            w += A[i, q] * lam[q]
        if w < -eps:
            return False
    return True


@jit
def _energy_norm(Pm, PA, PB, n, idx, geo, m, lam, rotation):
    """``lam.A.lam`` summed per body as ``invm |dp|^2 + invI dL^2`` (never negative)."""
    total = 0.0
    for x in range(n):
        px = 0.0
        py = 0.0
        lx = 0.0
        for i in range(m):
            for side in range(2):
                y, sgn, c = _side(PA, PB, idx, geo, i, side)
                if y == x:
                    px += sgn * lam[i] * geo[i, JAM_NX]
                    py += sgn * lam[i] * geo[i, JAM_NY]
                    lx += sgn * lam[i] * c
        total += Pm[x, INV_MASS] * (px * px + py * py)
        if rotation:
            total += Pm[x, INV_INERTIA] * lx * lx
    return total


@jit
def jam_impulses(S, Pm, hw, PA, PB, MAT, slop, rotation, idx, geo, lam):
    """Impulses of the block solve (see the module docstring), not yet applied.

    Args:
        idx, geo, lam: scratch of ``MAX_JAM_PAIRS`` pair indices, geometry rows
            (``JAM_COLUMNS``) and impulses, filled for the first m rows.

    Returns:
        m, the number of rows to apply (0: nothing to do, or more than ``MAX_JAM_PAIRS`` pairs
        touching, or no solution found).
    """
    n = S.shape[0]
    m = _collect(S, Pm, hw, PA, PB, slop, idx, geo)
    if m <= 0:
        return 0
    vn = geo[:m, JAM_VN].copy()
    vmax = np.abs(vn).max()
    if vmax == 0.0:
        return 0
    e = 1.0
    for i in range(m):
        e = min(e, MAT[idx[i], RESTITUTION])
    A = _delassus(Pm, PA, PB, n, idx, geo, m, rotation)
    sol = np.zeros(m)
    found = False
    for mask in range(1, 1 << m):
        if _try_active_set(A, vn, mask, m, sol, 1e-12 * vmax):
            found = True
            break
    if not found:
        return 0
    # Energy guard. With exact arithmetic lam.vn = -lam.A.lam, and k lam (k = 1 + e) changes
    # the kinetic energy by k lam.vn + k^2/2 lam.A.lam <= 0. An ill-conditioned A (mass ratios
    # of 1e11) solves lam only to ~1e-5, which at e = 1 added that much energy, so k is capped
    # where the change computed from this lam is zero, -2 lam.vn / lam.A.lam.
    lv = 0.0
    for i in range(m):
        lv += sol[i] * vn[i]
    lal = _energy_norm(Pm, PA, PB, n, idx, geo, m, sol, rotation)
    if not (lv < 0.0 and lal > 0.0):
        return 0
    k = min(1.0 + e, -2.0 * lv / lal)
    for i in range(m):
        lam[i] = k * sol[i]
    return m
