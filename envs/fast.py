"""The envs' hot loops as compiled batch kernels: the control envs' step, and the one-strike envs'
strike (see the section further down).

Per element: validate and clip the action, turn it into the mallet's force under the speed limit
(``limit_force``), measure the target, run the world's own element step
(``physics.kernels.step_element``, the kernel ``world.step`` runs), count the mallet's hits on the
target from the contact records, reward, and write the observation. Nothing here changes the
physics: a single env and a vector env agree bit for bit with ``world.step``. What it removes is
the Python and numpy work around the kernel, which at B = 1 cost more than the physics.

Each kernel is a ``physics.kernels.BatchKernel`` (:data:`CONTROL_STEP`, :data:`STRIKE`) that the
tasks hand to ``world.run``, which picks the serial, parallel or (pymunk backend) Python version.
The tasks' own packed rows are declared below as ``physics.layout.Table`` s, like the world's.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numba
import numpy as np
from numba import literally

from spinstrike.envs.layout import CONTROL_LAYOUT
from spinstrike.physics.jit import jit, jit_inline, jit_parallel
from spinstrike.physics.kernels import BLOCK as BLOCK
from spinstrike.physics.kernels import (
    BatchKernel,
    element_overlap,
    n_blocks,
    step_element,
    unpack,
)
from spinstrike.physics.layout import (
    ANGLE,
    CF_DT,
    CF_OVERLAP_TOL,
    CF_TOL,
    CF_ZENO_SPEED,
    CI_CONTACT_FRICTION,
    CI_ROTATION,
    CI_TABLE_FRICTION,
    FORCE_COLUMNS,
    FX,
    FY,
    H_B,
    H_M,
    HALF_H,
    HALF_LENGTH,
    HALF_W,
    INV_MASS,
    OMEGA,
    RADIUS,
    REC_J,
    REC_NX,
    REC_NY,
    REC_PX,
    REC_PY,
    REC_TIME,
    REC_WATCHED_J,
    STAT_CONTACTS,
    STAT_FALLBACK,
    STAT_WATCHED,
    STATE_COLUMNS,
    VX,
    VY,
    Table,
    X,
    Y,
)
from spinstrike.physics.motion import flight
from spinstrike.physics.solvers import (
    TRACE_COUNT,
    TRACE_DROPPED,
    TRACE_ENTRIES,
    Trace,
    rests_on,
    trace_state,
    untraced,
)

__all__ = ["CONTROL_OBS", "CONTROL_STEP", "OBS_SIZE", "STRIKE", "STRIKE_TRACED", "StrikeTrace",
           "control_observe", "limit_force", "sample_trace", "strike_trace"]

# ---------------------------------------------------------------------------------------------
# Control envs: the task's rows
# ---------------------------------------------------------------------------------------------

#: the observation's columns, from the one declaration of the layout (``envs.layout``)
CONTROL_OBS = Table("control observation", *(f.name for f in CONTROL_LAYOUT), prefix="O_")
(O_MALLET_X, O_MALLET_Y, O_MALLET_VX, O_MALLET_VY, O_TARGET_X, O_TARGET_Y, O_TARGET_COS,
 O_TARGET_SIN, O_TARGET_VX, O_TARGET_VY, O_TARGET_SPIN) = CONTROL_OBS
OBS_SIZE = len(CONTROL_OBS)

#: a control element's row ``tbuf [B, .]``: the action in [-1, 1]^2 (clipped in place), the
#: observation (clipped to its bounds), reward, hits on the target, their impulse (N s), the
#: mallet's force (N), the target's spin (rad/s) and speed (m/s), the mallet's speed, whether the
#: solver settled, and the measured spin or speed before the physics step
CONTROL_ROW = Table("control row", ("action", 2), ("obs", OBS_SIZE), "reward", "hits",
                    "impulse", ("force", 2), "spin", "speed", "mallet_speed", "fallback",
                    "before", prefix="T_")
(T_ACTION, T_OBS, T_REWARD, T_HITS, T_IMPULSE, T_FORCE, T_SPIN, T_SPEED, T_MALLET_SPEED,
 T_FALLBACK, T_BEFORE) = CONTROL_ROW
T_COLUMNS = len(CONTROL_ROW)

#: the control task's constants ``kcfg``: force bound (N), speed limit (m/s), reward scale, what
#: the reward measures, the mallet's and target's body indices, the observation's scales and
#: bounds (low, then high)
CONTROL_CFG = Table("control config", "max_force", "max_speed", "scale", "measure", "mallet",
                    "target", "speed_scale", "spin_scale", ("low", OBS_SIZE),
                    ("high", OBS_SIZE), prefix="K_")
(K_MAX_FORCE, K_MAX_SPEED, K_SCALE, K_MEASURE, K_MALLET, K_TARGET, K_SPEED_SCALE, K_SPIN_SCALE,
 K_LOW, K_HIGH) = CONTROL_CFG
K_SIZE = len(CONTROL_CFG)

#: what the reward measures (``kcfg[K_MEASURE]``)
MEASURE = Table("control measure", "spin", "speed", prefix="MEASURE_")
MEASURE_SPIN, MEASURE_SPEED = MEASURE


@jit
def limit_force(ax, ay, vx, vy, mass, dt, max_force, max_speed):
    """Force from an action in the unit disk, reduced so that free flight keeps the speed limit.

    The action's box [-1, 1]^2 is mapped onto the disk of radius ``max_force`` (an action outside
    the unit disk keeps its direction, at full force). If the mallet would end the step faster
    than ``max_speed`` in free flight, the force is the one that ends it at the limit (projected
    onto the speed ball; never more than ``max_force``).

    Returns:
        (fx, fy), N.
    """
    norm = math.sqrt(ax * ax + ay * ay)
    scale = max_force / max(norm, 1.0)
    fx = ax * scale
    fy = ay * scale
    ex = vx + fx * dt / mass
    ey = vy + fy * dt / mass
    speed = math.sqrt(ex * ex + ey * ey)
    if speed == math.inf:  # the square overflowed (max_force 1e156 N): the force was 0
        speed = math.hypot(ex, ey)
    if speed > max_speed:
        k = max_speed / speed
        gx = (ex * k - vx) * mass / dt
        gy = (ey * k - vy) * mass / dt
        gn = math.sqrt(gx * gx + gy * gy)
        if gn == math.inf:
            gn = math.hypot(gx, gy)
        c = min(1.0, max_force / max(gn, 1e-300))
        fx = gx * c
        fy = gy * c
    return fx, fy


@jit
def _measure(S, it, kcfg):
    if kcfg[K_MEASURE] == MEASURE_SPIN:
        return abs(S[it, OMEGA])
    return math.sqrt(S[it, VX] ** 2 + S[it, VY] ** 2)


@jit_inline
def _put(row, kcfg, k, v):
    """Observation entry k, clipped to its bounds."""
    lo = kcfg[K_LOW + k]
    hi = kcfg[K_HIGH + k]
    row[T_OBS + k] = lo if v < lo else (hi if v > hi else v)


@jit
def _observe(S, hw, row, kcfg):
    """The observation of one element (state ``S [N, 6]``) into its row, by field name."""
    im = int(kcfg[K_MALLET])
    it = int(kcfg[K_TARGET])
    _put(row, kcfg, O_MALLET_X, S[im, X] / hw[HALF_W])
    _put(row, kcfg, O_MALLET_Y, S[im, Y] / hw[HALF_H])
    _put(row, kcfg, O_MALLET_VX, S[im, VX] / kcfg[K_MAX_SPEED])
    _put(row, kcfg, O_MALLET_VY, S[im, VY] / kcfg[K_MAX_SPEED])
    _put(row, kcfg, O_TARGET_X, S[it, X] / hw[HALF_W])
    _put(row, kcfg, O_TARGET_Y, S[it, Y] / hw[HALF_H])
    _put(row, kcfg, O_TARGET_COS, math.cos(S[it, ANGLE]))
    _put(row, kcfg, O_TARGET_SIN, math.sin(S[it, ANGLE]))
    _put(row, kcfg, O_TARGET_VX, S[it, VX] / kcfg[K_SPEED_SCALE])
    _put(row, kcfg, O_TARGET_VY, S[it, VY] / kcfg[K_SPEED_SCALE])
    _put(row, kcfg, O_TARGET_SPIN, S[it, OMEGA] / kcfg[K_SPIN_SCALE])


@jit
def _pre(b, S, Pm, F, dt, tbuf, kcfg):
    """Clip the action, set the mallet's force, measure the target before the step."""
    row = tbuf[b]
    im = int(kcfg[K_MALLET])
    ax = min(1.0, max(-1.0, row[T_ACTION + FX]))
    ay = min(1.0, max(-1.0, row[T_ACTION + FY]))
    row[T_ACTION + FX] = ax
    row[T_ACTION + FY] = ay
    fx, fy = limit_force(ax, ay, S[b, im, VX], S[b, im, VY], 1.0 / Pm[b, im, INV_MASS], dt,
                         kcfg[K_MAX_FORCE], kcfg[K_MAX_SPEED])
    F[b, im, FX] = fx
    F[b, im, FY] = fy
    row[T_FORCE + FX] = fx
    row[T_FORCE + FY] = fy
    row[T_BEFORE] = _measure(S[b], int(kcfg[K_TARGET]), kcfg)


