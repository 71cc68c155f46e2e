"""The solvers, written once for a batch: one numba kernel steps one element of a world
(``physics.kernels`` runs it over the batch, serially or in parallel threads).

``exact`` (``docs/design.md`` §4): event driven. All pairs get a time of impact
(``events.time_of_impact``); the world flies in closed form to the earliest, resolves every pair
then within ``tolerance`` and approaching (the *simultaneous-contact rule*: sequential impulses
swept in pair order until no pair approaches, at most ``MAX_SWEEPS`` sweeps — this reproduces
Newton's cradle; if pairs still approach after that, a *jam*, one block solve of all touching pairs
removes the rest, ``physics.jam``), and searches again only for the pairs whose bodies changed. Two
guards keep a step finite (a third case needs neither: a disk its force pushes into a cushion
comes to rest on it, ``_rest_on_cushions``):

* a run of *resting bounces* (impacts closing slower than ``zeno_speed``, or time-of-impact
  searches that stall while the pair is within ``tolerance``: an inelastic body pinned by a force,
  or sliding along another, makes infinitely many in finite time) or ``max_events`` events end
  the event loop,
  and the rest of the step is *settled* by the fixed-step contact solver below, with substeps
  short enough that no pair closes by more than half the depth at which its overlap is still
  seen (``_settle_substeps``), at most ``MAX_SETTLE_SUBSTEPS``. The element is flagged
  (``stats[:, STAT_FALLBACK]``: ``FALLBACK_SETTLED``, or ``FALLBACK_CAPPED`` where the cap was
  reached and the no-overlap bound no longer holds), never hung.

``fixed``: ``substeps`` symplectic-Euler substeps; after each, pairs that overlap (or are within
``slop``) and approach get impulses from that (overlapped) pose, ``iterations`` sweeps, then
overlaps are pushed apart along the normal in proportion to the inverse masses.

Both take a :data:`Trace` (the *trace hook*, below): a renderer's record of one element's
trajectory. Every step but a filmed strike's passes an empty one (:func:`untraced`), which
records nothing, so filmed and unfilmed steps run one compiled solver.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np

from spinstrike.physics.calendar import (
    box_meets_wall,
    boxes_meet,
    close_pairs,
    element_rows,
    empty_heap,
    find_sorted,
    heap_remove,
    heap_set,
    near_time,
    reachable_pairs,
    sort_by_xmin,
    sort_ints,
    speed_bound,
    stays_clear,
    swept_box,
    watch_insert,
    watch_remove,
)
from spinstrike.physics.contacts import cores_cross, flat_points, wall_frame
from spinstrike.physics.events import (
    far_apart,
    geometry,
    pair_bodies,
    pair_geometry,
    time_of_impact,
)
from spinstrike.physics.impulse import apply_impulse, relative_velocity_of, resolve, resolve_flat
from spinstrike.physics.jam import (
    JAM_COLUMNS,
    JAM_CROSS_A,
    JAM_CROSS_B,
    JAM_CROSS_TA,
    JAM_CROSS_TB,
    JAM_NX,
    JAM_NY,
    JAM_PX,
    JAM_PY,
    MAX_JAM_PAIRS,
    _solve_small,
    collect,
    jam_friction_impulses,
    jam_impulses,
)
from spinstrike.physics.jit import jit, jit_counted, jit_inline, jit_uncounted, static_if
from spinstrike.physics.layout import (
    ANGLE,
    BOX_XMAX,
    BOX_XMIN,
    CAL_HEAP_SIZE,
    CAL_STAMP,
    CAL_WATCH_SIZE,
    CHECKPOINT,
    FALLBACK_CAPPED,
    FALLBACK_JAMMED,
    FALLBACK_SETTLED,
    FRICTION,
    FRICTION_DECEL,
    FX,
    FY,
    H_P,
    HALF_H,
    HALF_LENGTH,
    HALF_W,
    INV_INERTIA,
    INV_MASS,
    LEVEL_CAN_JAM,
    LEVEL_MANY_BODIES,
    LEVEL_ONE_PAIR_FRICTION,
    NONE,
    OMEGA,
    RADIUS,
    REC_HELD,
    REC_J,
    REC_JT,
    REC_NX,
    REC_NY,
    REC_PX,
    REC_PY,
    REC_TIME,
    REC_WATCHED_J,
    REST_FX,
    REST_FY,
    REST_JX,
    REST_JY,
    REST_PX,
    REST_PY,
    REST_TX,
    REST_TY,
    RESTITUTION,
    SPIN_DECEL,
    STAT_CONTACTS,
    STAT_EVENTS,
    STAT_FALLBACK,
    STAT_ITERATIONS,
    STAT_SUBSTEPS,
    STAT_WATCH,
    STAT_WATCHED,
    STATE_COLUMNS,
    VX,
    VY,
    Table,
    X,
    Y,
)
from spinstrike.physics.motion import flight

__all__ = ["MAX_SWEEPS", "TRACE_COUNT", "Trace", "exact_element", "exact_many_element",
           "fixed_element", "many_rows", "rests_on",
           "trace_state", "untraced"]

#: sequential-impulse sweeps over simultaneous contacts at one event
MAX_SWEEPS = 64
#: most substeps the settling integration of one step may take
MAX_SETTLE_SUBSTEPS = 1_000_000
#: most positional-correction sweeps of a settle's last substep, the one whose overlap the step
#: hands on (the other substeps stop at ``MAX_SWEEPS``; see :func:`_settle`)
MAX_FINAL_SEPARATE_SWEEPS = 4096
#: a flat contact's two ends (rod-rod, or a rod on a cushion) are simultaneous (neither lands
#: first) when their core distances differ by less than this times the two half-lengths (a
#: rod's own twice on a cushion): parallel to ~1e-12 rad, the
#: round-off of the ends' coordinates
FLAT_TIE = 1e-12

# ---------------------------------------------------------------------------------------------
# The trace hook (renderers; envs/fast.py's strike). Optional and read-only for the physics:
# when a solver is given a Trace, it appends the element's whole state after every event that
# resolved contacts (exact) and after every substep (fixed, and the exact solver's settling).
# Between two entries every body is in closed-form free flight (``motion.flight``, what
# ``_advance`` computes), so the state at any time t is the last entry at or before t flown by
# the remaining time: frames sampled that way lie on the very trajectory the solver computed.
# Untraced steps pass an empty trace (:func:`untraced`, room for no entry), not None: traced
# and untraced steps then have the same argument types, so the solver is compiled once for
# both (None was a second specialisation of every solver function that takes the trace: ~20 s
# of the first video after a first training run). An empty trace's hook returns at once and
# the physics is bit for bit the same. (``None`` is still accepted: numba prunes the hook's
# ``is None`` branches.) Carried over by any rewrite of the event loop: call ``trace_state``
# wherever the state has just changed other than by free flight.
# ---------------------------------------------------------------------------------------------

#: a trajectory trace: ``time [K]`` (s, from the start of the step), ``state [K, N, 6]`` (the
#: element's state rows after the event, ``layout.STATE``), ``count`` (``TRACE_COUNT``)
Trace = namedtuple("Trace", ["time", "state", "count"])

#: a trace's counters: entries written, entries that did not fit (the trace is full)
TRACE_COUNT = Table("solver trace count", "entries", "dropped", prefix="TRACE_")
TRACE_ENTRIES, TRACE_DROPPED = TRACE_COUNT
_TRACE_COUNTERS = len(TRACE_COUNT)


@jit_inline
def untraced(n_bodies):
    """The trace of an untraced step: room for no entry, nothing counted (see the section
    comment)."""
    return Trace(np.empty(0), np.empty((0, n_bodies, STATE_COLUMNS)),
                 np.zeros(_TRACE_COUNTERS, dtype=np.int64))


@jit_inline
def trace_state(trace, t, S):
    """Append the time ``t`` (s) and the element's state ``S [N, 6]`` to ``trace`` (an empty
    trace, :func:`untraced`: nothing)."""
    if trace.time.shape[0] == 0:
        return
    n = trace.count[TRACE_ENTRIES]
    if n < trace.time.shape[0]:
        trace.time[n] = t
        for i in range(S.shape[0]):
            for c in range(S.shape[1]):
                trace.state[n, i, c] = S[i, c]
        trace.count[TRACE_ENTRIES] = n + 1
    else:
        trace.count[TRACE_DROPPED] += 1



@jit_inline
def _record(p, t, px, py, nx, ny, j, jt, cpair, crec, stats):
    k = stats[STAT_CONTACTS]
    m = cpair.shape[0]
    if k < m:
        cpair[k] = p
        crec[k, REC_TIME] = t
        crec[k, REC_PX] = px
        crec[k, REC_PY] = py
        crec[k, REC_NX] = nx
        crec[k, REC_NY] = ny
        crec[k, REC_J] = j
        crec[k, REC_JT] = jt
        crec[k, REC_HELD] = 0.0
    else:  # the records are full: summed in row m (layout.RECORD)
        crec[m, REC_J] += j
        crec[m, REC_JT] += jt
    stats[STAT_CONTACTS] = k + 1
    if p == stats[STAT_WATCH]:  # counted and summed also where the records are full
        stats[STAT_WATCHED] += 1
        crec[m, REC_WATCHED_J] += j


@jit_inline
def _advance(S, Pm, F, t, rotation, table_friction):
    """Closed-form flight of every body by t seconds."""
    for i in range(S.shape[0]):
        if Pm[i, INV_MASS] == 0.0 and (Pm[i, INV_INERTIA] == 0.0 or S[i, OMEGA] == 0.0):
            continue
        x, y, an, vx, vy, w = flight(S, Pm, F, i, t, rotation, table_friction)
        S[i, X] = x
        S[i, Y] = y
        S[i, ANGLE] = an
        S[i, VX] = vx
        S[i, VY] = vy
        S[i, OMEGA] = w


@jit_inline
def _search(p, S, Pm, F, hw, PA, PB, horizon, tol, max_iterations, rotation, flat, table_friction):
    """Time of impact of pair p; a pair provably apart for the whole horizon is settled by the
    inlined ``far_apart`` test without calling the search (which is what its first iteration
    would find, so the results are the same bit for bit)."""
    a, b, wall = pair_bodies(p, PA, PB, S.shape[0])
    if far_apart(S, Pm, F, a, b, wall, hw[HALF_W], hw[HALF_H], horizon, tol, rotation):
        return horizon, NONE, 1
    return time_of_impact(S, Pm, F, a, b, wall, hw[HALF_W], hw[HALF_H], horizon, tol,
                          max_iterations, rotation, flat, table_friction)


@jit_inline
def _contact(p, S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat, contact_friction,
             changed, cpair, crec, stats):
    """Resolve pair p if it is within ``slop`` and approaching. Returns (hit, resting)."""
    a, b, wall = pair_bodies(p, PA, PB, S.shape[0])
    g, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, b, wall, hw[HALF_W],
                                                              hw[HALF_H])
    if g <= slop:
        is_flat, hit, resting = _flat_if(flat, p, S, Pm, hw, a, b, wall, MAT, nx, ny,
                                         zeno_speed, t, rotation, contact_friction, changed,
                                         cpair, crec, stats)
        if is_flat:
            return hit, resting
    if g <= slop and vn < 0.0:
        px = S[a, X] + oax + ka * nx
        py = S[a, Y] + oay + ka * ny
        j, jt, vn0 = resolve(S, Pm, a, b, wall >= 0, nx, ny, oax, oay, ka, obx, oby, kb,
                             MAT[p, RESTITUTION], MAT[p, FRICTION], rotation, contact_friction)
        _record(p, t, px, py, nx, ny, j, jt, cpair, crec, stats)
        changed[a] = 1
        if wall < 0:
            changed[b] = 1
        return True, 1 if -vn0 < zeno_speed else 0
    return False, 0


@jit_inline
def _flat_pair(p, S, Pm, hw, a, b, wall, MAT, nx, ny, zeno_speed, t, rotation, contact_friction,
               changed, cpair, crec, stats):
    """:func:`_contact` for pair p within ``slop`` if it is resolved flat
    (``contacts.flat_points``, the time of impact's decision too): (True, hit, resting); if
    not, (False, False, 0) and :func:`_contact` goes on. One call of :func:`_flat_contact`, its
    ``is_wall`` a run-time bool: as two literal constants it compiled ``resolve_flat`` twice
    (~5 s of a first run each)."""
    other = b if wall < 0 else a  # (a cushion's points and body unused)
    is_flat, o1ax, o1ay, o1bx, o1by, d1, o2ax, o2ay, o2bx, o2by, d2 = flat_points(
        S[a, X], S[a, Y], S[a, ANGLE], Pm[a, HALF_LENGTH], Pm[a, RADIUS],
        Pm[a, INV_MASS] == 0.0, S[other, X], S[other, Y], S[other, ANGLE],
        Pm[other, HALF_LENGTH], Pm[other, RADIUS], Pm[other, INV_MASS] == 0.0, wall,
        hw[HALF_W], hw[HALF_H], nx, ny)
    if not is_flat:
        return False, False, 0
    hit, resting = _flat_contact(p, S, Pm, a, other, wall >= 0, MAT, nx, ny, o1ax, o1ay, o1bx,
                                 o1by, d1, o2ax, o2ay, o2bx, o2by, d2, zeno_speed, t, rotation,
                                 contact_friction, changed, cpair, crec, stats)
    return True, hit, resting


@jit_inline
def _not_flat(p, S, Pm, hw, a, b, wall, MAT, nx, ny, zeno_speed, t, rotation, contact_friction,
              changed, cpair, crec, stats):
    """What :func:`_flat_pair` returns in a world with no pair that can lie flat."""
    return False, False, 0


#: flat pairs (a rod on a rod or on a cushion), compiled only for worlds that have such a pair
#: (the ``flat`` flag, ``kernels.FLAGS``): a rod and disks, or pucks, never pay for it
_flat_if = static_if(_flat_pair, otherwise=_not_flat)


@jit_inline
def _flat_contact(p, S, Pm, a, b, is_wall, MAT, nx, ny, o1ax, o1ay, o1bx, o1by, d1, o2ax, o2ay,
                  o2bx, o2by, d2, zeno_speed, t, rotation, contact_friction, changed, cpair, crec,
                  stats):
    """:func:`_contact` for a flat rod-rod pair within ``slop`` (``contacts.flat_ends``), or a
    free rod flat on a cushion (``is_wall``, b = a: ``contacts.flat_wall_ends``): its two ends'
    impacts in turn, as the event-driven solver meets them at any small tilt
    (``impulse.resolve_flat``), so the outcome does not jump at the flat threshold; it is hit
    when either end approaches. Recorded once, at the impulses' centre of pressure."""
    tie = d2 - d1 <= FLAT_TIE * (Pm[a, HALF_LENGTH] + Pm[b, HALF_LENGTH])
    j, jt, vn0, ox, oy = resolve_flat(S, Pm, a, b, is_wall, nx, ny, o1ax, o1ay, o1bx, o1by, o2ax,
                                      o2ay, o2bx, o2by, tie, MAT[p, RESTITUTION],
                                      MAT[p, FRICTION], rotation, contact_friction)
    if vn0 >= 0.0:
        return False, 0
    _record(p, t, S[a, X] + ox, S[a, Y] + oy, nx, ny, j, jt, cpair, crec, stats)
    changed[a] = 1
    changed[b] = 1
    return True, 1 if -vn0 < zeno_speed else 0


@jit_uncounted
def _contact_pass(S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat, contact_friction,
                  changed, cpair, crec, stats, listed, n_listed):
    """One sweep: resolve every pair within ``slop`` and approaching, in pair order. Returns
    (any, resting). ``listed``: None (every pair), or the pairs ``listed[:n_listed]`` in pair
    order, a superset of those within ``slop`` (``calendar.close_pairs``): the same contacts
    in the same order, for the others are left alone either way."""
    hit = False
    resting = 0
    for k in range(PA.shape[0] if listed is None else n_listed):
        p = k if listed is None else listed[k]
        h, r = _contact(p, S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat,
                        contact_friction, changed, cpair, crec, stats)
        hit |= h
        resting += r
    return hit, resting


@jit_uncounted
def _watched_pass(S, Pm, F, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat, contact_friction,
                  table_friction, changed, cpair, crec, stats, watch, n_watch, near):
    """:func:`_contact_pass` over the calendar's watch list (pairs in pair order that may be
    within ``slop`` by now, ``physics.calendar``): every other pair is farther apart, so the
    sweep resolves the same contacts in the same order. A pair whose time has come but whose
    bodies are still apart gets a later time (``calendar.near_time`` from now)."""
    hit = False
    resting = 0
    for k in range(n_watch):
        p = watch[k]
        if near[p] > t:
            continue
        ahead = near_time(p, S, Pm, F, hw, PA, PB, slop, table_friction)
        if ahead > 0.0:  # still apart: not before then
            near[p] = t + ahead
            continue
        h, r = _contact(p, S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat,
                        contact_friction, changed, cpair, crec, stats)
        hit |= h
        resting += r
    return hit, resting


@jit
def _no_friction_block(n, Pm, PA, PB, MAT, rotation, m, idx, geo, lam, lamt):
    """A world without contact friction has no friction block (``_friction_block_if``)."""
    return -1


#: the friction block, compiled only for worlds with contact friction
_friction_block_if = static_if(jam_friction_impulses, otherwise=_no_friction_block)


@jit_counted
def _jam(S, Pm, hw, PA, PB, MAT, slop, t, rotation, contact_friction, changed, cpair, crec,
         stats):
    """The sweeps did not converge (a jam): apply and record the block solve's impulses, with
    friction (``jam.jam_friction_impulses``) where a pair has some and the block takes them,
    else without (``jam.jam_impulses``).

    Reference counted even when called from the many-body loop (``jit_counted``, which keeps
    the counting that uncounted callers would otherwise pass on): the block solve allocates."""
    idx = np.empty(MAX_JAM_PAIRS, np.int64)
    geo = np.empty((MAX_JAM_PAIRS, JAM_COLUMNS))
    lam = np.zeros(MAX_JAM_PAIRS)
    lamt = np.zeros(MAX_JAM_PAIRS)
    n = S.shape[0]
    pairs = collect(S, Pm, hw, PA, PB, slop, idx, geo)
    m = _friction_block_if(contact_friction, n, Pm, PA, PB, MAT, rotation, pairs, idx, geo, lam,
                           lamt)
    lost = m < 0
    if lost:
        m = jam_impulses(n, Pm, PA, PB, MAT, rotation, pairs, idx, geo, lam)
    for i in range(m):
        if lam[i] <= 0.0:
            continue
        p = idx[i]
        a, b, wall = pair_bodies(p, PA, PB, n)
        apply_impulse(S, Pm, a, b, wall >= 0, lam[i], geo[i, JAM_NX], geo[i, JAM_NY],
                      geo[i, JAM_CROSS_A], geo[i, JAM_CROSS_B], rotation)
        if lamt[i] != 0.0:
            apply_impulse(S, Pm, a, b, wall >= 0, lamt[i], -geo[i, JAM_NY], geo[i, JAM_NX],
                          geo[i, JAM_CROSS_TA], geo[i, JAM_CROSS_TB], rotation)
        # the frictionless block, where a pair has friction, lost it (a wedge that should lock
        # squirted out; W8): the step's fallback says so
        if lost and MAT[p, FRICTION] > 0.0 and stats[STAT_FALLBACK] < FALLBACK_JAMMED:
            stats[STAT_FALLBACK] = FALLBACK_JAMMED
        _record(p, t, geo[i, JAM_PX], geo[i, JAM_PY], geo[i, JAM_NX], geo[i, JAM_NY], lam[i],
                lamt[i], cpair, crec, stats)
        changed[a] = 1
        if wall < 0:
            changed[b] = 1


#: the block solve, compiled only for scenes whose contacts can jam (``kernels.FLAGS``)
_jam_if = static_if(_jam, level=LEVEL_ONE_PAIR_FRICTION)


@jit
def _sweeps(S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat, contact_friction, changed,
            cpair, crec, stats, sweeps, jam, listed, n_listed):
    """Up to ``sweeps`` contact passes until none hits; then, if ``jam`` and the last pass still
    hit, the block solve of the jam. Returns the number of resting bounces seen. ``listed``,
    ``n_listed``: the pairs the passes visit (:func:`_contact_pass`).

    ``jam`` is a compile-time flag (``kernels.FLAGS``): a world whose contacts cannot jam (one
    contact pair, no contact friction) never compiles the block solve."""
    resting = 0
    hit = False
    for _ in range(sweeps):
        hit, r = _contact_pass(S, Pm, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat,
                               contact_friction, changed, cpair, crec, stats, listed, n_listed)
        resting += r
        if not hit:
            break
    if hit:
        _jam_if(jam, S, Pm, hw, PA, PB, MAT, slop, t, rotation, contact_friction, changed,
                cpair, crec, stats)
    return resting


@jit_uncounted
def _watched_sweeps(S, Pm, F, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat,
                    contact_friction, table_friction, changed, cpair, crec, stats, sweeps, jam,
                    watch, n_watch, near):
    """:func:`_sweeps` with the passes over the calendar's watch list (:func:`_watched_pass`);
    the block solve of a jam, rare, still collects every touching pair itself."""
    resting = 0
    hit = False
    for _ in range(sweeps):
        hit, r = _watched_pass(S, Pm, F, hw, PA, PB, MAT, slop, zeno_speed, t, rotation, flat,
                               contact_friction, table_friction, changed, cpair, crec, stats,
                               watch, n_watch, near)
        resting += r
        if not hit:
            break
    if hit:
        _jam_if(jam, S, Pm, hw, PA, PB, MAT, slop, t, rotation, contact_friction, changed,
                cpair, crec, stats)
    return resting


@jit
def _share(im, ii, c, equal):
    """(translation weight, rotation weight) of one body in a positional correction along n.

    ``c`` is the lever arm ``r x n``. Physical shares (``equal`` False) are the terms of the
    effective inverse mass, ``1/m`` and ``c^2 / I``; equal shares give every movable body a total
    of 1, split between translation and rotation in the proportion of those terms.
    """
    wt = im
    wr = ii * c * c
    if equal:
        total = wt + wr
        if total > 0.0:
            wt = wt / total
            wr = wr / total
    return wt, wr


@jit
def _separate(S, Pm, hw, PA, PB, weighted, rotate, slop, rows, n_listed, moved):
    """Push overlapping pairs apart along the normal, in proportion to their inverse masses
    (``weighted``), or in equal shares between the movable bodies of a pair.

    Two rods whose cores cross (a gap below ``-(rho_a + rho_b)``, ``contacts.capsule_capsule``)
    are pushed ``slop / 2`` beyond touching: pushed to a gap of exactly 0, their cores still
    touch, and round-off can leave them crossed (a settle left two bare rods crossed by 3e-17 m).

    One sweep in pair order; returns the deepest overlap it corrected (0 if none), the pair
    list's length and how far it may have moved a body since the list was made. ``rows``: None,
    every pair; or a many-body world's scratch (:func:`_settle_rows`), whose list
    ``listed[:n_listed]`` holds every pair within ``slop + margin`` when it was made, bodies
    having moved by at most ``moved`` since (the sum of the overlaps corrected bounds how far a
    correction moves a body's centre). Before a pair is visited with ``moved`` beyond the
    margin, the list is made again and the sweep goes on from the pair after the last one it
    visited: every pair it skips overlaps nothing when the sweep over every pair would have
    visited it, and the outcome is the same bit for bit. (Checked only between sweeps, the fixed
    solver's single sweep in an 80-body e = 0 pile pushed bodies farther than the margin and
    skipped pairs that had come to overlap.) A sweep can
    push a body into a third one (a puck pressed between the mallet and a cushion), so callers
    that must leave no overlap repeat it (``_substep``'s ``separate_sweeps``). Repeated
    sweeps use equal shares: with inverse-mass shares a light body pinned between a heavy one
    and a cushion takes almost all of each correction and gives it back to the cushion, so the
    overlap shrinks only by ``m_light / m_heavy`` per sweep (1e-4 m left after 64 sweeps at a
    mass ratio of 1e4); with equal shares it halves every sweep, whatever the masses.

    ``rotate``: the correction may also turn the bodies about their centres, in the share of
    their lever terms ``(r x n)^2 / I`` (the settling path). Without it a pivoted rod that had
    turned into a puck wedged in a corner could not be separated from it at all (translation
    is blocked on every side there): 5e-4 m of overlap was left.
    """
    n = S.shape[0]
    deepest = 0.0
    count = PA.shape[0] if rows is None else n_listed
    k = 0
    last = -1
    while k < count:
        if rows is None:
            p = k
        else:
            pidx, box, order, seen, listed, margin = rows
            if moved > margin:
                count = close_pairs(S, Pm, hw, slop + margin, pidx, box, order, seen, listed)
                moved = 0.0
                k = find_sorted(listed, count, last + 1)
                if k >= count:
                    break
            p = listed[k]
        k += 1
        last = p
        a, b, wall = pair_bodies(p, PA, PB, n)
        g, nx, ny, oax, oay, _, obx, oby, _, _ = pair_geometry(S, Pm, a, b, wall, hw[HALF_W],
                                                               hw[HALF_H])
        if g < 0.0:
            if wall < 0 and g < -(Pm[a, RADIUS] + Pm[b, RADIUS]):
                g -= 0.5 * slop  # crossed cores
            ca = oax * ny - oay * nx
            cb = obx * ny - oby * nx
            ira = Pm[a, INV_INERTIA] if rotate else 0.0
            irb = Pm[b, INV_INERTIA] if rotate and wall < 0 else 0.0
            ta, ra = _share(Pm[a, INV_MASS], ira, ca, not weighted)
            if wall < 0:
                tb, rb = _share(Pm[b, INV_MASS], irb, cb, not weighted)
            else:
                tb, rb = 0.0, 0.0
            total = ta + ra + tb + rb
            if total > 0.0:
                if -g > deepest:
                    deepest = -g
                moved -= g
                depth = -g / total
                S[a, X] -= nx * depth * ta
                S[a, Y] -= ny * depth * ta
                if ra > 0.0:
                    S[a, ANGLE] -= depth * ra / ca
                if wall < 0:
                    S[b, X] += nx * depth * tb
                    S[b, Y] += ny * depth * tb
                    if rb > 0.0:
                        S[b, ANGLE] += depth * rb / cb
    return deepest, count, moved


@jit
def _deepest(S, Pm, hw, PA, PB, listed, n_listed):
    """The deepest overlap of any pair now (0 if none): of every pair, or of
    ``listed[:n_listed]``, a superset of the pairs that overlap (:func:`_contact_pass`)."""
    n = S.shape[0]
    deepest = 0.0
    for k in range(PA.shape[0] if listed is None else n_listed):
        p = k if listed is None else listed[k]
        a, b, wall = pair_bodies(p, PA, PB, n)
        g = pair_geometry(S, Pm, a, b, wall, hw[HALF_W], hw[HALF_H])[0]
        if -g > deepest:
            deepest = -g
    return deepest


@jit
def _cores_crossed(S, Pm, PA, PB, listed, n_listed):
    """Whether any two rods' cores cross (``contacts.cores_cross``): of every pair, or of
    ``listed[:n_listed]``, a superset of the pairs that overlap (:func:`_contact_pass`)."""
    n = S.shape[0]
    for k in range(PA.shape[0] if listed is None else n_listed):
        p = k if listed is None else listed[k]
        a = PA[p]
        b = PB[p]
        if b < n and cores_cross(S[a, X], S[a, Y], S[a, ANGLE], Pm[a, HALF_LENGTH],
                                 S[b, X], S[b, Y], S[b, ANGLE], Pm[b, HALF_LENGTH]):
            return True
    return False


@jit
def _kick(S, Pm, F, h, rotation, table_friction):
    """Velocity update of one substep: applied forces, cloth friction; then positions."""
    for i in range(S.shape[0]):
        ima = Pm[i, INV_MASS]
        S[i, VX] += F[i, FX] * ima * h
        S[i, VY] += F[i, FY] * ima * h
        if table_friction:
            dv = Pm[i, FRICTION_DECEL] * h
            if dv > 0.0:
                speed = math.sqrt(S[i, VX] ** 2 + S[i, VY] ** 2)
                f = max(speed - dv, 0.0) / speed if speed > 0.0 else 0.0
                S[i, VX] *= f
                S[i, VY] *= f
            dw = Pm[i, SPIN_DECEL] * h
            if dw > 0.0 and rotation:
                w = S[i, OMEGA]
                S[i, OMEGA] = max(abs(w) - dw, 0.0) * (1.0 if w > 0.0 else -1.0)
        S[i, X] += S[i, VX] * h
        S[i, Y] += S[i, VY] * h
        if rotation:
            S[i, ANGLE] += S[i, OMEGA] * h


@jit
def _substep(S, Pm, F, hw, PA, PB, MAT, h, t, iterations, slop, rotation, flat, contact_friction,
             table_friction, cpair, crec, stats, changed, separate_sweeps, rotate, jam, trace,
             closed_form, rows):
    """One fixed substep of h seconds, ending at time t: forces and drift (:func:`_kick`; with
    ``closed_form``, the exact solver's settling, the closed-form flight :func:`_advance`, so a
    body that meets nothing in the settled rest of a step keeps its exact path: Euler's kick
    moved a driven mallet touching nothing 1.3e-4 m a step off it while a rod slid along a
    cushion elsewhere),
    sequential impulses on the pairs within ``slop`` and approaching (``iterations`` sweeps,
    then the block solve of a jam if ``jam``), then positional correction, repeated up to
    ``separate_sweeps`` times while a sweep still corrects an overlap deeper than ``slop``
    (``rotate``: turning the bodies too, :func:`_separate`), or leaves one (:func:`_deepest`),
    or leaves two rods' cores crossed. (A push of less than ``slop`` can cross bare rods that
    touch: one pair's correction crossed two bare rods in a pile of twelve bodies by 4e-12 m,
    and the last sweep, which corrected nothing deeper than ``slop``, handed them on crossed.
    And a correction that turns a rod moves its far end farther than the overlap it corrects:
    at a tolerance of 1 mm a mallet pressing a rod had it handed on 1.4 mm deep in a cushion by a
    sweep that corrected nothing deeper than 1 mm, a state ``World.restore`` then refused.)

    ``rows``: None, every pass visits every pair; or a many-body world's scratch
    (:func:`_settle_rows`), and the passes visit the pairs that may be close enough to matter
    (``calendar.close_pairs``), with the same outcome bit for bit. The list holds every pair
    within ``slop + margin`` after the drift; the impulses move no body, and the list is made
    again whenever the positional correction may have moved a body by ``margin`` since."""
    if closed_form:
        _advance(S, Pm, F, h, rotation, table_friction)
    else:
        _kick(S, Pm, F, h, rotation, table_friction)
    if rows is None:
        _sweeps(S, Pm, hw, PA, PB, MAT, slop, 0.0, t, rotation, flat, contact_friction, changed,
                cpair, crec, stats, iterations, jam, None, 0)
        for sweep in range(separate_sweeps):
            deepest, _, _ = _separate(S, Pm, hw, PA, PB, sweep == 0, rotate, slop, None, 0, 0.0)
            if deepest <= slop and (deepest == 0.0 or sweep + 1 == separate_sweeps or (
                    _deepest(S, Pm, hw, PA, PB, None, 0) <= slop
                    and not _cores_crossed(S, Pm, PA, PB, None, 0))):
                break
    else:
        pidx, box, order, seen, listed, margin = rows
        n_listed = close_pairs(S, Pm, hw, slop + margin, pidx, box, order, seen, listed)
        _sweeps(S, Pm, hw, PA, PB, MAT, slop, 0.0, t, rotation, flat, contact_friction, changed,
                cpair, crec, stats, iterations, jam, listed, n_listed)
        moved = 0.0
        for sweep in range(separate_sweeps):
            deepest, n_listed, moved = _separate(S, Pm, hw, PA, PB, sweep == 0, rotate, slop,
                                                 rows, n_listed, moved)
            if moved > margin:  # (for the checks below, which read the list)
                n_listed = close_pairs(S, Pm, hw, slop + margin, pidx, box, order, seen, listed)
                moved = 0.0
            if deepest <= slop and (deepest == 0.0 or sweep + 1 == separate_sweeps or (
                    _deepest(S, Pm, hw, PA, PB, listed, n_listed) <= slop
                    and not _cores_crossed(S, Pm, PA, PB, listed, n_listed))):
                break
    if trace is not None:  # the trace hook
        trace_state(trace, t, S)


@jit
def fixed_element(S, Pm, F, hw, PA, PB, MAT, T, substeps, iterations, slop, t0, rotation, flat,
                  contact_friction, table_friction, cpair, crec, stats, changed,
                  separate_sweeps, jam, trace, rows):
    """Advance one element by T seconds in ``substeps`` fixed substeps (:func:`_substep`).

    ``separate_sweeps``: positional-correction sweeps per substep; the fixed solver uses 1
    (its documented, cheap behaviour; the exact solver's settling, :func:`_settle`, repeats
    them). ``jam``: the sweeps end in the block solve of a jam. ``trace``: the trace hook (a
    ``Trace``: the state after every substep), or None. ``rows``: None, every pass visits every
    pair; or a many-body world's scratch (:func:`many_rows`), and the passes visit only the
    pairs close enough to touch, with the same outcome (:func:`_substep`).
    """
    h = T / substeps
    for k in range(substeps):
        _substep(S, Pm, F, hw, PA, PB, MAT, h, t0 + (k + 1) * h, iterations, slop, rotation, flat,
                 contact_friction, table_friction, cpair, crec, stats, changed,
                 separate_sweeps, rotation and separate_sweeps > 1, jam, trace, False, rows)
    stats[STAT_SUBSTEPS] += substeps


@jit_uncounted
def _rest_on_cushions(S, Pm, F, hw, PA, PB, MAT, rest, changed, tol, zeno_speed,
                      contact_friction, table_friction, t, cpair, crec, stats):
    """After an event: decide which of the bodies it changed rest on a cushion.

    A disk pushed into a frictionless cushion by a constant force bounces ever lower and more
    often (a geometric series, Zeno): each bounce leaves it ``e`` times slower, so the bounces
    end in finite time, with the disk at rest against the cushion and sliding along it. A disk
    that leaves a bounce slower than ``zeno_speed`` while its force pushes it into the cushion
    is put at that limit at once: its velocity along the cushion's normal becomes zero and the
    cushion holds back the force's normal component (stored in ``rest``, handed back at the
    end of the step by :func:`_end_rests`), so that its closed-form flight slides along the
    cushion. What the series would still have taken is at most ``2 e zeno_speed / (a (1 - e))``
    seconds of bounces no higher than ``zeno_speed^2 / (2 a)``; the motion along the cushion
    is the same (no friction there). Without this, the bounces ran the solver into its
    resting-bounce limit and the fixed-step settling (``fallback``) in every such step.

    Every body the event changed first gets its held-back force back (another body may have
    knocked it off the cushion); then each is tested again, cushion by cushion (two in a
    corner). Disks only (a cushion's normal through the centre: no torque), with the force as
    their net force (no cloth friction on them) and no contact friction with that cushion.

    A rest is a contact: when it ends (at time ``t`` of an event that changed the body, or of
    the step's end, :func:`_end_rests`) it is recorded as one, its impulse what the cushion
    held back over it plus what zeroing the normal velocity took (:func:`_hand_back`), so that
    the records sum to the momentum the cushions gave, as on the fixed solver (walk W24a F1:
    a disk pressed on a cushion had no reaction in ``contacts`` or ``watched_impulse``).
    """
    n = S.shape[0]
    _release(S, Pm, F, rest, changed, t, cpair, crec, stats)
    for p in range(PA.shape[0]):
        i = PA[p]
        wall = PB[p] - n
        if wall >= 0 and changed[i]:
            _rest(S, Pm, F, hw, MAT, rest, p, i, wall, tol, zeno_speed, contact_friction,
                  table_friction, t)


@jit_uncounted
def _rest_on_cushions_indexed(S, Pm, F, hw, MAT, rest, changed, pidx, tol, zeno_speed,
                              contact_friction, table_friction, t, cpair, crec, stats):
    """:func:`_rest_on_cushions` for the event calendar: the changed bodies' cushion pairs
    from the pair index (``pidx [N, N + 4]``), not a scan of every pair. Each decision touches
    only its body's normal component, so the order does not matter: the same rests."""
    n = S.shape[0]
    _release(S, Pm, F, rest, changed, t, cpair, crec, stats)
    for i in range(n):
        if changed[i]:
            for wall in range(4):
                p = pidx[i, n + wall]
                if p >= 0:
                    _rest(S, Pm, F, hw, MAT, rest, p, i, wall, tol, zeno_speed,
                          contact_friction, table_friction, t)


@jit_inline
def _hand_back(S, Pm, F, rest, i, t, cpair, crec, stats):
    """Body i gets the force a cushion held back from it (if any) back at time ``t``, and the
    rest is recorded as a contact (:func:`_end_rest`)."""
    if rest[i, REST_FX] != 0.0:
        F[i, FX] += rest[i, REST_FX]
        _end_rest(S, Pm, rest[i, REST_FX], 0.0, rest[i, REST_JX] + abs(rest[i, REST_FX]) * (
            t - rest[i, REST_TX]), rest[i, REST_PX], i, t, cpair, crec, stats)
        rest[i, REST_FX] = 0.0
    if rest[i, REST_FY] != 0.0:
        F[i, FY] += rest[i, REST_FY]
        _end_rest(S, Pm, 0.0, rest[i, REST_FY], rest[i, REST_JY] + abs(rest[i, REST_FY]) * (
            t - rest[i, REST_TY]), rest[i, REST_PY], i, t, cpair, crec, stats)
        rest[i, REST_FY] = 0.0


@jit_inline
def _end_rest(S, Pm, fx, fy, j, p, i, t, cpair, crec, stats):
    """Record body i's rest on a cushion (pair ``p``, a float) that ends at ``t``: the
    normal is the held force's direction (into the cushion, from the body to it), the point
    where the disk touches the cushion, ``j`` the impulse. A rest released before the force
    made up for the velocity away from the cushion it zeroed at its start (``j`` < 0: within
    ``u m / F`` of it, u < ``zeno_speed``; e.g. a settle that begins at the same event) gives
    the body what is left of that velocity back and records nothing: a cushion cannot pull."""
    nx = 1.0 if fx > 0.0 else (-1.0 if fx < 0.0 else 0.0)
    ny = 1.0 if fy > 0.0 else (-1.0 if fy < 0.0 else 0.0)
    if j > 0.0:
        r = Pm[i, RADIUS]
        _record(int(p), t, S[i, X] + r * nx, S[i, Y] + r * ny, nx, ny, j, 0.0, cpair, crec,
                stats)
        k = stats[STAT_CONTACTS] - 1
        if k < cpair.shape[0]:
            crec[k, REC_HELD] = 1.0
    elif j < 0.0:  # (-j n, away from the cushion)
        S[i, VX] += j * nx * Pm[i, INV_MASS]
        S[i, VY] += j * ny * Pm[i, INV_MASS]


@jit_inline
def _release(S, Pm, F, rest, changed, t, cpair, crec, stats):
    """The changed bodies get their held-back forces back at time ``t`` (another body may have
    knocked one off its cushion)."""
    for i in range(F.shape[0]):
        if changed[i]:
            _hand_back(S, Pm, F, rest, i, t, cpair, crec, stats)


@jit_inline
def _rest(S, Pm, F, hw, MAT, rest, p, i, wall, tol, zeno_speed, contact_friction,
          table_friction, t):
    """Put body i at rest on cushion ``wall`` (pair p) at time ``t`` if :func:`rests_on` says
    so: its velocity along the cushion's normal zeroed (the impulse that takes is booked at
    the rest's start), its force's normal component held back."""
    if rests_on(S, Pm, F, hw, MAT, p, i, wall, tol, zeno_speed, contact_friction,
                table_friction):
        if wall < 2:  # the cushions are axis-aligned: one component each
            rest[i, REST_JX] = S[i, VX] * math.copysign(1.0, F[i, FX]) / Pm[i, INV_MASS]
            rest[i, REST_TX] = t
            rest[i, REST_PX] = p
            S[i, VX] = 0.0
            rest[i, REST_FX] = F[i, FX]
            F[i, FX] = 0.0
        else:
            rest[i, REST_JY] = S[i, VY] * math.copysign(1.0, F[i, FY]) / Pm[i, INV_MASS]
            rest[i, REST_TY] = t
            rest[i, REST_PY] = p
            S[i, VY] = 0.0
            rest[i, REST_FY] = F[i, FY]
            F[i, FY] = 0.0


@jit_inline
def rests_on(S, Pm, F, hw, MAT, p, i, wall, tol, zeno_speed, contact_friction, table_friction):
    """Body i, on cushion ``wall`` (pair p), is one :func:`_rest_on_cushions` puts to rest: a
    disk (no cloth friction on it, none with this cushion) that touches the cushion, moves
    along its normal slower than ``zeno_speed`` and is pushed into it by its force ``F``.
    (Renderers that fly a traced state use the same test, ``envs.fast.sample_trace``.)"""
    if Pm[i, HALF_LENGTH] != 0.0 or Pm[i, INV_MASS] == 0.0:
        return False
    if (table_friction and Pm[i, FRICTION_DECEL] > 0.0) or (
            contact_friction and MAT[p, FRICTION] > 0.0):
        return False
    ix, iy, off = wall_frame(wall, hw[HALF_W], hw[HALF_H])
    if ix * S[i, X] + iy * S[i, Y] + off - Pm[i, RADIUS] > tol:
        return False
    return ix * F[i, FX] + iy * F[i, FY] < 0.0 and abs(ix * S[i, VX] + iy * S[i, VY]) < zeno_speed


@jit_inline
def _end_rests(S, Pm, F, rest, t, cpair, crec, stats):
    """Hand the held-back forces back at time ``t`` (the end of the step, or before settling),
    each rest recorded as a contact (:func:`_hand_back`)."""
    for i in range(F.shape[0]):
        _hand_back(S, Pm, F, rest, i, t, cpair, crec, stats)


@jit_inline
def _stalled_in_contact(p, S, Pm, hw, PA, PB, tol):
    """1 if pair p, whose search stalled (a checkpoint), is within ``tol``: a sliding or rolling
    contact, which counts toward settling like a resting bounce; else 0. (Both event loops.)"""
    a, b, wall = pair_bodies(p, PA, PB, S.shape[0])
    return 1 if pair_geometry(S, Pm, a, b, wall, hw[HALF_W], hw[HALF_H])[0] <= tol else 0


@jit_inline
def _int(value):
    """``value`` as a plain int64: a constant passed on would make numba compile the callee once
    more for its literal type."""
    return numba.int64(value)


@jit_inline
def _out_of_reach(S, Pm, a, b, wall, hw, closing, T, size):
    """Whether bodies a and b (b unused for cushion ``wall`` >= 0) provably cannot meet within
    T: their bounding circles (centre, radius plus half-length) are farther apart than the
    ``closing`` speed bound covers in T, with ``size`` (the pair's own bound, a margin for the
    positional correction's pushes) to spare."""
    reach = Pm[a, RADIUS] + Pm[a, HALF_LENGTH]
    margin = closing * T + size
    if wall >= 0:
        ix, iy, off = wall_frame(wall, hw[HALF_W], hw[HALF_H])
        return ix * S[a, X] + iy * S[a, Y] + off - reach > margin
    far = reach + Pm[b, RADIUS] + Pm[b, HALF_LENGTH] + margin
    dx = S[b, X] - S[a, X]
    dy = S[b, Y] - S[a, Y]
    return dx * dx + dy * dy > far * far  # False for NaN


@jit
def _settle_substeps(S, Pm, F, hw, PA, PB, T, settle_substep, rows):
    """Substeps for settling, so that no pair closes by more than it can overlap undetected.

    Only pairs that can meet within T count (:func:`_out_of_reach`): a 0.1 mm post that no
    body reached, 0.1 mm from the cushions, set a nine-body settle's substeps (23 instead of 7)
    and so its motion. A pair out of reach at one check stays apart until the next (each
    substep is at most T long and its drift uses the speeds checked), where it is checked
    again: a body that got faster brings its pairs into the bound, and the settle plans again.

    A body-body overlap is seen while it is shallower than ``rho_a + rho_b``, and two rods'
    while their cores cross as well (at least the shorter half-length deep: zero-thickness rods
    have only that, thin ones the larger of the two). A cushion's is seen at any depth (it is a
    half-plane), but a body that moves farther than its own reach into it in a substep is put
    back by the positional correction, not bounced: a puck at 1e5 m/s in a 1 m box, left to
    the settle by ``max_events``, moved 60 m a substep and ended squashed into a corner. So a
    body moves at most half its reach a substep against the cushions too.

    ``rows``: None, or a many-body world's scratch (:func:`_settle_rows`): then only the pairs
    whose boxes of twice their reach plus their flight within T overlap are checked
    (``calendar.close_pairs``), a superset of the pairs that are not out of reach, and the
    result is the same.
    """
    h = settle_substep
    if rows is None:
        for p in range(PA.shape[0]):
            h = _pair_substep(S, Pm, F, hw, PA, PB, T, p, h)
    else:
        pidx, box, order, seen, listed, _ = rows
        for k in range(reachable_pairs(S, Pm, F, hw, T, pidx, box, order, seen, listed)):
            h = _pair_substep(S, Pm, F, hw, PA, PB, T, listed[k], h)
    steps = T / h
    return steps if steps >= 1.0 else 1.0  # not rounded nor capped (see _settle); NaN: 1


@jit_inline
def _pair_substep(S, Pm, F, hw, PA, PB, T, p, h):
    """The substep ``h`` shortened, where pair p needs it, for :func:`_settle_substeps`."""
    n = S.shape[0]
    a = PA[p]
    b = PB[p]
    if b >= n:
        reach = Pm[a, RADIUS] + Pm[a, HALF_LENGTH]
        closing = speed_bound(S, Pm, F, a, T)
        if closing > 0.0 and 0.5 * reach / closing < h and not _out_of_reach(
                S, Pm, a, a, b - n, hw, closing, T, reach):
            return 0.5 * reach / closing
        return h
    size = Pm[a, RADIUS] + Pm[b, RADIUS]
    if Pm[a, HALF_LENGTH] > 0.0 and Pm[b, HALF_LENGTH] > 0.0:
        # crossing cores are seen however thin the rods (capsule_capsule gives them their
        # depth, the least distance of an end from the other's line, and the normal that
        # uncrosses them): a rod 50 um thick against a bare one needed 5e6 substeps for a
        # 1 s step. Before crossed cores had a depth they read as -(rho_a + rho_b) with no
        # usable normal, and this bound let a substep cross them for good
        size = max(size, min(Pm[a, HALF_LENGTH], Pm[b, HALF_LENGTH]))
    closing = speed_bound(S, Pm, F, a, T) + speed_bound(S, Pm, F, b, T)
    if closing > 0.0 and 0.5 * size / closing < h and not _out_of_reach(
            S, Pm, a, b, -1, hw, closing, T, size):
        return 0.5 * size / closing
    return h


@jit
def _plan(needed, budget):
    """(substeps, capped) for a stretch of settling that needs ``needed`` substeps
    (:func:`_settle_substeps`) and may take at most ``budget``, what is left of the cap."""
    if needed > budget:
        return budget, True
    return int(math.ceil(needed)), False


@jit
def _settle(S, Pm, F, hw, PA, PB, MAT, t_now, dt, settle_substep, sweeps, tol, rotation, flat,
            contact_friction, table_friction, cpair, crec, stats, changed, jam, trace, rows):
    """Settle the rest of the step (``t_now..dt``) in fixed substeps (:func:`_substep`, with
    ``sweeps`` impulse sweeps and positional-correction sweeps) and flag the element.

    The substeps are as many as the no-tunnelling bound needs (:func:`_settle_substeps`) from
    the bodies' speeds, and the bound is checked again after every substep: where collisions
    made a body faster than the plan allowed, the rest of the step is planned again with
    shorter substeps. (Planned once: a 1e-5 kg disk driven into a cushion by a 1e4 kg one at
    2 m/s got ~100 times faster during the settle and passed through the heavy disk, unflagged;
    ``tests/physics/test_extreme_inputs.py``.) At most ``MAX_SETTLE_SUBSTEPS`` over the step:
    a bound that needs shorter substeps flags the element ``FALLBACK_CAPPED`` (a pair may have
    passed through another: forces or speeds ~10^6 times what the bodies' sizes allow in the
    step, a force of 10^14 N on a 0.3 kg disk in a 20 ms step), else ``FALLBACK_SETTLED``.

    The last substep, whose pose the step hands on, repeats the positional correction up to
    ``MAX_FINAL_SEPARATE_SWEEPS`` times: in a plastic pile driven along a wedge (four disks
    pressed into a cushion corner) a sweep removes only ~1/6 of the overlap, and 64 sweeps left
    8.8e-9 m where the tolerance is 1e-9 m.

    ``rows``: None, or a many-body world's scratch (:func:`_settle_rows`): each substep then
    visits only the pairs close enough to touch (:func:`_substep`).
    """
    span = dt - t_now
    n, capped = _plan(_settle_substeps(S, Pm, F, hw, PA, PB, span, settle_substep, rows),
                      _int(MAX_SETTLE_SUBSTEPS))
    h = span / n
    t0 = t_now
    k = 0  # substeps of the current plan done
    total = 0
    while True:
        k += 1
        final = k == n
        _substep(S, Pm, F, hw, PA, PB, MAT, h, t0 + k * h, sweeps, tol, rotation, flat,
                 contact_friction, table_friction, cpair, crec, stats, changed,
                 MAX_FINAL_SEPARATE_SWEEPS if final else sweeps, rotation, jam, trace, True, rows)
        total += 1
        if final:
            break
        left = (n - k) * h
        needed = _settle_substeps(S, Pm, F, hw, PA, PB, left, settle_substep, rows)
        if needed > (n - k) * (1.0 + 1e-9):  # faster than planned (not round-off): plan again
            m, c = _plan(needed, MAX_SETTLE_SUBSTEPS - total)
            capped |= c
            if m > n - k:
                t0 = t0 + k * h
                n = m
                k = 0
                h = left / m
    stats[STAT_SUBSTEPS] += total
    stats[STAT_FALLBACK] = FALLBACK_CAPPED if capped else FALLBACK_SETTLED


# ---------------------------------------------------------------------------------------------
# A sustained contact of one pair, held (e = 0 chatter of a free pair). After a plastic impact
# two free bodies can stay pressed together with no force but their own motion (a striker left
# on a spinning rod is pushed round by it): the relative normal velocity is zero after each
# impact, the curvature of the relative motion closes the gap again at once, and the exact
# loop makes ever smaller impacts, a Zeno sequence with no end (the inelastic collapse of a
# single pair). The limit of that sequence is a frictionless contact held as a constraint,
# ``g = const``, while its force pushes (the Lagrange multiplier is >= 0). A one-pair world
# of two free, force-free bodies integrates that limit (:func:`_hold`) instead of settling it
# with fixed first-order substeps.
# ---------------------------------------------------------------------------------------------

#: most turn (rad) of either body, and slide relative to the pair's size, in one held substep
HOLD_TURN = 1e-4
#: Newton iterations of a held substep's position stage before it gives up (the step settles)
HOLD_ITERATIONS = 30
#: squared sine of the angle between two held rods below which the hold lets the step settle:
#: near parallel, the contact is a line whose closest point jumps from one end to the other,
#: which one impulse at one point cannot hold (:func:`_flat_rods`)
HOLD_FLAT = 1e-4


@jit_inline
def _holdable(S, Pm, F, PA, PB, MAT, rotation, contact_friction, table_friction):
    """Whether the event loop may hold the sustained contact of its world's pair: one pair
    (nothing else can meet its bodies), two bodies (not a cushion), both free (mass and
    inertia finite), turning (``rotation``), no applied force, no cloth friction and no contact
    friction. (Two rods are held while they are not near parallel: :func:`_hold`.)"""
    n = S.shape[0]
    if PA.shape[0] != 1 or not rotation:
        return False
    a = PA[0]
    b = PB[0]
    if b >= n:
        return False
    if contact_friction and MAT[0, FRICTION] > 0.0:
        return False
    for i in (a, b):
        if Pm[i, INV_MASS] <= 0.0 or Pm[i, INV_INERTIA] <= 0.0:
            return False
        if F[i, FX] != 0.0 or F[i, FY] != 0.0:
            return False
        if table_friction and (Pm[i, FRICTION_DECEL] > 0.0 or Pm[i, SPIN_DECEL] > 0.0):
            return False
    return True


@jit_inline
def _flat_rods(S, Pm, a, b):
    """Whether the pair is two rods within ``HOLD_FLAT`` of parallel (squared sine)."""
    if Pm[a, HALF_LENGTH] == 0.0 or Pm[b, HALF_LENGTH] == 0.0:
        return False
    sine = math.sin(S[a, ANGLE] - S[b, ANGLE])
    return sine * sine < HOLD_FLAT


@jit_inline
def _gap_moved(S, Pm, a, b, wall, h, j, nx, ny, rna, rnb):
    """Gap of the pair after flying h seconds with the impulse ``j`` along ``n`` (levers
    ``rna``, ``rnb``) applied at the start (the poses only; S is not changed)."""
    ima = Pm[a, INV_MASS]
    imb = Pm[b, INV_MASS]
    iia = Pm[a, INV_INERTIA]
    iib = Pm[b, INV_INERTIA]
    xa = S[a, X] + h * (S[a, VX] - j * nx * ima)
    ya = S[a, Y] + h * (S[a, VY] - j * ny * ima)
    ta = S[a, ANGLE] + h * (S[a, OMEGA] - j * rna * iia)
    xb = S[b, X] + h * (S[b, VX] + j * nx * imb)
    yb = S[b, Y] + h * (S[b, VY] + j * ny * imb)
    tb = S[b, ANGLE] + h * (S[b, OMEGA] + j * rnb * iib)
    # the wall and pinned flags passed as pair_geometry passes them (run-time values): as
    # constants, or omitted, they compiled geometry and its callees a second time
    return geometry(xa, ya, ta, 0.0, 0.0, 0.0, Pm[a, HALF_LENGTH], Pm[a, RADIUS],
                    xb, yb, tb, 0.0, 0.0, 0.0, Pm[b, HALF_LENGTH], Pm[b, RADIUS], wall, 0.0,
                    0.0, Pm[a, INV_MASS] == 0.0, Pm[b, INV_MASS] == 0.0)[0]


@jit
def _kinetic(S, Pm, a, b):
    e = 0.0
    for i in (a, b):
        e += 0.5 * ((S[i, VX] ** 2 + S[i, VY] ** 2) / Pm[i, INV_MASS]
                    + S[i, OMEGA] ** 2 / Pm[i, INV_INERTIA])
    return e


@jit
def _least_energy(c, w, u):
    """The least-energy velocities ``u*`` (energy weights 1 / ``w``) with ``c u* = c u``:
    ``u* = W c^T y``, ``(c W c^T) y = c u``; NaN where that system is singular to round-off.
    Loops and jam's Gaussian elimination (numpy's linalg in numba added to the compile time);
    the system is scaled to a unit diagonal first (its rows mix masses and inverse masses, 1e18
    apart for two 1e-9 kg bodies, where the elimination's relative singular test misfires)."""
    rhs = np.zeros(4)
    a4 = np.zeros((4, 4))
    for r in range(4):
        for q in range(6):
            rhs[r] += c[r, q] * u[q]
            for r2 in range(4):
                a4[r, r2] += c[r, q] * w[q] * c[r2, q]
    d = np.empty(4)
    for r in range(4):
        d[r] = math.sqrt(a4[r, r])
    for r in range(4):
        rhs[r] /= d[r]
        for r2 in range(4):
            a4[r, r2] /= d[r] * d[r2]
    ustar = np.zeros(6)
    if not _solve_small(a4, rhs, 4):
        ustar[:] = np.nan
        return ustar
    for q in range(6):
        for r in range(4):
            ustar[q] += w[q] * c[r, q] * rhs[r] / d[r]
    return ustar


@jit
def _no_gain(S, Pm, a, b, e0, nx, ny, rna, rnb):
    """Take back any kinetic energy a held substep gained over ``e0`` (the round-off-free
    integrator still errs by O(h^2) either way) without touching what the exact motion keeps:
    linear momentum, angular momentum and the contact's zero normal velocity. Those are four
    linear conditions on the pair's six velocities; the velocities are moved toward the least
    energetic ones that meet them, along the line that keeps them, to energy ``e0``."""
    e1 = _kinetic(S, Pm, a, b)
    if not e1 > e0:
        return
    w = np.empty(6)
    u = np.empty(6)
    c = np.zeros((4, 6))
    ma = 1.0 / Pm[a, INV_MASS]
    mb = 1.0 / Pm[b, INV_MASS]
    cx = (ma * S[a, X] + mb * S[b, X]) / (ma + mb)
    cy = (ma * S[a, Y] + mb * S[b, Y]) / (ma + mb)
    k = 0
    for i in (a, b):
        m = 1.0 / Pm[i, INV_MASS]
        w[k], w[k + 1], w[k + 2] = Pm[i, INV_MASS], Pm[i, INV_MASS], Pm[i, INV_INERTIA]
        u[k], u[k + 1], u[k + 2] = S[i, VX], S[i, VY], S[i, OMEGA]
        c[0, k] = m
        c[1, k + 1] = m
        c[2, k] = -m * (S[i, Y] - cy)
        c[2, k + 1] = m * (S[i, X] - cx)
        c[2, k + 2] = 1.0 / Pm[i, INV_INERTIA]
        k += 3
    c[3, 0], c[3, 1], c[3, 2] = -nx, -ny, -rna
    c[3, 3], c[3, 4], c[3, 5] = nx, ny, rnb
    ustar = _least_energy(c, w, u)
    dk = 0.0
    kstar = 0.0
    for q in range(6):
        dk += 0.5 * (u[q] - ustar[q]) ** 2 / w[q]
        kstar += 0.5 * ustar[q] ** 2 / w[q]
    if not dk > 0.0:  # also NaN: singular
        return
    s = math.sqrt(max(e0 - kstar, 0.0) / dk)
    if s >= 1.0:
        return
    k = 0
    for i in (a, b):
        S[i, VX] = ustar[k] + s * (u[k] - ustar[k])
        S[i, VY] = ustar[k + 1] + s * (u[k + 1] - ustar[k + 1])
        S[i, OMEGA] = ustar[k + 2] + s * (u[k + 2] - ustar[k + 2])
        k += 3


@jit
def _hold(S, Pm, hw, PA, PB, t_now, dt, tol, zeno_speed, cpair, crec, stats, trace):
    """Hold the world's one pair in contact from ``t_now`` (RATTLE, the symmetric second-order
    integrator of constrained motion, on each body's ``x, y, angle``, whose mass matrix is
    constant): an impulse at the start of each substep chosen so that the gap after the
    substep's flight is the gap held (Newton), then the plastic impulse that leaves no normal
    velocity there. Both act at the pair's one contact point along its normal, so linear and
    angular momentum are kept to round-off; any energy the O(h^2) error would add is taken
    back (:func:`_no_gain`). Substeps turn either body, or slide the pair, by at most
    ``HOLD_TURN``. Each substep is recorded as a contact (its two impulses). Two rods are held
    while they are not near parallel (:func:`_flat_rods`): the gap is then a smooth function of
    the poses between the switches of the closest features (an end on a side, two ends), and
    continuous across them.

    The contact is let go where it would have to pull (the first impulse comes out negative):
    the pair separates by its own motion. Returns (time reached, outcome): 1 held to ``dt``,
    0 let go at that time (the event loop goes on), -1 the position stage did not converge or
    two rods turned near parallel (the caller settles the rest of the step)."""
    # the one pair is two bodies; its wall (-1) and whether it is a cushion (False) are passed
    # as run-time values: as literal constants they compiled geometry and its callees, and
    # relative_velocity_of, a second time
    a, b, wall = pair_bodies(0, PA, PB, S.shape[0])
    g0, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, b, wall, 0.0, 0.0)
    held = min(max(g0, 0.0), tol)
    e0 = _kinetic(S, Pm, a, b)
    size = Pm[a, RADIUS] + Pm[a, HALF_LENGTH] + Pm[b, RADIUS] + Pm[b, HALF_LENGTH]
    t = t_now
    j = 0.0
    substeps = 0
    outcome = 1
    while t < dt:
        if _flat_rods(S, Pm, a, b):
            outcome = -1
            break
        g0, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, b, wall, 0.0, 0.0)
        rna = oax * ny - oay * nx
        rnb = obx * ny - oby * nx
        k_n = (Pm[a, INV_MASS] + Pm[b, INV_MASS] + rna * rna * Pm[a, INV_INERTIA]
               + rnb * rnb * Pm[b, INV_INERTIA])
        rel = math.sqrt((S[b, VX] - S[a, VX]) ** 2 + (S[b, VY] - S[a, VY]) ** 2)
        rate = max(abs(S[a, OMEGA]), abs(S[b, OMEGA]), rel / size)
        h = dt - t
        if rate * h > HOLD_TURN:
            h = HOLD_TURN / rate
            if t + h >= dt:
                h = dt - t
        # position stage: the impulse whose flight ends at the held gap (Newton on one scalar)
        g = _gap_moved(S, Pm, a, b, wall, h, j, nx, ny, rna, rnb) - held
        it = 0
        while abs(g) > 1e-3 * tol and it < HOLD_ITERATIONS:
            j -= g / (h * k_n)
            g = _gap_moved(S, Pm, a, b, wall, h, j, nx, ny, rna, rnb) - held
            it += 1
        if abs(g) > 1e-3 * tol or not math.isfinite(j):
            outcome = -1
            break
        free = j < 0.0  # the contact would pull: the pair flies apart this substep
        if free:
            j = 0.0
        else:
            apply_impulse(S, Pm, a, b, False, j, nx, ny, rna, rnb, True)
        for i in (a, b):
            S[i, X] += h * S[i, VX]
            S[i, Y] += h * S[i, VY]
            S[i, ANGLE] += h * S[i, OMEGA]
        t = t + h if t + h < dt else dt
        if free:
            substeps += 1
            if trace is not None:  # the trace hook
                trace_state(trace, t, S)
            gap, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, b, wall, 0.0,
                                                                        0.0)
            if gap > tol and vn >= zeno_speed:
                outcome = 0  # apart and leaving faster than a resting bounce: let go
                break
            continue
        # velocity stage: no normal velocity at the new pose (bilateral: either sign)
        g1, nx, ny, oax, oay, ka, obx, oby, kb, vn = pair_geometry(S, Pm, a, b, wall, 0.0, 0.0)
        rna = oax * ny - oay * nx
        rnb = obx * ny - oby * nx
        vn, vt, scale = relative_velocity_of(S[a, VX], S[a, VY], S[a, OMEGA], S[b, VX],
                                             S[b, VY], S[b, OMEGA], wall >= 0, nx, ny, oax,
                                             oay, ka, obx, oby, kb)
        k_n = (Pm[a, INV_MASS] + Pm[b, INV_MASS] + rna * rna * Pm[a, INV_INERTIA]
               + rnb * rnb * Pm[b, INV_INERTIA])
        # the substep's impulse in all, j + mu, may not pull: where the pair would part (a
        # disk sliding along a rod at a normal speed below round-off, walk W28b F3) mu took
        # back more than j pushed, and the records read -2e-21 N s a substep
        mu = max(-vn / k_n, -j)
        apply_impulse(S, Pm, a, b, False, mu, nx, ny, rna, rnb, True)
        _no_gain(S, Pm, a, b, e0, nx, ny, rna, rnb)
        if j + mu > 0.0:
            _record(0, t, S[a, X] + oax + ka * nx, S[a, Y] + oay + ka * ny, nx, ny, j + mu,
                    0.0, cpair, crec, stats)
        substeps += 1
        if trace is not None:  # the trace hook
            trace_state(trace, t, S)
    stats[STAT_SUBSTEPS] += substeps
    return t, outcome


