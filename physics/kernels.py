"""The interface for compiled steps: what a kernel outside ``physics`` (the envs' fused control
step and strike, ``envs/fast.py``) needs to run the world's own solver inside its own loop.

A world keeps every array the kernels touch in two packed buffers (``World.buffers``, laid out
by ``physics.layout``). A *batch kernel* takes those two buffers first, then its own arrays,
then the world's compile-time flags (:data:`FLAGS`); it calls :func:`unpack` once per block of
elements and :func:`step_element` for each element it steps, so an env kernel and
``world.step`` run the very same element kernel and agree bit for bit. :class:`BatchKernel`
bundles a kernel's serial and parallel versions (and, for the pymunk backend, which steps
outside numba, a Python version); ``World.run`` is the one place that picks among them, appends
the flags and books the step.

**Compile-time flags.** The solver kind, the effects that have code paths of their own,
whether the scene's contacts can jam and whether a pair can lie flat are passed as numba
*literal* arguments (``numba.literally`` in each batch kernel); each combination is compiled
(and cached) once. Where a flag picks a call through :func:`~spinstrike.physics.jit.static_if`
(the solver kind, the jam block solve, the hold, the many-body calendar or the scan, flat
pairs) the call a flag rules out is never typed or compiled (the jam block solve alone is a
quarter of the strike kernel's compile time; the scan, a third of a many-body world's). The
effects' flags are tested in ordinary ``if`` statements, which numba does not prune: an effect's
functions are compiled into every kernel and skipped at run time (their code runs only where the
effect is listed and its parameter is above zero, ``tests/physics/test_effects.py``).
"""

from __future__ import annotations

import math
from collections import namedtuple
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from numba import literally

from spinstrike.physics.events import pair_bodies, pair_geometry
from spinstrike.physics.jit import jit, jit_inline, jit_parallel, static_if
from spinstrike.physics.layout import (
    CF_DT,
    CF_SETTLE,
    CF_TOL,
    CF_ZENO_SPEED,
    CI_ITERATIONS,
    CI_MAX_EVENTS,
    CI_MAX_ITERATIONS,
    CI_SUBSTEPS,
    CI_ZENO_IMPACTS,
    F_CREC,
    F_FCFG,
    F_FORCES,
    F_HALF,
    F_MATERIALS,
    F_PARAMS,
    F_REST,
    F_STATE,
    F_TIME,
    F_TOI,
    FALLBACK_NONFINITE,
    FALLBACK_UNRESOLVED,
    FCFG_SIZE,
    FORCE_COLUMNS,
    FX,
    FY,
    H_B,
    H_FLOAT,
    H_INT,
    H_M,
    H_N,
    H_P,
    HALF_COLUMNS,
    HALF_H,
    HALF_LENGTH,
    HALF_W,
    I_CHANGED,
    I_CPAIR,
    I_ICFG,
    I_KIND,
    I_PAIR_A,
    I_PAIR_B,
    I_STATS,
    ICFG_SIZE,
    INV_MASS,
    LEVEL_MANY_BODIES,
    MATERIAL_COLUMNS,
    OMEGA,
    PARAM_COLUMNS,
    REC_COLUMNS,
    REC_J,
    REC_JT,
    REC_WATCHED_J,
    REST_COLUMNS,
    STAT_COLUMNS,
    STAT_FALLBACK,
    STAT_WATCH,
    STATE_COLUMNS,
    VX,
    VY,
)
from spinstrike.physics.solvers import (
    exact_element,
    exact_many_element,
    fixed_element,
    many_rows,
    untraced,
)

__all__ = ["BLOCK", "FLAGS", "Flags", "STEP", "TRAVEL_LIMIT", "BatchKernel", "Views",
           "element_overlap", "n_blocks", "step_element", "travel", "unpack"]

#: elements per block of the parallel kernels (each block unpacks the buffers once)
BLOCK = 64

