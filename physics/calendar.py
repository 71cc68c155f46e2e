"""The exact solver's broadphase and event calendar for many bodies (``docs/design.md`` §4).

With N bodies the plain event loop (``solvers.exact_element``) costs O(N^2) per event: it
picks the earliest of all pairs' times of impact, sweeps every pair for simultaneous contacts
and checks every pair for a changed body. From ``layout.CALENDAR_BODIES`` bodies an exact world
runs the same loop on three structures instead, kept in the element's calendar rows
(``layout.calendar_widths``: scratch that comes in with the buffers, nothing is allocated):

* **Swept boxes** (broadphase): each body's axis-aligned box over the rest of the step, from its
  speed and applied force (``_box``), widened by its reach, ``BOX_MARGIN`` of it and the contact
  tolerance. Two bodies whose boxes do not overlap, or a body whose box does not reach a
  cushion, stay apart by more than the tolerance until the step ends: their pair is not
  searched (the plain loop's search finds no contact for it either). At the start of a step the
  overlapping pairs are found by sweep and prune along x; after an event only the changed
  bodies' boxes are recomputed and tested against the others.
* **The calendar**: an indexed binary heap of the pairs with a predicted event (contact or
  checkpoint), ordered by (time, pair): the earliest, ties to the lowest pair, as the plain
  loop's scan picks. An event re-predicts only the pairs of the bodies it changed; a pair's
  heap position is updated in place (a decrease-key heap, so no stale entries to drop).
* **The watch list**: the pairs, in pair order, that may come within the tolerance before the
  step ends (``_near_time``: a lower bound on that time from the centres' distance and speeds).
  The simultaneous-contact sweep visits only those whose time has come, in the order the plain
  sweep visits all pairs: it resolves the very same contacts, bit for bit.

So an event costs the searches of the pairs it touched, O(log P) heap updates, one pass over
the watch list and O(N) box tests per changed body, instead of O(N^2).

The same rows are the scratch of the fixed substeps that settle the rest of a step (and of the
fixed solver's, in a world of as many bodies): **the pair list** (``close_pairs``) holds, in pair
order, the pairs whose boxes about the bodies' current poses meet, a superset of those close
enough to touch, so the substeps' sweeps visit those instead of all P pairs, with the same
outcome bit for bit.
"""

from __future__ import annotations

import math

from spinstrike.physics.contacts import wall_frame
from spinstrike.physics.events import pair_bodies
from spinstrike.physics.jit import jit_inline, jit_uncounted
from spinstrike.physics.layout import (
    BOX_COLUMNS,
    BOX_XMAX,
    BOX_XMIN,
    BOX_YMAX,
    BOX_YMIN,
    CAL_COLUMNS,
    CAL_HEAP_SIZE,
    CAL_WATCH_SIZE,
    F_CALF,
    FRICTION_DECEL,
    FX,
    FY,
    H_FLOAT,
    H_INT,
    HALF_H,
    HALF_LENGTH,
    HALF_W,
    I_CALI,
    I_PAIR_INDEX,
    INV_MASS,
    OMEGA,
    RADIUS,
    VX,
    VY,
    X,
    Y,
)

__all__ = ["BOX_MARGIN", "NEAR_SLACK", "box_meets_wall", "boxes_meet", "close_pairs",
           "element_rows", "empty_heap", "find_sorted", "heap_remove", "heap_set", "listed_pairs",
           "near_time", "reachable_pairs", "rows", "sort_by_xmin", "sort_ints", "speed_bound",
           "stays_clear", "swept_box", "watch_insert", "watch_remove"]

#: share of a body's reach added to its swept box: pairs that pass closer than this are
#: searched (a search of a pair grazing past by little more than the tolerance takes many
#: conservative-advancement iterations, and the plain loop would have searched it too)
BOX_MARGIN = 0.05
#: relative widening of the reach in the straight-flight near time (round-off margin)
NEAR_SLACK = 1e-6


@jit_inline
def element_rows(fbuf, ibuf, b, n, p):
    """The views of element b's calendar rows in a world's buffers: (near [P], box [N, 4],
    counters, heap [P], heap position + 1 [P], watch list [P], stamp [P], on the watch list
    [P], order [N], pair index [N, N + 4]) (``layout.calendar_widths``, ``field_shapes``)."""
    cf = p + n * BOX_COLUMNS
    ci = CAL_COLUMNS + 5 * p + n
    of = ibuf[H_FLOAT + F_CALF] + b * cf
    oi = ibuf[H_INT + I_CALI] + b * ci
    o = ibuf[H_INT + I_PAIR_INDEX]
    pidx = ibuf[o:o + n * (n + 4)].reshape((n, n + 4))
    near, box, cnt, heap, hpos, watch, stamp, watched, order = rows(fbuf[of:of + cf],
                                                                    ibuf[oi:oi + ci], n, p)
    return near, box, cnt, heap, hpos, watch, stamp, watched, order, pidx


