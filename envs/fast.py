"""The envs' hot loops as compiled calls over the whole batch: the control envs' step, and the
one-strike envs' strike (see the section further down).

Per element: validate and clip the action, turn it into the mallet's force under the speed limit
(``limit_force``), measure the target, run the same solver kernel ``world.step`` runs
(``physics.solvers.exact_element`` / ``fixed_element``), count the mallet's hits on the target
from the contact records, reward, and write the observation. Nothing here changes the physics:
it is the world's own element kernel, called from the env's kernel instead of from
``world.step``, so a single env and a vector env still agree bit for bit. What it removes is the
Python and numpy work around the kernel, which at B = 1 cost more than the physics.

The task's arrays live in one float64 buffer ``tbuf [B, T_COLUMNS]`` (actions in, observations,
reward and info out) and its constants in ``kcfg``; see the column constants below.
"""

from __future__ import annotations

import math
from pathlib import Path

import numba
import numpy as np

from spinstrike.physics._cache import refresh_kernel_cache
from spinstrike.physics.layout import (
    ANGLE,
    CF_DT,
    H_B,
    H_M,
    HALF_LENGTH,
    INV_MASS,
    OMEGA,
    RADIUS,
    REC_J,
    REC_NX,
    REC_NY,
    REC_PX,
    REC_PY,
    REC_TIME,
    STAT_CONTACTS,
    STAT_FALLBACK,
    VX,
    VY,
    X,
    Y,
)
from spinstrike.physics.solvers import BLOCK, step_element, unpack

# these kernels inline the physics kernels: recompile them when either changes (numba loads its
# cache at a kernel's first call, so clearing it here, at import, is in time)
refresh_kernel_cache(Path(__file__).resolve().parent, ("fast.py",))

__all__ = ["OBS_SIZE", "S_COLUMNS", "T_COLUMNS", "control_observe", "control_step",
           "limit_force", "strike_parallel", "strike_post_batch", "strike_serial"]

# the world's clock and statistics are kept by ``control_step`` exactly as ``world.step`` keeps
# them; the fused kernel runs the element kernel ``world.step`` would have run

jit = numba.njit(cache=True, nogil=True, error_model="numpy")
jit_parallel = numba.njit(cache=True, nogil=True, parallel=True, error_model="numpy")

OBS_SIZE = 11
# tbuf columns
T_ACTION = 0          # 2: the action in [-1, 1]^2 (clipped in place)
T_OBS = 2             # OBS_SIZE: the observation, clipped to its bounds
T_REWARD = T_OBS + OBS_SIZE
T_HITS = T_REWARD + 1
T_IMPULSE = T_HITS + 1
T_FORCE = T_IMPULSE + 1   # 2
T_SPIN = T_FORCE + 2
T_SPEED = T_SPIN + 1
T_MALLET_SPEED = T_SPEED + 1
T_FALLBACK = T_MALLET_SPEED + 1
T_BEFORE = T_FALLBACK + 1   # the measured spin or speed before the physics step
T_COLUMNS = T_BEFORE + 1
# kcfg slots
K_MAX_FORCE, K_MAX_SPEED, K_SCALE, K_MEASURE, K_MALLET, K_TARGET, K_FIXED = 0, 1, 2, 3, 4, 5, 6
K_SPEED_SCALE, K_SPIN_SCALE = 7, 8
K_LOW = 9                 # OBS_SIZE lower bounds, then OBS_SIZE upper bounds
K_SIZE = K_LOW + 2 * OBS_SIZE
#: what the reward measures (K_MEASURE)
MEASURE_SPIN, MEASURE_SPEED = 0.0, 1.0


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
    if speed > max_speed:
        k = max_speed / speed
        gx = (ex * k - vx) * mass / dt
        gy = (ey * k - vy) * mass / dt
        gn = math.sqrt(gx * gx + gy * gy)
        c = min(1.0, max_force / max(gn, 1e-300))
        fx = gx * c
        fy = gy * c
    return fx, fy


@jit
def _measure(S, it, kcfg):
    if kcfg[K_MEASURE] == MEASURE_SPIN:
        return abs(S[it, OMEGA])
    return math.sqrt(S[it, VX] ** 2 + S[it, VY] ** 2)


@jit
def _observe(S, hw, row, kcfg):
    im = int(kcfg[K_MALLET])
    it = int(kcfg[K_TARGET])
    vals = (S[im, X] / hw[0], S[im, Y] / hw[1],
            S[im, VX] / kcfg[K_MAX_SPEED], S[im, VY] / kcfg[K_MAX_SPEED],
            S[it, X] / hw[0], S[it, Y] / hw[1],
            math.cos(S[it, ANGLE]), math.sin(S[it, ANGLE]),
            S[it, VX] / kcfg[K_SPEED_SCALE], S[it, VY] / kcfg[K_SPEED_SCALE],
            S[it, OMEGA] / kcfg[K_SPIN_SCALE])
    for k in range(OBS_SIZE):
        v = vals[k]
        lo = kcfg[K_LOW + k]
        hi = kcfg[K_LOW + OBS_SIZE + k]
        row[T_OBS + k] = lo if v < lo else (hi if v > hi else v)