#: a world's arrays, as :func:`unpack` rebuilds them from the packed buffers: state ``S``,
#: parameters ``Pm``, forces ``F``, table half sizes ``HW``, pair materials ``MAT``, contact
#: records ``crec``, time-of-impact scratch ``toi``, float config ``fcfg``, pair bodies ``PA``,
#: ``PB``, contact pairs ``cpair``, statistics ``stats``, search kinds ``kind``, changed flags
#: ``changed``, int config ``icfg``, clock ``clock`` (shapes: ``layout.field_shapes``); the two
#: buffers ``fbuf``, ``ibuf`` themselves (the exact solver's calendar takes its rows from them,
#: ``calendar.element_rows``, only where it is compiled); and the force components held back by
#: cushions ``rest`` (``solvers._rest_on_cushions``)
Views = namedtuple("Views", ["S", "Pm", "F", "HW", "MAT", "crec", "toi", "fcfg", "PA", "PB",
                             "cpair", "stats", "kind", "changed", "icfg", "clock", "fbuf", "ibuf",
                             "rest"])


@jit_inline
def _floats(fbuf, ibuf, field, size):
    o = ibuf[H_FLOAT + field]
    return fbuf[o:o + size]


@jit_inline
def _ints(ibuf, field, size):
    o = ibuf[H_INT + field]
    return ibuf[o:o + size]


@jit
def unpack(fbuf, ibuf):
    """The named arrays of a world's two packed buffers, as :data:`Views`."""
    B = ibuf[H_B]
    N = ibuf[H_N]
    P = ibuf[H_P]
    M = ibuf[H_M]
    S = _floats(fbuf, ibuf, F_STATE, B * N * STATE_COLUMNS).reshape((B, N, STATE_COLUMNS))
    Pm = _floats(fbuf, ibuf, F_PARAMS, B * N * PARAM_COLUMNS).reshape((B, N, PARAM_COLUMNS))
    F = _floats(fbuf, ibuf, F_FORCES, B * N * FORCE_COLUMNS).reshape((B, N, FORCE_COLUMNS))
    HW = _floats(fbuf, ibuf, F_HALF, B * HALF_COLUMNS).reshape((B, HALF_COLUMNS))
    MAT = _floats(fbuf, ibuf, F_MATERIALS, B * P * MATERIAL_COLUMNS).reshape(
        (B, P, MATERIAL_COLUMNS))
    crec = _floats(fbuf, ibuf, F_CREC, B * (M + 1) * REC_COLUMNS).reshape(
        (B, M + 1, REC_COLUMNS))
    toi = _floats(fbuf, ibuf, F_TOI, B * P).reshape((B, P))
    fcfg = _floats(fbuf, ibuf, F_FCFG, FCFG_SIZE)
    clock = _floats(fbuf, ibuf, F_TIME, B)
    PA = _ints(ibuf, I_PAIR_A, P)
    PB = _ints(ibuf, I_PAIR_B, P)
    cpair = _ints(ibuf, I_CPAIR, B * M).reshape((B, M))
    stats = _ints(ibuf, I_STATS, B * STAT_COLUMNS).reshape((B, STAT_COLUMNS))
    kind = _ints(ibuf, I_KIND, B * P).reshape((B, P))
    changed = _ints(ibuf, I_CHANGED, B * N).reshape((B, N))
    icfg = _ints(ibuf, I_ICFG, ICFG_SIZE)
    rest = _floats(fbuf, ibuf, F_REST, B * N * REST_COLUMNS).reshape((B, N, REST_COLUMNS))
    return Views(S, Pm, F, HW, MAT, crec, toi, fcfg, PA, PB, cpair, stats, kind, changed, icfg,
                 clock, fbuf, ibuf, rest)


#: the compile-time flags every batch kernel takes last, in this order (``World.flags``): the
#: solver is ``fixed`` (else exact); the ``rotation``, ``contact_friction`` and
#: ``table_friction`` effects; whether the scene's contacts can ``jam``, a level
#: (``layout.LEVEL``): 0, one contact pair (sequential impulses always converge in one sweep);
#: 1, one pair with contact friction (it can jam; frictionless, it is held); 2, two or more
#: pairs; 3, the same among ``layout.CALENDAR_BODIES`` or
#: more bodies, where an exact world steps on its broadphase and event calendar
#: (``physics.calendar``) and the substeps of its settling, or of the fixed solver, sweep only
#: the pairs close enough to touch; whether a contact pair can lie ``flat`` (two rods, or a rod
#: and a cushion: ``contacts.flat_points``)
FLAGS = ("fixed", "rotation", "contact_friction", "table_friction", "jam", "flat")
#: a world's flags by name (``World.flags``), in :data:`FLAGS` order
Flags = namedtuple("Flags", FLAGS)