@jit
def _post(b, S, HW, crec, stats, n_stored, tbuf, kcfg):
    """Hits on the target, reward, info and observation after the step."""
    row = tbuf[b]
    Sb = S[b]
    im = int(kcfg[K_MALLET])
    it = int(kcfg[K_TARGET])
    after = _measure(Sb, it, kcfg)
    # every mallet-target impulse (the world watches the pair), counted and summed by the solver
    # whether or not the records, which keep a step's first max_contacts, hold it: a mallet
    # pushing the rod at e = 0 makes ~1,500 contacts in a settled step, and the sum of the
    # stored ones was a median 0.11 of the whole
    hits = stats[b, STAT_WATCHED]
    impulse = crec[b, n_stored, REC_WATCHED_J]
    row[T_REWARD] = (after - row[T_BEFORE]) / kcfg[K_SCALE] if hits > 0 else 0.0
    row[T_HITS] = hits
    row[T_IMPULSE] = impulse
    row[T_SPIN] = Sb[it, OMEGA]
    row[T_SPEED] = math.sqrt(Sb[it, VX] ** 2 + Sb[it, VY] ** 2)
    row[T_MALLET_SPEED] = math.sqrt(Sb[im, VX] ** 2 + Sb[im, VY] ** 2)
    row[T_FALLBACK] = stats[b, STAT_FALLBACK]
    _observe(Sb, HW[b], row, kcfg)