@jit_inline
def rows(calf, cali, n, p):
    """The views of one element's calendar rows ``calf``, ``cali``: (near [P], box [N, 4],
    counters, heap [P], heap position + 1 [P], watch list [P], stamp [P], on the watch list
    [P], order [N]) (``layout.calendar_widths``)."""
    near = calf[:p]
    box = calf[p:p + n * BOX_COLUMNS].reshape((n, BOX_COLUMNS))
    cnt = cali[:CAL_COLUMNS]
    o = CAL_COLUMNS
    heap = cali[o:o + p]
    hpos = cali[o + p:o + 2 * p]
    watch = cali[o + 2 * p:o + 3 * p]
    stamp = cali[o + 3 * p:o + 4 * p]
    watched = cali[o + 4 * p:o + 5 * p]
    order = cali[o + 5 * p:o + 5 * p + n]
    return near, box, cnt, heap, hpos, watch, stamp, watched, order


# -- broadphase ---------------------------------------------------------------------------------


@jit_inline
def swept_box(S, Pm, F, i, T, tol, box):
    """Box of every point body i can reach within T seconds (closed-form flight: a line, a
    parabola under its applied force, or a slide that only slows it), into ``box[i]``."""
    ima = Pm[i, INV_MASS]
    dx = abs(S[i, VX]) * T + 0.5 * abs(F[i, FX]) * ima * T * T
    dy = abs(S[i, VY]) * T + 0.5 * abs(F[i, FY]) * ima * T * T
    reach = Pm[i, HALF_LENGTH] + Pm[i, RADIUS]
    pad = reach * (1.0 + BOX_MARGIN) + tol
    box[i, BOX_XMIN] = S[i, X] - dx - pad
    box[i, BOX_XMAX] = S[i, X] + dx + pad
    box[i, BOX_YMIN] = S[i, Y] - dy - pad
    box[i, BOX_YMAX] = S[i, Y] + dy + pad


@jit_inline
def boxes_meet(box, i, j):
    """Whether the swept boxes of bodies i and j overlap."""
    return (box[i, BOX_XMIN] <= box[j, BOX_XMAX] and box[j, BOX_XMIN] <= box[i, BOX_XMAX]
            and box[i, BOX_YMIN] <= box[j, BOX_YMAX] and box[j, BOX_YMIN] <= box[i, BOX_YMAX])


@jit_inline
def box_meets_wall(box, i, wall, hw):
    """Whether body i's swept box reaches cushion ``wall`` (0 left, 1 right, 2 bottom, 3 top)."""
    if wall == 0:
        return box[i, BOX_XMIN] <= -hw[HALF_W]
    if wall == 1:
        return box[i, BOX_XMAX] >= hw[HALF_W]
    if wall == 2:
        return box[i, BOX_YMIN] <= -hw[HALF_H]
    return box[i, BOX_YMAX] >= hw[HALF_H]


@jit_inline
def _straight(S, Pm, F, i, table_friction):
    """Whether body i flies in a straight line at constant velocity (no applied force, not
    slowed by the cloth)."""
    if Pm[i, INV_MASS] != 0.0 and (F[i, FX] != 0.0 or F[i, FY] != 0.0):
        return False
    if table_friction and Pm[i, FRICTION_DECEL] > 0.0:
        return S[i, VX] == 0.0 and S[i, VY] == 0.0
    return True


@jit_inline
def _first_within(d2, du, u2, reach):
    """First time >= 0 at which a distance ``|d + u t|`` (``d2 = |d|^2``, ``du = d.u``,
    ``u2 = |u|^2``) is at most ``reach``: 0 if it is now, ``inf`` if never."""
    r2 = reach * reach
    if d2 <= r2:
        return 0.0
    if du >= 0.0 or u2 == 0.0:
        return math.inf
    disc = du * du - u2 * (d2 - r2)
    if disc < 0.0:
        return math.inf
    return (d2 - r2) / (-du + math.sqrt(disc))