@jit_inline
def _no_rows(Pm, fbuf, ibuf, b):
    """No pair-list scratch: a world of few bodies visits every pair."""
    return None


#: the fixed solver's pair-list scratch (``solvers.many_rows``) in a many-body world (the
#: ``jam`` level ``LEVEL_MANY_BODIES``), None below it
_rows_if = static_if(many_rows, level=LEVEL_MANY_BODIES, otherwise=_no_rows)


@jit_inline
def _fixed(v, b, dt, rotation, flat, contact_friction, table_friction, jam, trace):
    """The fixed solver's step of element b (one positional-correction sweep a substep, no
    block solve)."""
    fixed_element(v.S[b], v.Pm[b], v.F[b], v.HW[b], v.PA, v.PB, v.MAT[b], dt,
                  v.icfg[CI_SUBSTEPS], v.icfg[CI_ITERATIONS], 0.0, 0.0, rotation, flat,
                  contact_friction, table_friction, v.cpair[b], v.crec[b], v.stats[b],
                  v.changed[b], 1, False, trace, _rows_if(jam, v.Pm[b], v.fbuf, v.ibuf, b))


#: the exact solver's calendar, only at the ``jam`` level ``LEVEL_MANY_BODIES`` (exact worlds of
#: ``CALENDAR_BODIES`` or more bodies): other worlds never compile it, and their exact step
#: keeps its own argument list
_many_if = static_if(exact_many_element, level=LEVEL_MANY_BODIES)


@jit_inline
def _exact_many(v, b, dt, rotation, flat, contact_friction, table_friction, jam, trace):
    """The exact solver's step of element b on its calendar, at the ``jam`` level
    ``LEVEL_MANY_BODIES`` (no code below it)."""
    _many_if(jam, v.S[b], v.Pm[b], v.F[b], v.HW[b], v.PA, v.PB, v.MAT[b], dt, v.fcfg[CF_TOL],
             v.icfg[CI_MAX_EVENTS], v.icfg[CI_MAX_ITERATIONS], v.fcfg[CF_ZENO_SPEED],
             v.icfg[CI_ZENO_IMPACTS], v.fcfg[CF_SETTLE], rotation, flat, contact_friction,
             table_friction, v.cpair[b], v.crec[b], v.stats[b], v.toi[b], v.kind[b],
             v.changed[b], v.rest[b], v.fbuf, v.ibuf, b, trace)


#: one solver or the other, by the world's literal ``fixed`` flag: the other is never compiled
#: (a fixed world of many bodies has the ``jam`` level ``LEVEL_MANY_BODIES`` too, for its pair
#: lists, and must not compile the exact solver's calendar)
_fixed_if = static_if(_fixed)
_exact_many_unless = static_if(_exact_many, negate=True)
#: the scan (``exact_element``) only below the ``jam`` level ``LEVEL_MANY_BODIES``, where the
#: calendar steps the world instead. (A test inside the solver would not do: numba prunes a branch
#: on a literal argument compared with a literal, not with a named constant, so a many-body world
#: compiled the whole scan, unused: ~30 s of its first run.)
_scan_unless = static_if(exact_element, negate=True, level=LEVEL_MANY_BODIES)


@jit_inline
def _scan(S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
          zeno_impacts, settle_substep, rotation, flat, contact_friction, table_friction, jam,
          cpair, crec, stats, toi, kind, changed, rest, trace):
    _scan_unless(jam, S, Pm, F, hw, PA, PB, MAT, dt, tol, max_events, max_iterations, zeno_speed,
                 zeno_impacts, settle_substep, rotation, flat, contact_friction, table_friction,
                 jam, cpair, crec, stats, toi, kind, changed, rest, trace)


_exact_unless = static_if(_scan, negate=True)


#: the longest travel of a body in one step on a walled table, in units of the table's smaller
#: half size, that a step takes (walk W24a F2): a body travelling ``D`` metres is folded back
#: onto the table with a round-off of ``D * 2**-52``, 2**-20 (1e-6) of the half size at this
#: bound; ~2**52 half sizes beyond it, the cushions' correction cancelled to round-off and put
#: bodies at the table's centre or off it, with no word from the fixed solver. No scene near
#: physical speeds comes close: a 0.6 m x 0.4 m table's bound in a 20 ms step is 4e11 m/s.
TRAVEL_LIMIT = 2.0 ** 32