@jit_inline
def _try_hold(S, Pm, F, hw, PA, PB, MAT, t_now, dt, tol, zeno_speed, rotation,
              contact_friction, table_friction, cpair, crec, stats, trace):
    """:func:`_hold` where the world can hold (:func:`_holdable`); returns its (time reached,
    outcome), or (``t_now``, -1): not held, the caller settles the rest of the step."""
    if _holdable(S, Pm, F, PA, PB, MAT, rotation, contact_friction, table_friction):
        return _hold(S, Pm, hw, PA, PB, t_now, dt, tol, zeno_speed, cpair, crec, stats, trace)
    return t_now, -1


@jit_inline
def _no_hold(S, Pm, F, hw, PA, PB, MAT, t_now, dt, tol, zeno_speed, rotation,
             contact_friction, table_friction, cpair, crec, stats, trace):
    """What :func:`_try_hold` returns where the world cannot hold."""
    return t_now, -1


#: the hold, compiled only for one-pair worlds, with contact friction or not (the ``jam`` flag's
#: level, ``kernels.FLAGS``): a walled table or a many-body scene never pays for its compile
_hold_unless = static_if(_try_hold, negate=True, level=LEVEL_CAN_JAM, otherwise=_no_hold)


@jit
def _search_all(S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations, rotation, flat,
                table_friction, toi, kind):
    """Search every pair from ``t_now`` to ``dt`` and file the outcomes in ``toi`` / ``kind``;
    returns the iterations. Not inlined: :func:`exact_element` calls it at the start of a step
    and where a held contact lets go, and each inlined copy of ``_search`` costs compile time."""
    iterations = 0
    for p in range(PA.shape[0]):
        tc, k, it = _search(p, S, Pm, F, hw, PA, PB, dt - t_now, tol, max_iterations, rotation,
                            flat, table_friction)
        toi[p] = t_now + tc if k != NONE else dt
        kind[p] = k
        iterations += it
    return iterations