@jit_inline
def _finite_actions(tbuf, start, stop):
    for b in range(start, stop):
        if not (math.isfinite(tbuf[b, T_ACTION + FX]) and math.isfinite(tbuf[b, T_ACTION + FY])):
            return False
    return True


@jit
def control_body(fbuf, ibuf, tbuf, kcfg, start, stop, fixed, rotation, cf, tf, jam, flat):
    """One control step of elements ``start..stop-1``: the worst ``fallback`` statistic among
    them (``layout.FALLBACK``), or -1 (and nothing done) if one of their actions is not finite.
    The last five arguments are the world's compile-time flags (``kernels.FLAGS``)."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    if not _finite_actions(tbuf, start, stop):
        return -1
    v = unpack(fbuf, ibuf)
    n_stored = ibuf[H_M]
    dt = v.fcfg[CF_DT]
    off = untraced(v.S.shape[1])
    worst = 0
    for b in range(start, stop):
        _pre(b, v.S, v.Pm, v.F, dt, tbuf, kcfg)
        worst = max(worst, step_element(v, b, dt, fixed, rotation, cf, tf, jam, flat, off))
        _post(b, v.S, v.HW, v.crec, v.stats, n_stored, tbuf, kcfg)
    return worst


@jit_parallel
def control_step_parallel(fbuf, ibuf, tbuf, kcfg, fixed, rotation, cf, tf, jam, flat):
    """:func:`control_body` over the whole batch in parallel threads (blocks of ``BLOCK``
    elements); nothing is done (-1) if any action is not finite."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    n = ibuf[H_B]
    if not _finite_actions(tbuf, 0, n):
        return -1
    worst = 0
    for k in numba.prange(n_blocks(n)):
        worst = max(worst, control_body(fbuf, ibuf, tbuf, kcfg, k * BLOCK,
                                        min(n, (k + 1) * BLOCK), fixed, rotation, cf, tf, jam,
                                        flat))
    return worst