@jit_inline
def near_time(p, S, Pm, F, hw, PA, PB, tol, table_friction):
    """A time (s from now) before which pair p's gap stays above ``tol``, from the distance of
    the centres less the bodies' reaches (a lower bound of the gap); 0 if it may be within
    ``tol`` now, ``inf`` if never. Bodies in straight flight: the first time their relative
    line comes that close (``reach (1 + NEAR_SLACK)``); otherwise their speeds and applied
    accelerations bound how fast the distance closes, with a margin of 2."""
    a, b, wall = pair_bodies(p, PA, PB, S.shape[0])
    ra = Pm[a, HALF_LENGTH] + Pm[a, RADIUS]
    straight = _straight(S, Pm, F, a, table_friction)
    if wall >= 0:
        ix, iy, off = wall_frame(wall, hw[HALF_W], hw[HALF_H])
        lower = ix * S[a, X] + iy * S[a, Y] + off - ra
        if straight:
            reach = (ra + tol) * (1.0 + NEAR_SLACK)
            s = lower + ra
            if s <= reach:
                return 0.0
            rate = ix * S[a, VX] + iy * S[a, VY]
            return (s - reach) / -rate if rate < 0.0 else math.inf
        speed = math.sqrt(S[a, VX] ** 2 + S[a, VY] ** 2)
        acc = math.sqrt(F[a, FX] ** 2 + F[a, FY] ** 2) * Pm[a, INV_MASS]
    else:
        rb = Pm[b, HALF_LENGTH] + Pm[b, RADIUS]
        dx = S[b, X] - S[a, X]
        dy = S[b, Y] - S[a, Y]
        if straight and _straight(S, Pm, F, b, table_friction):
            ux = S[b, VX] - S[a, VX]
            uy = S[b, VY] - S[a, VY]
            return _first_within(dx * dx + dy * dy, dx * ux + dy * uy, ux * ux + uy * uy,
                                 (ra + rb + tol) * (1.0 + NEAR_SLACK))
        lower = math.sqrt(dx * dx + dy * dy) - ra - rb
        speed = (math.sqrt(S[a, VX] ** 2 + S[a, VY] ** 2)
                 + math.sqrt(S[b, VX] ** 2 + S[b, VY] ** 2))
        acc = (math.sqrt(F[a, FX] ** 2 + F[a, FY] ** 2) * Pm[a, INV_MASS]
               + math.sqrt(F[b, FX] ** 2 + F[b, FY] ** 2) * Pm[b, INV_MASS])
    d = 0.5 * (lower - tol)
    if not d > 0.0:
        return 0.0
    if acc == 0.0:
        return d / speed if speed > 0.0 else math.inf
    return 2.0 * d / (speed + math.sqrt(speed * speed + 2.0 * acc * d))


@jit_inline
def stays_clear(p, S, Pm, F, hw, PA, PB, T, tol, table_friction):
    """Whether pair p provably stays apart by more than ``tol`` plus ``BOX_MARGIN`` of the
    reaches for the next T seconds, both bodies flying straight (a pair whose relative line
    passes that far needs no search: the search finds no contact either)."""
    a, b, wall = pair_bodies(p, PA, PB, S.shape[0])
    if not _straight(S, Pm, F, a, table_friction):
        return False
    ra = Pm[a, HALF_LENGTH] + Pm[a, RADIUS]
    if wall >= 0:
        ix, iy, off = wall_frame(wall, hw[HALF_W], hw[HALF_H])
        s = ix * S[a, X] + iy * S[a, Y] + off
        rate = ix * S[a, VX] + iy * S[a, VY]
        return s + min(rate, 0.0) * T > ra * (1.0 + BOX_MARGIN) + tol
    if not _straight(S, Pm, F, b, table_friction):
        return False
    rb = Pm[b, HALF_LENGTH] + Pm[b, RADIUS]
    dx = S[b, X] - S[a, X]
    dy = S[b, Y] - S[a, Y]
    ux = S[b, VX] - S[a, VX]
    uy = S[b, VY] - S[a, VY]
    t = _first_within(dx * dx + dy * dy, dx * ux + dy * uy, ux * ux + uy * uy,
                      (ra + rb) * (1.0 + BOX_MARGIN) + tol)
    return t > T


# -- the settle's pair list ----------------------------------------------------------------------


@jit_inline
def speed_bound(S, Pm, F, i, T):
    """Fastest a point of body i's core can move within T: centre, spin, applied force."""
    return (math.sqrt(S[i, VX] ** 2 + S[i, VY] ** 2) + abs(S[i, OMEGA]) * Pm[i, HALF_LENGTH]
            + math.sqrt(F[i, FX] ** 2 + F[i, FY] ** 2) * Pm[i, INV_MASS] * T)