@jit
def _pre(b, S, Pm, F, dt, tbuf, kcfg):
    """Clip the action, set the mallet's force, measure the target before the step."""
    row = tbuf[b]
    im = int(kcfg[K_MALLET])
    ax = min(1.0, max(-1.0, row[T_ACTION]))
    ay = min(1.0, max(-1.0, row[T_ACTION + 1]))
    row[T_ACTION] = ax
    row[T_ACTION + 1] = ay
    fx, fy = limit_force(ax, ay, S[b, im, VX], S[b, im, VY], 1.0 / Pm[b, im, INV_MASS], dt,
                         kcfg[K_MAX_FORCE], kcfg[K_MAX_SPEED])
    F[b, im, 0] = fx
    F[b, im, 1] = fy
    row[T_FORCE] = fx
    row[T_FORCE + 1] = fy
    row[T_BEFORE] = _measure(S[b], int(kcfg[K_TARGET]), kcfg)


@jit
def _post(b, S, HW, PA, PB, cpair, crec, stats, n_stored, tbuf, kcfg):
    """Hits on the target, reward, info and observation after the step."""
    row = tbuf[b]
    Sb = S[b]
    im = int(kcfg[K_MALLET])
    it = int(kcfg[K_TARGET])
    after = _measure(Sb, it, kcfg)
    hits = 0
    impulse = 0.0
    for k in range(min(stats[b, STAT_CONTACTS], n_stored)):
        p = cpair[b, k]
        if (PA[p] == im and PB[p] == it) or (PA[p] == it and PB[p] == im):
            hits += 1
            impulse += crec[b, k, REC_J]
    row[T_REWARD] = (after - row[T_BEFORE]) / kcfg[K_SCALE] if hits > 0 else 0.0
    row[T_HITS] = hits
    row[T_IMPULSE] = impulse
    row[T_SPIN] = Sb[it, OMEGA]
    row[T_SPEED] = math.sqrt(Sb[it, VX] ** 2 + Sb[it, VY] ** 2)
    row[T_MALLET_SPEED] = math.sqrt(Sb[im, VX] ** 2 + Sb[im, VY] ** 2)
    row[T_FALLBACK] = stats[b, STAT_FALLBACK]
    _observe(Sb, HW[b], row, kcfg)


@jit
def _control_one(b, v, n_stored, tbuf, kcfg):
    dt = v.fcfg[CF_DT]
    _pre(b, v.S, v.Pm, v.F, dt, tbuf, kcfg)
    step_element(v, b, dt, kcfg[K_FIXED] != 0.0)
    _post(b, v.S, v.HW, v.PA, v.PB, v.cpair, v.crec, v.stats, n_stored, tbuf, kcfg)


@jit
def _control_range(fbuf, ibuf, tbuf, kcfg, start, stop):
    v = unpack(fbuf, ibuf)
    for b in range(start, stop):
        _control_one(b, v, ibuf[H_M], tbuf, kcfg)


@jit
def _finite_actions(tbuf):
    for b in range(tbuf.shape[0]):
        if not (math.isfinite(tbuf[b, T_ACTION]) and math.isfinite(tbuf[b, T_ACTION + 1])):
            return False
    return True


@jit
def control_step_serial(fbuf, ibuf, tbuf, kcfg):
    """One control step of every element; False (and nothing done) if an action is not finite."""
    if not _finite_actions(tbuf):
        return False
    _control_range(fbuf, ibuf, tbuf, kcfg, 0, ibuf[H_B])
    return True