@jit
def control_pre(fbuf, ibuf, tbuf, kcfg):
    """The step's first stage alone (for a backend that steps outside numba: pymunk)."""
    if not _finite_actions(tbuf, 0, ibuf[H_B]):
        return False
    v = unpack(fbuf, ibuf)
    for b in range(ibuf[H_B]):
        _pre(b, v.S, v.Pm, v.F, v.fcfg[CF_DT], tbuf, kcfg)
    return True


@jit
def control_post(fbuf, ibuf, tbuf, kcfg):
    """The step's last stage alone, after the backend stepped the world."""
    v = unpack(fbuf, ibuf)
    for b in range(ibuf[H_B]):
        _post(b, v.S, v.HW, v.crec, v.stats, ibuf[H_M], tbuf, kcfg)


@jit
def control_observe(fbuf, ibuf, tbuf, kcfg, env):
    """Write the observations of elements ``env`` from their state (after a reset)."""
    v = unpack(fbuf, ibuf)
    for b in env:
        _observe(v.S[b], v.HW[b], tbuf[b], kcfg)


def _control_stepwise(world, tbuf, kcfg) -> int:
    """The control step for a world on the pymunk backend: compiled stages around its step
    (which raises for a state no longer finite)."""
    buf = world.buffers
    if not control_pre(buf.fbuf, buf.ibuf, tbuf, kcfg):
        return -1
    world.step(world.dt)
    control_post(buf.fbuf, buf.ibuf, tbuf, kcfg)
    return 0  # world.step raised for a state no longer finite


#: one control step of every element: ``world.run(CONTROL_STEP, tbuf, kcfg, dt=dt)`` returns
#: the worst ``fallback`` statistic of the step's elements, or -1, having done nothing, if an
#: action is not finite
CONTROL_STEP = BatchKernel("control step", control_body, control_step_parallel,
                           _control_stepwise)


# ---------------------------------------------------------------------------------------------
# One-strike envs: the whole strike (a loop of solver chunks until no further contact can
# happen) per element, in one call. Each element runs only its own chunks, so a vector env no
# longer steps every element until the slowest one is done.
# ---------------------------------------------------------------------------------------------

#: a strike ``sbuf [B, .]``: in, the striker's launch (start, m, and velocity, m/s); out, the
#: contacts and their total impulse (N s), the first contact's time (s, -1: none), impulse and
#: point (m), the worst ``fallback`` statistic of its chunks (``layout.FALLBACK``; 0: none), the
#: simulated time (s), the target's velocity (m/s)
#: and spin (rad/s) and the striker's velocity after the last contact, whether the strike is
#: over, and the contact pair a refused launch would overlap (-1: none; -2: not finite)
STRIKE_ROW = Table("strike row", "launch_x", "launch_y", "launch_vx", "launch_vy", "contacts",
                   "impulse", "first_time", "first_j", "first_px", "first_py", "fallback",
                   "sim_time", "target_vx", "target_vy", "target_w", "striker_vx", "striker_vy",
                   "done", "overlap_pair", "overlap_gap", prefix="S_")
(S_LAUNCH_X, S_LAUNCH_Y, S_LAUNCH_VX, S_LAUNCH_VY, S_CONTACTS, S_IMPULSE, S_FIRST_TIME,
 S_FIRST_J, S_FIRST_PX, S_FIRST_PY, S_FALLBACK, S_SIM_TIME, S_TARGET_VX, S_TARGET_VY,
 S_TARGET_W, S_STRIKER_VX, S_STRIKER_VY, S_DONE, S_OVERLAP_PAIR, S_OVERLAP_GAP) = STRIKE_ROW