@jit_inline
def travel(S, Pm, F, i, dt):
    """An upper bound on body i's travel in a step of ``dt`` seconds under its own motion and
    force, m: its centre's speed plus its spin times its half-length (a rod's tip), times
    ``dt``, plus what its force adds, ``|F| dt^2 / (2 m)``. (A collision can only pass on
    speeds of this order, a light body's up to twice a heavy one's.)"""
    speed = math.hypot(S[i, VX], S[i, VY]) + abs(S[i, OMEGA]) * Pm[i, HALF_LENGTH]
    push = math.hypot(F[i, FX], F[i, FY]) * Pm[i, INV_MASS]
    return speed * dt + 0.5 * push * dt * dt


@jit_inline
def _unresolved(S, Pm, F, hw, dt):
    """True if a body of the element would travel beyond :data:`TRAVEL_LIMIT` half sizes of
    its walled table in this step (never on an unbounded table, whose half sizes are inf)."""
    limit = TRAVEL_LIMIT * min(hw[HALF_W], hw[HALF_H])
    if not math.isfinite(limit):
        return False
    for i in range(S.shape[0]):
        if travel(S, Pm, F, i, dt) > limit:
            return True
    return False


@jit
def step_element(v, b, dt, fixed, rotation, contact_friction, table_friction, jam, flat,
                 trace=None):
    """Advance element b of a world's views by dt seconds with the world's solver, from
    statistics zeroed here; the clock advances too. ``fixed`` to ``flat`` are the world's
    compile-time flags (:data:`FLAGS`); ``trace``: the solvers' trace hook (``solvers.Trace``),
    passed through (``solvers.untraced``: nothing recorded, the same compiled solver; None:
    nothing recorded, the hook compiled away in a solver of its own). Returns the element's
    ``fallback`` statistic (``layout.FALLBACK``), checked last for a state that is no longer
    finite (``FALLBACK_NONFINITE``: inputs beyond what float64 carries, e.g. 1e160 m/s) or,
    before the step, ``FALLBACK_UNRESOLVED`` (a body's travel beyond :data:`TRAVEL_LIMIT` half
    sizes of a walled table: the element is not stepped, its state and clock unchanged)."""
    for k in range(STAT_COLUMNS):  # the watched pair stays
        if k != STAT_WATCH:
            v.stats[b, k] = 0
    m = v.cpair.shape[1]  # the sums of the contacts beyond the records
    v.crec[b, m, REC_J] = 0.0
    v.crec[b, m, REC_JT] = 0.0
    v.crec[b, m, REC_WATCHED_J] = 0.0
    if _unresolved(v.S[b], v.Pm[b], v.F[b], v.HW[b], dt):
        v.stats[b, STAT_FALLBACK] = FALLBACK_UNRESOLVED
        return FALLBACK_UNRESOLVED
    v.clock[b] += dt
    _fixed_if(fixed, v, b, dt, rotation, flat, contact_friction, table_friction, jam, trace)
    _exact_unless(fixed, v.S[b], v.Pm[b], v.F[b], v.HW[b], v.PA, v.PB, v.MAT[b], dt,
                  v.fcfg[CF_TOL], v.icfg[CI_MAX_EVENTS], v.icfg[CI_MAX_ITERATIONS],
                  v.fcfg[CF_ZENO_SPEED], v.icfg[CI_ZENO_IMPACTS], v.fcfg[CF_SETTLE], rotation, flat,
                  contact_friction, table_friction, jam, v.cpair[b], v.crec[b], v.stats[b],
                  v.toi[b], v.kind[b], v.changed[b], v.rest[b], trace)
    _exact_many_unless(fixed, v, b, dt, rotation, flat, contact_friction, table_friction, jam,
                       trace)
    for i in range(v.S.shape[1]):
        for k in range(v.S.shape[2]):
            if not math.isfinite(v.S[b, i, k]):
                v.stats[b, STAT_FALLBACK] = FALLBACK_NONFINITE
    return v.stats[b, STAT_FALLBACK]


@jit
def element_overlap(S, Pm, hw, PA, PB, tol):
    """(pair, gap) of the first contact pair of one element (state ``S [N, 6]``) that overlaps
    by more than ``tol`` metres, or (-1, 0.0): the check every placement passes."""
    n = S.shape[0]
    for p in range(PA.shape[0]):
        a, c, wall = pair_bodies(p, PA, PB, n)
        g = pair_geometry(S, Pm, a, c, wall, hw[HALF_W], hw[HALF_H])[0]
        if g < -tol:
            return p, g
    return -1, 0.0