@jit
def exact_element(S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
                  zeno_impacts, settle_substep, rotation, flat, contact_friction, table_friction,
                  jam, cpair, crec, stats, toi, kind, changed, rest, trace):
    """Advance one element by dt seconds, event by event, every pair scanned at every event.

    ``toi``, ``kind`` (per pair), ``changed`` and ``rest`` (per body) are the element's scratch
    rows (``rest``: the force components cushions hold back, :func:`_rest_on_cushions`);
    ``rotation``, ``flat``, ``contact_friction``, ``table_friction`` and ``jam`` are
    compile-time flags (``kernels.FLAGS``). Used below the ``jam`` level
    ``LEVEL_MANY_BODIES`` only: at that level :func:`exact_many_element` steps the world, on the
    broadphase and the event calendar, with the same events bit for bit
    (``kernels.step_element`` picks one or the other at compile time).
    ``trace``: the trace hook (a ``Trace``: the state after every event that resolved
    contacts; an empty one, :func:`untraced`, records nothing), or None.
    """
    sweeps = _int(MAX_SWEEPS)
    n_pairs = PA.shape[0]
    iterations = _search_all(S, Pm, F, hw, PA, PB, 0.0, dt, tol, max_iterations, rotation, flat,
                             table_friction, toi, kind)
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
        changed[:] = 0
        if kind[best] == CHECKPOINT:
            resting += _stalled_in_contact(best, S, Pm, hw, PA, PB, tol)
        else:
            resting += _sweeps(S, Pm, hw, PA, PB, MAT, tol, zeno_speed, t_now, rotation, flat,
                               contact_friction, changed, cpair, crec, stats, sweeps, jam, None,
                               0)
            _rest_on_cushions(S, Pm, F, hw, PA, PB, MAT, rest, changed, tol, zeno_speed,
                              contact_friction, table_friction, t_now, cpair, crec, stats)
            if trace is not None:  # the trace hook
                trace_state(trace, t_now, S)
        horizon = dt - t_now
        for p in range(n_pairs):
            if p == best or changed[PA[p]] or (PB[p] < S.shape[0] and changed[PB[p]]):
                tc, k, it = _search(p, S, Pm, F, hw, PA, PB, horizon, tol, max_iterations,
                                    rotation, flat, table_friction)
                toi[p] = t_now + tc if k != NONE else dt
                kind[p] = k
                iterations += it
        if events >= max_events or resting >= zeno_impacts:
            _end_rests(S, Pm, F, rest, t_now, cpair, crec, stats)
            if t_now < dt and events < max_events:
                t_now, outcome = _hold_unless(jam, S, Pm, F, hw, PA, PB, MAT, t_now, dt, tol,
                                              zeno_speed, rotation, contact_friction,
                                              table_friction, cpair, crec, stats, trace)
                if outcome == 0:  # let go: the pair separates, the event loop goes on
                    resting = 0
                    iterations += _search_all(S, Pm, F, hw, PA, PB, t_now, dt, tol,
                                              max_iterations, rotation, flat, table_friction, toi,
                                              kind)
                    continue
            if t_now < dt:
                _settle(S, Pm, F, hw, PA, PB, MAT, t_now, dt, settle_substep, sweeps, tol,
                        rotation, flat, contact_friction, table_friction, cpair, crec, stats,
                        changed, jam, trace, None)
            break
    _end_rests(S, Pm, F, rest, t_now, cpair, crec, stats)
    stats[STAT_EVENTS] += events
    stats[STAT_ITERATIONS] += iterations