S_COLUMNS = len(STRIKE_ROW)

#: the strike's constants ``scfg``: chunk length (s), most chunks, target and striker body
#: indices, free plane (1) or table (0)
STRIKE_CFG = Table("strike config", "chunk", "chunks", "target", "striker", "free",
                   prefix="SC_")
SC_CHUNK, SC_CHUNKS, SC_TARGET, SC_STRIKER, SC_FREE = STRIKE_CFG
SC_SIZE = len(STRIKE_CFG)

#: a contact of the traced element: time from the launch (s), point (m), unit normal (a to b),
#: normal impulse (N s), bodies a and b (b >= N: a cushion)
TRACE_CONTACT = Table("trace contact", "time", "px", "py", "nx", "ny", "j", "a", "b",
                      prefix="TC_")
TC_TIME, TC_PX, TC_PY, TC_NX, TC_NY, TC_J, TC_A, TC_B = TRACE_CONTACT

#: what a traced strike records of element 0 (``STRIKE_TRACED``), for its video: ``events``,
#: the solver's trace hook (``solvers.Trace``: the state after every event, times from the
#: launch); ``chunks``, the state at the launch and after every chunk (a ``Trace`` too: the
#: only record on the pymunk backend); ``contacts [C, TRACE_CONTACT]`` and their
#: ``contact_count [TRACE_COUNT]``. Between two states of either trace every body is in
#: free flight, so :func:`sample_trace` gives the state at any time of the strike.
StrikeTrace = namedtuple("StrikeTrace", ["events", "chunks", "contacts", "contact_count"])


def strike_trace(n_chunks: int, n_bodies: int, events: int = 4096,
                 contacts: int = 1024) -> StrikeTrace:
    """Empty buffers for a traced strike of ``n_chunks`` chunks at most (``events`` solver
    states and ``contacts`` contacts at most; more are counted as dropped)."""
    def trace(n):
        return Trace(np.zeros(n), np.zeros((n, n_bodies, STATE_COLUMNS)),
                     np.zeros(len(TRACE_COUNT), dtype=np.int64))
    return StrikeTrace(trace(events), trace(n_chunks + 1),
                       np.zeros((contacts, len(TRACE_CONTACT))),
                       np.zeros(len(TRACE_COUNT), dtype=np.int64))

@jit
def _strike_start(row):
    for c in range(S_CONTACTS, S_COLUMNS):
        row[c] = 0.0
    row[S_FIRST_TIME] = -1.0
    row[S_OVERLAP_PAIR] = -1.0


@jit
def _launch(S, Pm, hw, PA, PB, row, js, tol):
    """Put the striker at its launch point with its launch velocity, every other body at rest
    where it is; the placement must be finite and overlap nothing (else the row says why, and
    False)."""
    x, y, vx, vy = row[S_LAUNCH_X], row[S_LAUNCH_Y], row[S_LAUNCH_VX], row[S_LAUNCH_VY]
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(vx) and math.isfinite(vy)):
        row[S_OVERLAP_PAIR] = -2.0
        return False
    for i in range(S.shape[0]):
        S[i, VX] = 0.0
        S[i, VY] = 0.0
        S[i, OMEGA] = 0.0
    S[js, X] = x
    S[js, Y] = y
    S[js, VX] = vx
    S[js, VY] = vy
    p, g = element_overlap(S, Pm, hw, PA, PB, tol)
    if p >= 0:
        row[S_OVERLAP_PAIR] = p
        row[S_OVERLAP_GAP] = g
        return False
    return True