@jit_parallel
def control_step_parallel(fbuf, ibuf, tbuf, kcfg):
    """:func:`control_step_serial` in parallel threads (blocks of ``BLOCK`` elements)."""
    if not _finite_actions(tbuf):
        return False
    n = ibuf[H_B]
    for k in numba.prange((n + BLOCK - 1) // BLOCK):
        _control_range(fbuf, ibuf, tbuf, kcfg, k * BLOCK, min(n, (k + 1) * BLOCK))
    return True


@jit
def control_pre(fbuf, ibuf, tbuf, kcfg):
    """The step's first stage alone (for a backend that steps outside numba: pymunk)."""
    if not _finite_actions(tbuf):
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
        _post(b, v.S, v.HW, v.PA, v.PB, v.cpair, v.crec, v.stats, ibuf[H_M], tbuf, kcfg)


@jit
def control_observe(fbuf, ibuf, tbuf, kcfg, env):
    """Write the observations of elements ``env`` (after a reset)."""
    v = unpack(fbuf, ibuf)
    for b in env:
        _observe(v.S[b], v.HW[b], tbuf[b], kcfg)


def control_step(world, tbuf: np.ndarray, kcfg: np.ndarray, parallel: bool) -> bool:
    """One control step of every element of ``world`` (its ``dt`` set in the world's config);
    returns False, having done nothing, if an action is not finite."""
    if world._backend is not None:
        if not control_pre(world._fbuf, world._ibuf, tbuf, kcfg):
            return False
        world.step(world._fcfg[CF_DT])
        control_post(world._fbuf, world._ibuf, tbuf, kcfg)
        return True
    kernel = control_step_parallel if parallel else control_step_serial
    if not kernel(world._fbuf, world._ibuf, tbuf, kcfg):
        return False
    world._finish_step()
    return True


# ---------------------------------------------------------------------------------------------
# One-strike envs: the whole strike (a loop of solver chunks until no further contact can
# happen) per element, in one call. Each element runs only its own chunks, so a vector env no
# longer steps every element until the slowest one is done.
# ---------------------------------------------------------------------------------------------

# sbuf columns
S_CONTACTS, S_IMPULSE, S_FIRST_TIME, S_FIRST_J, S_FIRST_PX, S_FIRST_PY = 0, 1, 2, 3, 4, 5
S_FALLBACK, S_SIM_TIME, S_TARGET_VX, S_TARGET_VY, S_TARGET_W = 6, 7, 8, 9, 10
S_STRIKER_VX, S_STRIKER_VY, S_DONE = 11, 12, 13
S_COLUMNS = 14
# scfg slots
SC_CHUNK, SC_CHUNKS, SC_TARGET, SC_STRIKER, SC_FREE, SC_FIXED, SC_RECORD = 0, 1, 2, 3, 4, 5, 6
SC_SIZE = 7
#: contact rows recorded for element 0's animation
TRACE_CONTACTS = 256


@jit
def _strike_start(row):
    for c in range(S_COLUMNS):
        row[c] = 0.0
    row[S_FIRST_TIME] = -1.0


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
    for q in range(min(stats[b, STAT_CONTACTS], n_stored)):
        row[S_CONTACTS] += 1.0
        row[S_IMPULSE] += crec[b, q, REC_J]
        if row[S_FIRST_TIME] < 0.0:
            row[S_FIRST_TIME] = t0 + crec[b, q, REC_TIME]
            row[S_FIRST_J] = crec[b, q, REC_J]
            row[S_FIRST_PX] = crec[b, q, REC_PX]
            row[S_FIRST_PY] = crec[b, q, REC_PY]
    if stats[b, STAT_FALLBACK] != 0:
        row[S_FALLBACK] = 1.0
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
def _trace_pose(S, trace, tcount):
    n = tcount[0]
    if n < trace.shape[0]:
        for i in range(S.shape[1]):
            trace[n, i, 0] = S[0, i, X]
            trace[n, i, 1] = S[0, i, Y]
            trace[n, i, 2] = S[0, i, ANGLE]
        tcount[0] = n + 1


@jit
def _trace_contacts(cpair, crec, stats, n_stored, ctrace, tcount):
    for q in range(min(stats[0, STAT_CONTACTS], n_stored)):
        n = tcount[1]
        if n < ctrace.shape[0]:
            ctrace[n, 0] = crec[0, q, REC_PX]
            ctrace[n, 1] = crec[0, q, REC_PY]
            ctrace[n, 2] = crec[0, q, REC_NX]
            ctrace[n, 3] = crec[0, q, REC_NY]
            ctrace[n, 4] = crec[0, q, REC_J]
            tcount[1] = n + 1


@jit
def _strike_one(b, v, n_stored, sbuf, scfg, trace, ctrace, tcount):
    _strike_start(sbuf[b])
    record = scfg[SC_RECORD] != 0.0 and b == 0
    if record:
        _trace_pose(v.S, trace, tcount)
    for k in range(int(scfg[SC_CHUNKS])):
        step_element(v, b, scfg[SC_CHUNK], scfg[SC_FIXED] != 0.0)
        if record:
            _trace_contacts(v.cpair, v.crec, v.stats, n_stored, ctrace, tcount)
            _trace_pose(v.S, trace, tcount)
        if _strike_post(b, k, v.S, v.Pm, v.cpair, v.crec, v.stats, n_stored, sbuf, scfg):
            break


@jit
def _strike_range(fbuf, ibuf, sbuf, scfg, trace, ctrace, tcount, start, stop):
    v = unpack(fbuf, ibuf)
    for b in range(start, stop):
        _strike_one(b, v, ibuf[H_M], sbuf, scfg, trace, ctrace, tcount)


@jit
def strike_serial(fbuf, ibuf, sbuf, scfg, trace, ctrace, tcount):
    """Simulate every element's strike to its end (see the section comment)."""
    _strike_range(fbuf, ibuf, sbuf, scfg, trace, ctrace, tcount, 0, ibuf[H_B])


@jit_parallel
def strike_parallel(fbuf, ibuf, sbuf, scfg, trace, ctrace, tcount):
    """:func:`strike_serial` in parallel threads (blocks of ``BLOCK`` elements)."""
    n = ibuf[H_B]
    for k in numba.prange((n + BLOCK - 1) // BLOCK):
        _strike_range(fbuf, ibuf, sbuf, scfg, trace, ctrace, tcount, k * BLOCK,
                      min(n, (k + 1) * BLOCK))


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