@jit_uncounted
def _predict(p, S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations, rotation, flat,
             table_friction, toi, kind, near, heap, hpos, watch, watched, cnt):
    """Search pair p from now to the end of the step and file the outcome: in the calendar if
    it has an event, on the watch list if it may come within ``tol``. Returns the search's
    iterations.

    Compiled once, not inlined (as :func:`_first`): inlined at both its call sites, with the
    search it inlines, it was a large part of a many-body world's first compile (with the scan
    no longer compiled there, ``kernels._scan``: 98 -> 64 CPU s); uncounted, so the call costs
    no reference counting, and the step rate did not move."""
    if stays_clear(p, S, Pm, F, hw, PA, PB, dt - t_now, tol, table_friction):
        tc, k, it = dt - t_now, NONE, 0
    else:
        tc, k, it = _search(p, S, Pm, F, hw, PA, PB, dt - t_now, tol, max_iterations,
                            rotation, flat, table_friction)
    toi[p] = t_now + tc if k != NONE else dt
    kind[p] = k
    if k != NONE:
        heap_set(heap, hpos, cnt, toi, p)
    else:
        heap_remove(heap, hpos, cnt, toi, p)
    t_near = t_now + near_time(p, S, Pm, F, hw, PA, PB, tol, table_friction)
    near[p] = t_near
    if t_near < dt:
        watch_insert(watch, watched, cnt, p)
    else:
        watch_remove(watch, watched, cnt, p)
    return it