@jit
def _finished(S, Pm, it, js, free):
    """No further contact can happen: free plane: the striker is beyond the rod's reach and
    moving away; otherwise (cushions, cloth friction): everything has stopped."""
    if free:
        dx = S[js, X] - S[it, X]
        dy = S[js, Y] - S[it, Y]
        dvx = S[js, VX] - S[it, VX]
        dvy = S[js, VY] - S[it, VY]
        reach = (Pm[it, HALF_LENGTH] + Pm[it, RADIUS]) + Pm[js, RADIUS]
        return math.sqrt(dx * dx + dy * dy) > reach + 1e-9 and dx * dvx + dy * dvy > 0.0
    for i in range(S.shape[0]):
        if S[i, VX] != 0.0 or S[i, VY] != 0.0 or S[i, OMEGA] != 0.0:
            return False
    return True


@jit
def _strike_post(b, k, S, Pm, cpair, crec, stats, n_stored, sbuf, scfg):
    """Book one chunk of element b's strike; True when the strike is over (outcome frozen)."""
    row = sbuf[b]
    chunk = scfg[SC_CHUNK]
    t0 = k * chunk
    # every contact: beyond the n_stored records, counted in the statistics and their impulses
    # summed in row n_stored (a strike at e = 0 can make ~10^4; 64 a chunk were counted)
    row[S_CONTACTS] += stats[b, STAT_CONTACTS]
    row[S_IMPULSE] += crec[b, n_stored, REC_J]
    for q in range(min(stats[b, STAT_CONTACTS], n_stored)):
        row[S_IMPULSE] += crec[b, q, REC_J]
        if row[S_FIRST_TIME] < 0.0:
            row[S_FIRST_TIME] = t0 + crec[b, q, REC_TIME]
            row[S_FIRST_J] = crec[b, q, REC_J]
            row[S_FIRST_PX] = crec[b, q, REC_PX]
            row[S_FIRST_PY] = crec[b, q, REC_PY]
    if stats[b, STAT_FALLBACK] > row[S_FALLBACK]:  # the worst, by layout.FALLBACK's order
        row[S_FALLBACK] = stats[b, STAT_FALLBACK]
    it = int(scfg[SC_TARGET])
    js = int(scfg[SC_STRIKER])
    if not (_finished(S[b], Pm[b], it, js, scfg[SC_FREE] != 0.0)
            or k == int(scfg[SC_CHUNKS]) - 1):
        return False
    row[S_TARGET_VX] = S[b, it, VX]
    row[S_TARGET_VY] = S[b, it, VY]
    row[S_TARGET_W] = S[b, it, OMEGA]
    row[S_STRIKER_VX] = S[b, js, VX]
    row[S_STRIKER_VY] = S[b, js, VY]
    row[S_SIM_TIME] = (k + 1) * chunk
    row[S_DONE] = 1.0
    return True


@jit
def _trace_contacts(b, t0, PA, PB, cpair, crec, stats, n_stored, contacts, count):
    """Append element b's contacts of the chunk that started at t0 (s) to the trace."""
    for q in range(min(stats[b, STAT_CONTACTS], n_stored)):
        n = count[TRACE_ENTRIES]
        if n < contacts.shape[0]:
            p = cpair[b, q]
            contacts[n, TC_TIME] = t0 + crec[b, q, REC_TIME]
            contacts[n, TC_PX] = crec[b, q, REC_PX]
            contacts[n, TC_PY] = crec[b, q, REC_PY]
            contacts[n, TC_NX] = crec[b, q, REC_NX]
            contacts[n, TC_NY] = crec[b, q, REC_NY]
            contacts[n, TC_J] = crec[b, q, REC_J]
            contacts[n, TC_A] = PA[p]
            contacts[n, TC_B] = PB[p]
            count[TRACE_ENTRIES] = n + 1
        else:
            count[TRACE_DROPPED] += 1


@jit
def _traced_chunk(v, b, k, n_stored, scfg, trace, off, fixed, rotation, cf, tf, jam, flat):
    """Chunk k of element b's strike in a traced strike: element 0's is recorded (the solver's
    states after its events, the state at the chunk's end, its contacts), the others' not
    (``off``: the empty solver trace, ``solvers.untraced``)."""
    chunk = scfg[SC_CHUNK]
    if b != 0:
        step_element(v, b, chunk, fixed, rotation, cf, tf, jam, flat, off)
        return
    t0 = k * chunk
    events = trace.events
    first = events.count[TRACE_ENTRIES]
    step_element(v, b, chunk, fixed, rotation, cf, tf, jam, flat, events)
    for q in range(first, events.count[TRACE_ENTRIES]):
        events.time[q] = t0 + events.time[q]  # the hook records times within the step
    trace_state(trace.chunks, (k + 1) * chunk, v.S[b])
    _trace_contacts(b, t0, v.PA, v.PB, v.cpair, v.crec, v.stats, n_stored, trace.contacts,
                    trace.contact_count)


