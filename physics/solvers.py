"""The solvers, written once for a batch: one numba kernel steps one element; two thin wrappers
run it over the batch (serially, or in parallel threads for large batches).

``exact`` (DESIGN §5): event driven. All pairs get a time of impact (``events.time_of_impact``);
the world flies in closed form to the earliest, resolves every pair then within ``tolerance`` and
approaching (the *simultaneous-contact rule*: sequential impulses swept in pair order until no pair
approaches, at most ``MAX_SWEEPS`` sweeps — this reproduces Newton's cradle), and searches again
only for the pairs whose bodies changed. Two guards keep a step finite:

* a run of *resting bounces* (impacts closing slower than ``zeno_speed``, or time-of-impact
  searches that stall while the pair is within ``tolerance``: an inelastic body pinned by a force,
  or sliding along another, makes infinitely many in finite time) or ``max_events`` events end
  the event loop,
  and the rest of the step is *settled* by the fixed-step contact solver below, with substeps
  short enough that no pair closes by more than half the depth at which its overlap is still
  seen (``_settle_substeps``). The element is
  flagged (``stats[:, STAT_FALLBACK]``), never hung, never left overlapping.

``fixed``: ``substeps`` symplectic-Euler substeps; after each, pairs that overlap (or are within
``slop``) and approach get impulses from that (overlapped) pose, ``iterations`` sweeps, then
overlaps are pushed apart along the normal in proportion to the inverse masses.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from physics.events import pair_geometry, time_of_impact
from physics.impulse import resolve
from physics.layout import (
    CHECKPOINT,
    FRICTION,
    FRICTION_DECEL,
    HALF_LENGTH,
    INV_INERTIA,
    INV_MASS,
    NONE,
    OMEGA,
    RADIUS,
    RESTITUTION,
    SPIN_DECEL,
    STAT_CONTACTS,
    STAT_EVENTS,
    STAT_FALLBACK,
    STAT_ITERATIONS,
    STAT_SUBSTEPS,
    VX,
    VY,
    X,
    Y,
)
from physics.motion import flight

__all__ = [
    "MAX_SWEEPS",
    "exact_batch_parallel",
    "exact_batch_serial",
    "fixed_batch_parallel",
    "fixed_batch_serial",
]

#: sequential-impulse sweeps over simultaneous contacts at one event
MAX_SWEEPS = 64
#: most substeps the settling integration of one step may take
MAX_SETTLE_SUBSTEPS = 1_000_000

jit = numba.njit(cache=True, nogil=True)
jit_parallel = numba.njit(cache=True, nogil=True, parallel=True)


@jit
def _record(p, t, px, py, nx, ny, j, jt, cpair, ctime, cgeo, cimp, stats):
    k = stats[STAT_CONTACTS]
    if k < cpair.shape[0]:
        cpair[k] = p
        ctime[k] = t
        cgeo[k, 0] = px
        cgeo[k, 1] = py
        cgeo[k, 2] = nx
        cgeo[k, 3] = ny
        cimp[k, 0] = j
        cimp[k, 1] = jt
    stats[STAT_CONTACTS] = k + 1


@jit
def _advance(S, Pm, F, t, rotation, table_friction):
    """Closed-form flight of every body by t seconds."""
    for i in range(S.shape[0]):
        st = S[i]
        pr = Pm[i]
        if pr[INV_MASS] == 0.0 and (pr[INV_INERTIA] == 0.0 or st[OMEGA] == 0.0):
            continue
        ima = pr[INV_MASS]
        x, y, an, vx, vy, w = flight(st, pr, F[i, 0] * ima, F[i, 1] * ima, t, rotation,
                                     table_friction)
        st[0] = x
        st[1] = y
        st[2] = an
        st[3] = vx
        st[4] = vy
        st[5] = w


@jit
def _search(p, S, Pm, F, hw, PA, PB, horizon, tol, max_iterations, tmp_a, tmp_b, rotation,
            table_friction):
    n = S.shape[0]
    a = PA[p]
    b = PB[p]
    if b >= n:
        return time_of_impact(S[a], Pm[a], F[a], S[a], Pm[a], F[a], b - n, hw[0], hw[1], horizon,
                              tol, max_iterations, tmp_a, tmp_b, rotation, table_friction)
    return time_of_impact(S[a], Pm[a], F[a], S[b], Pm[b], F[b], -1, hw[0], hw[1], horizon, tol,
                          max_iterations, tmp_a, tmp_b, rotation, table_friction)


@jit
def _contact_pass(S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, contact_friction,
                  changed, cpair, ctime, cgeo, cimp, stats):
    """One sweep: resolve every pair within ``slop`` and approaching. Returns (any, resting)."""
    n = S.shape[0]
    hit = False
    resting = 0
    for p in range(PA.shape[0]):
        a = PA[p]
        b = PB[p]
        wall = b - n if b >= n else -1
        bb = a if wall >= 0 else b
        g, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S[a], Pm[a], S[bb], Pm[bb],
                                                                  wall, hw[0], hw[1])
        if g <= slop and vn < 0.0:
            px = S[a, X] + oax + ka * nx
            py = S[a, Y] + oay + ka * ny
            j, jt, vn0 = resolve(S[a], Pm[a], S[bb], Pm[bb], wall >= 0, nx, ny, oax, oay, ka,
                                 obx, oby, kb, MAT[p, RESTITUTION], MAT[p, FRICTION], rotation,
                                 contact_friction)
            _record(p, t, px, py, nx, ny, j, jt, cpair, ctime, cgeo, cimp, stats)
            if -vn0 < zeno_speed:
                resting += 1
            changed[a] = True
            if wall < 0:
                changed[b] = True
            hit = True
    return hit, resting


@jit
def _separate(S, Pm, hw, PA, PB):
    """Push overlapping pairs apart along the normal, in proportion to their inverse masses.

    One sweep in pair order; returns the deepest overlap it corrected (0 if none). A sweep can
    push a body into a third one (a puck pressed between the mallet and a cushion), so callers
    that must leave no overlap repeat it (``fixed_element``'s ``separate_sweeps``).
    """
    n = S.shape[0]
    deepest = 0.0
    for p in range(PA.shape[0]):
        a = PA[p]
        b = PB[p]
        wall = b - n if b >= n else -1
        bb = a if wall >= 0 else b
        g, nx, ny, _, _, _, _, _, _, _ = pair_geometry(S[a], Pm[a], S[bb], Pm[bb], wall, hw[0],
                                                       hw[1])
        if g < 0.0:
            wa = Pm[a, INV_MASS]
            wb = Pm[b, INV_MASS] if wall < 0 else 0.0
            total = wa + wb
            if total > 0.0:
                if -g > deepest:
                    deepest = -g
                depth = -g / total
                S[a, X] -= nx * depth * wa
                S[a, Y] -= ny * depth * wa
                if wall < 0:
                    S[b, X] += nx * depth * wb
                    S[b, Y] += ny * depth * wb
    return deepest


@jit
def _kick(S, Pm, F, h, rotation, table_friction):
    """Velocity update of one substep: applied forces, cloth friction; then positions."""
    for i in range(S.shape[0]):
        st = S[i]
        pr = Pm[i]
        ima = pr[INV_MASS]
        st[VX] += F[i, 0] * ima * h
        st[VY] += F[i, 1] * ima * h
        if table_friction:
            dv = pr[FRICTION_DECEL] * h
            if dv > 0.0:
                speed = math.sqrt(st[VX] ** 2 + st[VY] ** 2)
                f = max(speed - dv, 0.0) / speed if speed > 0.0 else 0.0
                st[VX] *= f
                st[VY] *= f
            dw = pr[SPIN_DECEL] * h
            if dw > 0.0 and rotation:
                w = st[OMEGA]
                st[OMEGA] = max(abs(w) - dw, 0.0) * (1.0 if w > 0.0 else -1.0)
        st[X] += st[VX] * h
        st[Y] += st[VY] * h
        if rotation:
            st[2] += st[OMEGA] * h


@jit
def fixed_element(S, Pm, F, hw, PA, PB, MAT, T, substeps, iterations, slop, t0, rotation,
                  contact_friction, table_friction, cpair, ctime, cgeo, cimp, stats,
                  separate_sweeps=1):
    """Advance one element by T seconds in ``substeps`` fixed substeps.

    ``separate_sweeps``: positional-correction sweeps per substep, repeated while one still
    corrects an overlap deeper than ``slop``. The plain fixed solver uses 1 (its documented,
    cheap behaviour); the exact solver's settling uses ``MAX_SWEEPS`` so that a chain of
    contacts (mallet -> puck -> cushion) is not left overlapping.
    """
    changed = np.zeros(S.shape[0], np.bool_)
    h = T / substeps
    for k in range(substeps):
        _kick(S, Pm, F, h, rotation, table_friction)
        t = t0 + (k + 1) * h
        for _ in range(iterations):
            hit, resting = _contact_pass(S, Pm, hw, PA, PB, MAT, slop, 0.0, t, rotation,
                                         contact_friction, changed, cpair, ctime, cgeo, cimp,
                                         stats)
            if not hit:
                break
        for _ in range(separate_sweeps):
            if _separate(S, Pm, hw, PA, PB) <= slop:
                break
    stats[STAT_SUBSTEPS] += substeps


@jit
def _settle_substeps(S, Pm, F, PA, PB, T, settle_substep):
    """Substeps for settling, so that no pair closes by more than it can overlap undetected.

    A body-body overlap is seen while it is shallower than ``rho_a + rho_b`` (two zero-thickness
    rods: the shorter half-length), a cushion's at any depth (it is a half-plane).
    """
    n = S.shape[0]
    speed = np.zeros(n)
    for i in range(n):
        st = S[i]
        pr = Pm[i]
        speed[i] = (math.sqrt(st[VX] ** 2 + st[VY] ** 2) + abs(st[OMEGA]) * pr[HALF_LENGTH]
                    + math.sqrt(F[i, 0] ** 2 + F[i, 1] ** 2) * pr[INV_MASS] * T)
    h = settle_substep
    for p in range(PA.shape[0]):
        a = PA[p]
        b = PB[p]
        if b >= n:
            continue
        size = Pm[a, RADIUS] + Pm[b, RADIUS]
        if size == 0.0:
            size = min(Pm[a, HALF_LENGTH], Pm[b, HALF_LENGTH])
        closing = speed[a] + speed[b]
        if closing > 0.0 and 0.5 * size / closing < h:
            h = 0.5 * size / closing
    steps = math.ceil(T / h)
    return max(1, min(steps, MAX_SETTLE_SUBSTEPS))


@jit
def exact_element(S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
                  zeno_impacts, settle_substep, rotation, contact_friction, table_friction,
                  cpair, ctime, cgeo, cimp, stats):
    """Advance one element by dt seconds, event by event."""
    n_pairs = PA.shape[0]
    toi = np.empty(n_pairs)
    kind = np.empty(n_pairs, np.int8)
    tmp_a = np.empty(6)
    tmp_b = np.empty(6)
    changed = np.zeros(S.shape[0], np.bool_)
    iterations = 0
    for p in range(n_pairs):
        tc, k, it = _search(p, S, Pm, F, hw, PA, PB, dt, tol, max_iterations, tmp_a, tmp_b,
                            rotation, table_friction)
        toi[p] = tc
        kind[p] = k
        iterations += it
    t_now = 0.0
    events = 0
    resting = 0
    while True:
        best = -1
        t_best = dt
        for p in range(n_pairs):
            if kind[p] != NONE and (toi[p] < t_best or (best == -1 and toi[p] <= t_best)):
                best = p
                t_best = toi[p]
        if t_best > t_now:
            _advance(S, Pm, F, t_best - t_now, rotation, table_friction)
            t_now = t_best
        if best == -1:
            break
        events += 1
        changed[:] = False
        if kind[best] == CHECKPOINT:
            # a search that stalls while the pair is in contact is a sliding/rolling contact:
            # it counts toward settling like a resting bounce
            a = PA[best]
            b = PB[best]
            wall = b - S.shape[0] if b >= S.shape[0] else -1
            bb = a if wall >= 0 else b
            g = pair_geometry(S[a], Pm[a], S[bb], Pm[bb], wall, hw[0], hw[1])[0]
            if g <= tol:
                resting += 1
        else:
            for _ in range(MAX_SWEEPS):
                hit, r = _contact_pass(S, Pm, hw, PA, PB, MAT, tol, zeno_speed, t_now, rotation,
                                       contact_friction, changed, cpair, ctime, cgeo, cimp, stats)
                resting += r
                if not hit:
                    break
        horizon = dt - t_now
        for p in range(n_pairs):
            if p == best or changed[PA[p]] or (PB[p] < S.shape[0] and changed[PB[p]]):
                tc, k, it = _search(p, S, Pm, F, hw, PA, PB, horizon, tol, max_iterations, tmp_a,
                                    tmp_b, rotation, table_friction)
                toi[p] = t_now + tc if k != NONE else dt
                kind[p] = k
                iterations += it
        if events >= max_events or resting >= zeno_impacts:
            if t_now < dt:
                substeps = _settle_substeps(S, Pm, F, PA, PB, dt - t_now, settle_substep)
                fixed_element(S, Pm, F, hw, PA, PB, MAT, dt - t_now, substeps, MAX_SWEEPS, tol,
                              t_now, rotation, contact_friction, table_friction, cpair, ctime,
                              cgeo, cimp, stats, MAX_SWEEPS)
                stats[STAT_FALLBACK] = 1
            break
    stats[STAT_EVENTS] += events
    stats[STAT_ITERATIONS] += iterations


@jit_parallel
def exact_batch_parallel(S, Pm, F, HW, PA, PB, MAT, dt, tol, max_events, max_iterations,
                         zeno_speed, zeno_impacts, settle_substep, rotation, contact_friction,
                         table_friction, cpair, ctime, cgeo, cimp, stats):
    """``exact_element`` over the batch, in parallel threads."""
    for b in numba.prange(S.shape[0]):
        exact_element(S[b], Pm[b], F[b], HW[b], PA, PB, MAT[b], dt, tol, max_events,
                      max_iterations, zeno_speed, zeno_impacts, settle_substep, rotation,
                      contact_friction, table_friction, cpair[b], ctime[b], cgeo[b], cimp[b],
                      stats[b])


@jit
def exact_batch_serial(S, Pm, F, HW, PA, PB, MAT, dt, tol, max_events, max_iterations,
                       zeno_speed, zeno_impacts, settle_substep, rotation, contact_friction,
                       table_friction, cpair, ctime, cgeo, cimp, stats):
    """``exact_element`` over the batch, in this thread."""
    for b in range(S.shape[0]):
        exact_element(S[b], Pm[b], F[b], HW[b], PA, PB, MAT[b], dt, tol, max_events,
                      max_iterations, zeno_speed, zeno_impacts, settle_substep, rotation,
                      contact_friction, table_friction, cpair[b], ctime[b], cgeo[b], cimp[b],
                      stats[b])


@jit_parallel
def fixed_batch_parallel(S, Pm, F, HW, PA, PB, MAT, dt, substeps, iterations, rotation,
                         contact_friction, table_friction, cpair, ctime, cgeo, cimp, stats):
    """``fixed_element`` over the batch, in parallel threads."""
    for b in numba.prange(S.shape[0]):
        fixed_element(S[b], Pm[b], F[b], HW[b], PA, PB, MAT[b], dt, substeps, iterations, 0.0,
                      0.0, rotation, contact_friction, table_friction, cpair[b], ctime[b],
                      cgeo[b], cimp[b], stats[b])


@jit
def fixed_batch_serial(S, Pm, F, HW, PA, PB, MAT, dt, substeps, iterations, rotation,
                       contact_friction, table_friction, cpair, ctime, cgeo, cimp, stats):
    """``fixed_element`` over the batch, in this thread."""
    for b in range(S.shape[0]):
        fixed_element(S[b], Pm[b], F[b], HW[b], PA, PB, MAT[b], dt, substeps, iterations, 0.0,
                      0.0, rotation, contact_friction, table_friction, cpair[b], ctime[b],
                      cgeo[b], cimp[b], stats[b])