@jit_uncounted
def _first_predictions(S, Pm, F, hw, PA, PB, dt, tol, max_iterations, rotation, flat,
                       table_friction, toi, kind, pidx, near, box, cnt, heap, hpos, watch,
                       watched, order, seen):
    """The step's first predictions: the swept boxes, the pairs whose boxes overlap (sweep and
    prune along x, the bodies re-sorted from the last step's order) searched, the calendar and
    the watch list filled. ``seen``: scratch [N]. Returns the iterations."""
    n = S.shape[0]
    for k in range(cnt[CAL_HEAP_SIZE]):
        hpos[heap[k]] = 0
    for k in range(cnt[CAL_WATCH_SIZE]):
        watched[watch[k]] = 0
    cnt[CAL_HEAP_SIZE] = 0
    cnt[CAL_WATCH_SIZE] = 0
    for i in range(n):
        swept_box(S, Pm, F, i, dt, tol, box)
    sort_by_xmin(order, box, n, seen)
    iterations = 0
    n_watch = 0
    for k in range(n):
        i = order[k]
        for m in range(k + 1, n):
            j = order[m]
            if box[j, BOX_XMIN] > box[i, BOX_XMAX]:
                break
            p = pidx[i, j]
            if p >= 0 and boxes_meet(box, i, j):
                n_watch, it = _first(p, S, Pm, F, hw, PA, PB, dt, tol, max_iterations,
                                     rotation, flat, table_friction, toi, kind, near, heap, hpos,
                                     watch, watched, cnt, n_watch)
                iterations += it
        for w in range(4):
            p = pidx[i, n + w]
            if p >= 0 and box_meets_wall(box, i, w, hw):
                n_watch, it = _first(p, S, Pm, F, hw, PA, PB, dt, tol, max_iterations,
                                     rotation, flat, table_friction, toi, kind, near, heap, hpos,
                                     watch, watched, cnt, n_watch)
                iterations += it
    sort_ints(watch, n_watch)
    cnt[CAL_WATCH_SIZE] = n_watch
    return iterations