@jit_uncounted
def close_pairs(S, Pm, hw, pad, pidx, box, order, seen, out):
    """The pairs whose gap may be at most ``pad`` now (:func:`listed_pairs` of each body's
    centre plus its reach, a bounding circle whatever its angle, and ``pad``): a pair left out
    is more than ``pad`` apart (two bodies more than ``2 pad``)."""
    finite = True
    for i in range(S.shape[0]):
        finite &= _box(S, Pm, i, Pm[i, HALF_LENGTH] + Pm[i, RADIUS] + pad, box)
    return listed_pairs(hw, pidx, box, order, seen, out, finite)


@jit_uncounted
def reachable_pairs(S, Pm, F, hw, T, pidx, box, order, seen, out):
    """The pairs whose bodies (or a body and a cushion) could come within their reach of each
    other within T seconds (:func:`listed_pairs` of each body's centre plus twice its reach and
    its :func:`speed_bound` over T): every pair left out is farther apart than the reaches and
    flights of its bodies."""
    finite = True
    for i in range(S.shape[0]):
        finite &= _box(S, Pm, i, 2.0 * (Pm[i, HALF_LENGTH] + Pm[i, RADIUS])
                       + speed_bound(S, Pm, F, i, T) * T, box)
    return listed_pairs(hw, pidx, box, order, seen, out, finite)


@jit_inline
def _box(S, Pm, i, half, box):
    """Body i's box, its centre plus ``half`` (widened by ``NEAR_SLACK`` for round-off), into
    ``box[i]``; whether it is finite."""
    half *= 1.0 + NEAR_SLACK
    box[i, BOX_XMIN] = S[i, X] - half
    box[i, BOX_XMAX] = S[i, X] + half
    box[i, BOX_YMIN] = S[i, Y] - half
    box[i, BOX_YMAX] = S[i, Y] + half
    return math.isfinite(half) and math.isfinite(S[i, X]) and math.isfinite(S[i, Y])


@jit_uncounted
def listed_pairs(hw, pidx, box, order, seen, out, finite):
    """The pairs (in pair order, into ``out``; returns how many) of the bodies whose ``box``es
    overlap, and of a body and a cushion its box reaches (sweep and prune along x, the bodies
    re-sorted from ``order``); every pair when a box is not ``finite`` (NaN boxes cannot be
    sorted; the passes find nothing to do there anyway). ``seen``: scratch [N], zero on
    return."""
    n = order.shape[0]
    if not finite:
        for p in range(out.shape[0]):
            out[p] = p
        return out.shape[0]
    sort_by_xmin(order, box, n, seen)
    for i in range(n):
        seen[i] = 0
    m = 0
    for k in range(n):
        i = order[k]
        for q in range(k + 1, n):
            j = order[q]
            if box[j, BOX_XMIN] > box[i, BOX_XMAX]:
                break
            p = pidx[i, j]
            if p >= 0 and boxes_meet(box, i, j):
                out[m] = p
                m += 1
        for w in range(4):
            p = pidx[i, n + w]
            if p >= 0 and box_meets_wall(box, i, w, hw):
                out[m] = p
                m += 1
    sort_ints(out, m)
    return m


@jit_inline
def empty_heap(cnt, heap, hpos):
    """Take every pair out of the calendar (the settle that ends a step uses its rows as
    scratch; the next step's first predictions fill it afresh)."""
    for k in range(cnt[CAL_HEAP_SIZE]):
        hpos[heap[k]] = 0
    cnt[CAL_HEAP_SIZE] = 0


# -- the calendar: an indexed binary heap of pairs by (time, pair) -------------------------------


@jit_inline
def _before(toi, p, q):
    return toi[p] < toi[q] or (toi[p] == toi[q] and p < q)


@jit_uncounted
def _sift_up(heap, hpos, toi, k):
    p = heap[k]
    while k > 0:
        up = (k - 1) >> 1
        q = heap[up]
        if not _before(toi, p, q):
            break
        heap[k] = q
        hpos[q] = k + 1
        k = up
    heap[k] = p
    hpos[p] = k + 1
    return k