@jit
def strike_body(fbuf, ibuf, sbuf, scfg, trace, start, stop, fixed, rotation, cf, tf, jam, flat):
    """Simulate the strikes of elements ``start..stop-1`` to their ends (see the section
    comment); ``trace``: None, or a :data:`StrikeTrace` that records element 0 (a separate
    specialisation of this kernel; the solver under it is the same, given an empty trace by
    unfilmed strikes, ``solvers.untraced``). The last five arguments are the world's
    compile-time flags (``kernels.FLAGS``)."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    v = unpack(fbuf, ibuf)
    n_stored = ibuf[H_M]
    off = untraced(v.S.shape[1])  # the solver's own trace hook, empty: one solver compile
    for b in range(start, stop):
        row = sbuf[b]
        _strike_start(row)
        if not _launch(v.S[b], v.Pm[b], v.HW[b], v.PA, v.PB, row, int(scfg[SC_STRIKER]),
                       v.fcfg[CF_OVERLAP_TOL]):
            continue
        if trace is not None:
            if b == 0:
                trace_state(trace.chunks, 0.0, v.S[b])
        for k in range(int(scfg[SC_CHUNKS])):
            if trace is None:
                step_element(v, b, scfg[SC_CHUNK], fixed, rotation, cf, tf, jam, flat, off)
            else:
                _traced_chunk(v, b, k, n_stored, scfg, trace, off, fixed, rotation, cf, tf, jam,
                              flat)
            if _strike_post(b, k, v.S, v.Pm, v.cpair, v.crec, v.stats, n_stored, sbuf, scfg):
                break


@jit_parallel
def strike_parallel(fbuf, ibuf, sbuf, scfg, trace, fixed, rotation, cf, tf, jam, flat):
    """:func:`strike_body` over the whole batch in parallel threads (blocks of ``BLOCK``
    elements)."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam),
    literally(flat)
    n = ibuf[H_B]
    for k in numba.prange(n_blocks(n)):
        strike_body(fbuf, ibuf, sbuf, scfg, trace, k * BLOCK, min(n, (k + 1) * BLOCK), fixed,
                    rotation, cf, tf, jam, flat)


@jit
def strike_post_batch(k, fbuf, ibuf, sbuf, scfg):
    """Book chunk k for every element still striking (a backend stepping outside numba)."""
    v = unpack(fbuf, ibuf)
    for b in range(ibuf[H_B]):
        if sbuf[b, S_DONE] == 0.0:
            _strike_post(b, k, v.S, v.Pm, v.cpair, v.crec, v.stats, ibuf[H_M], sbuf, scfg)


@jit
def strike_start_batch(sbuf):
    for b in range(sbuf.shape[0]):
        _strike_start(sbuf[b])


@jit
def trace_chunk_batch(k, fbuf, ibuf, sbuf, scfg, trace):
    """Trace element 0's chunk k (a backend stepping outside numba: no solver events)."""
    if sbuf[0, S_DONE] != 0.0:
        return
    v = unpack(fbuf, ibuf)
    chunk = scfg[SC_CHUNK]
    trace_state(trace.chunks, (k + 1) * chunk, v.S[0])
    _trace_contacts(0, k * chunk, v.PA, v.PB, v.cpair, v.crec, v.stats, ibuf[H_M],
                    trace.contacts, trace.contact_count)