@jit_uncounted
def _first(p, S, Pm, F, hw, PA, PB, dt, tol, max_iterations, rotation, flat, table_friction, toi,
           kind, near, heap, hpos, watch, watched, cnt, n_watch):
    """:func:`_predict` at the start of the step, the watch list appended (sorted after).
    Compiled once, not inlined (see :func:`_predict`)."""
    if stays_clear(p, S, Pm, F, hw, PA, PB, dt, tol, table_friction):
        tc, k, it = dt, NONE, 0
    else:
        tc, k, it = _search(p, S, Pm, F, hw, PA, PB, dt, tol, max_iterations, rotation, flat,
                            table_friction)
    toi[p] = tc
    kind[p] = k
    if k != NONE:
        heap_set(heap, hpos, cnt, toi, p)
    t_near = near_time(p, S, Pm, F, hw, PA, PB, tol, table_friction)
    near[p] = t_near
    if t_near < dt:
        watch[n_watch] = p
        watched[p] = 1
        n_watch += 1
    return n_watch, it


@jit_inline
def _repredict(best, S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations, rotation, flat,
               table_friction, toi, kind, changed, pidx, near, box, cnt, heap, hpos, watch, stamp,
               watched):
    """After an event at ``t_now``: re-predict its pair and every pair of a body it changed
    (once each), those bodies' swept boxes recomputed first; a pair whose boxes no longer meet
    leaves the calendar and the watch list. Returns the searches' iterations."""
    n = S.shape[0]
    cnt[CAL_STAMP] += 1
    mark = cnt[CAL_STAMP]
    stamp[best] = mark
    iterations = _predict(best, S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations, rotation,
                          flat, table_friction, toi, kind, near, heap, hpos, watch, watched, cnt)
    for i in range(n):
        if changed[i]:
            swept_box(S, Pm, F, i, dt - t_now, tol, box)
    for i in range(n):
        if not changed[i]:
            continue
        for j in range(n + 4):
            p = pidx[i, j]
            if p < 0 or stamp[p] == mark:
                continue
            stamp[p] = mark
            if box_meets_wall(box, i, j - n, hw) if j >= n else boxes_meet(box, i, j):
                iterations += _predict(p, S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations,
                                       rotation, flat, table_friction, toi, kind, near, heap, hpos,
                                       watch, watched, cnt)
            else:  # (a call that passes arrays costs reference counting: test first)
                if hpos[p]:
                    kind[p] = NONE
                    heap_remove(heap, hpos, cnt, toi, p)
                if watched[p]:
                    watch_remove(watch, watched, cnt, p)
    return iterations