@jit_inline
def n_blocks(n):
    """Blocks of :data:`BLOCK` elements covering a batch of n (the parallel kernels' prange)."""
    return (n + BLOCK - 1) // BLOCK


# The world's own step. A batch kernel's body steps a range of elements and unpacks the buffers
# once for it, not per element (unpacking makes sixteen views, each with reference-count
# traffic: 0.7 us an element when done inside the loop); the serial version is the body over the
# whole batch, called directly (every compiled layer above the solver costs its own compile, as
# numba links and optimises a function's callees again), and the parallel version spreads blocks
# of elements over the threads.


@jit
def step_body(fbuf, ibuf, start, stop, fixed, rotation, cf, tf, jam, flat):
    """Step elements ``start..stop-1`` of a world by its ``dt`` (``fcfg``); return the worst
    ``fallback`` statistic among them (``layout.FALLBACK``, ordered by severity)."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    v = unpack(fbuf, ibuf)
    dt = v.fcfg[CF_DT]
    off = untraced(v.S.shape[1])  # a traced step then runs the same compiled solver
    worst = 0
    for b in range(start, stop):
        worst = max(worst, step_element(v, b, dt, fixed, rotation, cf, tf, jam, flat, off))
    return worst


@jit_parallel
def step_parallel(fbuf, ibuf, fixed, rotation, cf, tf, jam, flat):
    """:func:`step_body` over the whole batch in parallel threads, a block of elements a task."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    n = ibuf[H_B]
    worst = 0
    for k in numba.prange(n_blocks(n)):
        worst = max(worst, step_body(fbuf, ibuf, k * BLOCK, min(n, (k + 1) * BLOCK), fixed,
                                     rotation, cf, tf, jam, flat))
    return worst


@dataclass(frozen=True, eq=False)  # compared and hashed by identity: World.run looks it up
class BatchKernel:
    """A batch kernel in the versions ``World.run`` picks from.

    Attributes:
        name: what it does (for error messages).
        body: ``body(fbuf, ibuf, *args, start, stop, *flags)``, compiled: elements
            ``start..stop-1``, in this thread (``flags``: the world's :data:`FLAGS`, literal
            arguments); the serial version is the body over the whole batch.
        parallel: the same in parallel threads (used from ``world.PARALLEL_BATCH`` elements).
        stepwise: ``stepwise(world, *args)`` in Python for a world on the pymunk backend, which
            steps outside numba (``None``: not available there).
    """

    name: str
    body: Callable[..., Any]
    parallel: Callable[..., Any]
    stepwise: Callable[..., Any] | None = None
    _entries: dict = field(default_factory=dict, compare=False, repr=False)

    def entry(self, parallel: bool, fbuf: np.ndarray, ibuf: np.ndarray, args: tuple,
              tail: tuple) -> Callable[..., Any]:
        """The compiled callable to run as ``entry(fbuf, ibuf, *args, *tail)``: the parallel
        version (``tail``: the literal ``flags``) or the body (``tail``: ``0, B, *flags``).

        The specialisation for the argument types and the literal flags is compiled (or loaded
        from the cache) once and its entry point returned: a dispatcher called with plain
        booleans for ``literally`` arguments would re-run numba's front end on every call
        (4 ms), and its first, non-literal attempt would count as a cache miss.
        """
        dispatcher = self.parallel if parallel else self.body
        if not hasattr(dispatcher, "compile"):  # NUMBA_DISABLE_JIT: a plain function
            return dispatcher
        n_flags = len(FLAGS)
        key = (parallel, tail[-n_flags:])
        entry = self._entries.get(key)
        if entry is None:
            plain = (fbuf, ibuf, *args, *tail[:-n_flags])
            sig = (*(numba.typeof(a) for a in plain),
                   *(numba.types.literal(f) for f in tail[-n_flags:]))
            entry = self._entries[key] = dispatcher.compile(sig)
        return entry


def _backend_step(world) -> int:
    return world._step_backend()


#: the world's own step (``World.step``)
STEP = BatchKernel("step", step_body, step_parallel, _backend_step)