@jit_uncounted
def _sift_down(heap, hpos, toi, k, size):
    p = heap[k]
    while True:
        c = 2 * k + 1
        if c >= size:
            break
        if c + 1 < size and _before(toi, heap[c + 1], heap[c]):
            c += 1
        q = heap[c]
        if not _before(toi, q, p):
            break
        heap[k] = q
        hpos[q] = k + 1
        k = c
    heap[k] = p
    hpos[p] = k + 1


@jit_inline
def heap_set(heap, hpos, cnt, toi, p):
    """Put pair p in the calendar at its time ``toi[p]``, or move it there."""
    k = hpos[p] - 1
    if k < 0:
        k = cnt[CAL_HEAP_SIZE]
        cnt[CAL_HEAP_SIZE] = k + 1
        heap[k] = p
    k2 = _sift_up(heap, hpos, toi, k)
    if k2 == k:
        _sift_down(heap, hpos, toi, k, cnt[CAL_HEAP_SIZE])


@jit_inline
def heap_remove(heap, hpos, cnt, toi, p):
    """Take pair p out of the calendar (nothing if it is not in it)."""
    k = hpos[p] - 1
    if k < 0:
        return
    hpos[p] = 0
    last = cnt[CAL_HEAP_SIZE] - 1
    cnt[CAL_HEAP_SIZE] = last
    if k == last:
        return
    heap[k] = heap[last]
    hpos[heap[k]] = k + 1
    k2 = _sift_up(heap, hpos, toi, k)
    if k2 == k:
        _sift_down(heap, hpos, toi, k, last)


# -- the watch list: pairs in pair order ---------------------------------------------------------


@jit_inline
def find_sorted(watch, size, p):
    """First index of the sorted ``watch[:size]`` whose pair is >= p."""
    lo = 0
    hi = size
    while lo < hi:
        mid = (lo + hi) >> 1
        if watch[mid] < p:
            lo = mid + 1
        else:
            hi = mid
    return lo


@jit_inline
def watch_insert(watch, watched, cnt, p):
    """Add pair p to the watch list, kept in pair order (nothing if it is on it)."""
    if watched[p]:
        return
    watched[p] = 1
    size = cnt[CAL_WATCH_SIZE]
    k = find_sorted(watch, size, p)
    for m in range(size, k, -1):
        watch[m] = watch[m - 1]
    watch[k] = p
    cnt[CAL_WATCH_SIZE] = size + 1


@jit_inline
def watch_remove(watch, watched, cnt, p):
    """Take pair p off the watch list (nothing if it is not on it)."""
    if not watched[p]:
        return
    watched[p] = 0
    size = cnt[CAL_WATCH_SIZE]
    k = find_sorted(watch, size, p)
    for m in range(k, size - 1):
        watch[m] = watch[m + 1]
    cnt[CAL_WATCH_SIZE] = size - 1


# -- in-place heapsorts (no allocation) -----------------------------------------------------------


@jit_uncounted
def sort_ints(a, size):
    """Sort ``a[:size]`` ascending in place."""
    for start in range(size // 2 - 1, -1, -1):
        _sift_ints(a, start, size)
    for end in range(size - 1, 0, -1):
        a[0], a[end] = a[end], a[0]
        _sift_ints(a, 0, end)


@jit_inline
def _sift_ints(a, k, size):
    v = a[k]
    while True:
        c = 2 * k + 1
        if c >= size:
            break
        if c + 1 < size and a[c + 1] > a[c]:
            c += 1
        if a[c] <= v:
            break
        a[k] = a[c]
        k = c
    a[k] = v


@jit_uncounted
def sort_by_xmin(order, box, size, seen):
    """Sort the bodies ``order[:size]`` by their boxes' lower x in place, by insertion from the
    order they had (the last step's: the boxes move little in a step, so it is nearly sorted
    and this costs about one comparison a body, where sorting from scratch cost ~15% of a
    64-puck step). An ``order`` that is not a permutation of the bodies (a new world's zeroed
    row) starts from ``0..size-1``. ``seen``: scratch [size]. Pairs are searched whatever the
    order among equal keys, and the calendar orders its events by (time, pair): the events do
    not depend on it."""
    for i in range(size):
        seen[i] = 0
    valid = True
    for k in range(size):
        i = order[k]
        if i < 0 or i >= size or seen[i]:
            valid = False
            break
        seen[i] = 1
    if not valid:
        for k in range(size):
            order[k] = k
    for k in range(1, size):
        v = order[k]
        key = box[v, BOX_XMIN]
        m = k - 1
        while m >= 0 and box[order[m], BOX_XMIN] > key:
            order[m + 1] = order[m]
            m -= 1
        order[m + 1] = v