@jit
def exact_many_element(S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations,
                       zeno_speed, zeno_impacts, settle_substep, rotation, flat, contact_friction,
                       table_friction, cpair, crec, stats, toi, kind, changed, rest, fbuf, ibuf,
                       element, trace):
    """:func:`exact_element` for many bodies (the ``jam`` level ``LEVEL_MANY_BODIES``, passed
    on as that literal), on the broadphase and the event calendar (``physics.calendar``): the
    scan's events, found without scanning every pair. ``fbuf``, ``ibuf``: the world's buffers,
    from which element ``element``'s calendar rows are taken (``calendar.element_rows``).

    (No ``jam`` parameter: ``kernels.step_element`` calls this through ``static_if`` with the
    flag first, and a call of more than 30 arguments is compiled by Python as a call with
    ``*args``, which numba cannot inline.)

    The event loop (:func:`_many_events`) is compiled without reference counting
    (``jit_uncounted``): the counts numba kept on the arrays of inlined helpers in loops (a
    flight per body per event, the heap, the sweeps) were two thirds of the step's time. The
    settling that may end the step runs here, counted, as in :func:`exact_element`."""
    n = S.shape[0]
    near, box, cnt, heap, hpos, watch, stamp, watched, order, pidx = element_rows(
        fbuf, ibuf, element, n, PA.shape[0])
    t_now, events, iterations, settle = _many_events(
        S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
        zeno_impacts, rotation, flat, contact_friction, table_friction, LEVEL_MANY_BODIES, cpair,
        crec, stats, toi, kind, changed, rest, near, box, cnt, heap, hpos, watch, stamp, watched,
        order, pidx, trace)
    _end_rests(S, Pm, F, rest, t_now, cpair, crec, stats)
    if settle:
        _settle(S, Pm, F, hw, PA, PB, MAT, t_now, dt, settle_substep, _int(MAX_SWEEPS), tol,
                rotation, flat, contact_friction, table_friction, cpair, crec, stats, changed,
                LEVEL_MANY_BODIES, trace, _settle_rows(Pm, cnt, heap, hpos, box, order, pidx))
    stats[STAT_EVENTS] += events
    stats[STAT_ITERATIONS] += iterations