def _strike_stepwise(world, sbuf, scfg, trace) -> None:
    """The strike for a world on the pymunk backend: the launch by a validated edit, then world
    steps of one chunk from Python, each booked (and traced) by the same compiled code."""
    buf = world.buffers
    strike_start_batch(sbuf)
    state = world.state
    js = int(scfg[SC_STRIKER])
    positions = state.positions.copy()
    velocities = np.zeros_like(positions)
    positions[:, js] = sbuf[:, S_LAUNCH_X:S_LAUNCH_Y + 1]
    velocities[:, js] = sbuf[:, S_LAUNCH_VX:S_LAUNCH_VY + 1]
    with world.edit() as e:
        e.set_state(positions=positions, velocities=velocities, omegas=0.0)
    if trace is not None:
        trace_state(trace.chunks, 0.0, unpack(buf.fbuf, buf.ibuf).S[0])
    for k in range(int(scfg[SC_CHUNKS])):
        world.step(scfg[SC_CHUNK])
        if trace is not None:
            trace_chunk_batch(k, buf.fbuf, buf.ibuf, sbuf, scfg, trace)
        strike_post_batch(k, buf.fbuf, buf.ibuf, sbuf, scfg)
        if (sbuf[:, S_DONE] != 0.0).all():
            break


@jit
def sample_trace(fbuf, ibuf, b, key_time, key_state, times, out):
    """States of element b at ``times`` (s, ascending) from a trace's states ``key_state [K, N,
    6]`` at ``key_time [K]`` (ascending; the first at or before the first time): each is the
    last state at or before the time, flown by the rest (``motion.flight``), into
    ``out [len(times), N, 6]``. A disk resting on a cushion in a state (``solvers.rests_on``)
    flies as the solver flew it: without the force's component the cushion holds back."""
    v = unpack(fbuf, ibuf)
    Pm = v.Pm[b]
    hw = v.HW[b]
    MAT = v.MAT[b]
    rotation = v.icfg[CI_ROTATION] != 0
    table_friction = v.icfg[CI_TABLE_FRICTION] != 0
    contact_friction = v.icfg[CI_CONTACT_FRICTION] != 0
    tol = v.fcfg[CF_TOL]
    zeno_speed = v.fcfg[CF_ZENO_SPEED]
    k = 0
    n_keys = key_time.shape[0]
    S = np.empty((key_state.shape[1], STATE_COLUMNS))
    F = np.empty((key_state.shape[1], FORCE_COLUMNS))
    n = S.shape[0]
    for f in range(times.shape[0]):
        t = times[f]
        while k + 1 < n_keys and key_time[k + 1] <= t:
            k += 1
        for i in range(n):
            for c in range(STATE_COLUMNS):
                S[i, c] = key_state[k, i, c]
            F[i, FX] = v.F[b, i, FX]
            F[i, FY] = v.F[b, i, FY]
        for p in range(v.PA.shape[0]):  # what the cushions held back in the solver's flight
            i = v.PA[p]
            wall = v.PB[p] - n
            if wall >= 0 and rests_on(S, Pm, F, hw, MAT, p, i, wall, tol, zeno_speed,
                                      contact_friction, table_friction):
                if wall < 2:  # the left or right cushion
                    F[i, FX] = 0.0
                else:
                    F[i, FY] = 0.0
        for i in range(n):
            x, y, an, vx, vy, w = flight(S, Pm, F, i, t - key_time[k], rotation, table_friction)
            out[f, i, X] = x
            out[f, i, Y] = y
            out[f, i, ANGLE] = an
            out[f, i, VX] = vx
            out[f, i, VY] = vy
            out[f, i, OMEGA] = w


#: every element's whole strike, from its launch (``sbuf``'s launch columns):
#: ``world.run(STRIKE, sbuf, scfg, None)``
STRIKE = BatchKernel("strike", strike_body, strike_parallel, _strike_stepwise)
#: the same, tracing element 0 for its video: ``world.run(STRIKE_TRACED, sbuf, scfg, trace)``
#: with a :data:`StrikeTrace` (counts zeroed); its own kernel object, so that each keeps the
#: entry point compiled for its argument types
STRIKE_TRACED = BatchKernel("traced strike", strike_body, strike_parallel, _strike_stepwise)