#: share of the smallest body's reach by which a settle's pair list reaches beyond the tolerance
#: (``_settle_rows``): a wider list visits more pairs, a narrower one is made again more often
SETTLE_LIST_MARGIN = 0.25


@jit_inline
def _settle_rows(Pm, cnt, heap, hpos, box, order, pidx):
    """A many-body world's calendar rows as the scratch of the settle that ends its step
    (``rows`` of :func:`_substep`): (pair index, boxes, body order, scratch [N], pair list
    [P], margin). The calendar is emptied: its heap holds the pair list, and the first N heap
    positions (zero again after each use) are the sort's scratch. The margin is
    ``SETTLE_LIST_MARGIN`` of the smallest reach (0 for bodies of no size)."""
    empty_heap(cnt, heap, hpos)
    n = Pm.shape[0]
    reach = math.inf
    for i in range(n):
        reach = min(reach, Pm[i, HALF_LENGTH] + Pm[i, RADIUS])
    return pidx, box, order, hpos[:n], heap, SETTLE_LIST_MARGIN * reach


@jit_inline
def many_rows(Pm, fbuf, ibuf, b):
    """Element b's calendar rows in a many-body world's buffers as the pair lists' scratch
    (``rows`` of :func:`fixed_element`, :func:`_settle_rows`)."""
    _, box, cnt, heap, hpos, _, _, _, order, pidx = element_rows(fbuf, ibuf, b, Pm.shape[0],
                                                                 ibuf[H_P])
    return _settle_rows(Pm, cnt, heap, hpos, box, order, pidx)


@jit_uncounted
def _many_events(S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
                 zeno_impacts, rotation, flat, contact_friction, table_friction, jam, cpair, crec,
                 stats, toi, kind, changed, rest, near, box, cnt, heap, hpos, watch, stamp,
                 watched, order, pidx, trace):
    """The event loop of :func:`exact_many_element` on the element's calendar rows. Returns
    (time reached, events, search iterations, whether the rest of the step must be settled:
    a run of resting bounces or ``max_events`` ended the loop before ``dt``).

    Uncounted (``jit_uncounted``): nothing here allocates; the one callee that does, the block
    solve of a jam (``_jam``), keeps its counting."""
    sweeps = _int(MAX_SWEEPS)
    iterations = _first_predictions(S, Pm, F, hw, PA, PB, dt, tol, max_iterations, rotation, flat,
                                    table_friction, toi, kind, pidx, near, box, cnt, heap, hpos,
                                    watch, watched, order, changed)
    t_now = 0.0
    events = 0
    resting = 0
    settle = False
    while True:
        best = -1
        t_best = dt
        if cnt[CAL_HEAP_SIZE] > 0 and toi[heap[0]] <= dt:
            best = heap[0]
            t_best = toi[best]
        if t_best > t_now:
            _advance(S, Pm, F, t_best - t_now, rotation, table_friction)
            t_now = t_best
        if best == -1:
            break
        events += 1
        changed[:] = 0
        if kind[best] == CHECKPOINT:
            resting += _stalled_in_contact(best, S, Pm, hw, PA, PB, tol)
        else:
            resting += _watched_sweeps(S, Pm, F, hw, PA, PB, MAT, tol, zeno_speed, t_now,
                                       rotation, flat, contact_friction, table_friction, changed,
                                       cpair, crec, stats, sweeps, jam, watch,
                                       cnt[CAL_WATCH_SIZE], near)
            _rest_on_cushions_indexed(S, Pm, F, hw, MAT, rest, changed, pidx, tol, zeno_speed,
                                      contact_friction, table_friction, t_now, cpair, crec,
                                      stats)
            if trace is not None:  # the trace hook
                trace_state(trace, t_now, S)
        iterations += _repredict(best, S, Pm, F, hw, PA, PB, t_now, dt, tol, max_iterations,
                                 rotation, flat, table_friction, toi, kind, changed, pidx, near,
                                 box, cnt, heap, hpos, watch, stamp, watched)
        if events >= max_events or resting >= zeno_impacts:
            settle = t_now < dt
            break
    return t_now, events, iterations, settle
