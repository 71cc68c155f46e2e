"""The solvers' trace hook (``solvers.Trace``) records and changes nothing else: over the golden
scenarios (exact, coarse, fixed; cushions, posts, pivots, the driven mallet, friction, the
cradle), a world stepped with a trace for every element stays bit for bit with one stepped
without; every recorded state lies on the trajectory (flown to the end of the step it is the
world's end state), and the exact solver records one state per contact instant."""

import numpy as np
import pytest
from numba import literally

from spinstrike import physics
from spinstrike.envs.fast import sample_trace
from spinstrike.physics.jit import jit
from spinstrike.physics.kernels import BatchKernel, step_element, unpack
from spinstrike.physics.solvers import TRACE_COUNT, TRACE_DROPPED, TRACE_ENTRIES, Trace
from tests.physics import golden
from tests.stability.catalogue import _pressed_scenes

STEPS = 40
SIZE = 4096


@jit
def _traced_step(fbuf, ibuf, dt, times, states, counts, start, stop, fixed, rotation, cf, tf,
                 jam, flat):
    """The world's step, element b traced into row b of ``times``, ``states``, ``counts``."""
    literally(fixed), literally(rotation), literally(cf), literally(tf), literally(jam)
    literally(flat)
    v = unpack(fbuf, ibuf)
    for b in range(start, stop):
        step_element(v, b, dt, fixed, rotation, cf, tf, jam, flat,
                     Trace(times[b], states[b], counts[b]))


TRACED_STEP = BatchKernel("traced step", _traced_step, _traced_step)


def _scenarios():
    out = {name: (scene, solver, None) for name, (scene, solver) in golden.scenarios().items()}
    # a puck pressed into a cushion by the mallet: the exact solver settles (fixed substeps)
    _, pressed, force = _pressed_scenes()[0]
    out["pressed_settles"] = (pressed, None, force)
    return out


@pytest.mark.parametrize("name", list(_scenarios()))
def test_a_traced_step_is_the_same_step(name):
    scene, solver, push = _scenarios()[name]
    batch = 3
    plain = physics.World(scene, batch_size=batch, solver=solver)
    traced = physics.World(scene, batch_size=batch, solver=solver)
    rng = np.random.default_rng(3)
    n = plain.n_bodies
    movable = ~(plain.static | plain.pivot)
    vel = rng.uniform(-2.5, 2.5, (batch, n, 2)) * movable[None, :, None]
    if push is not None:  # from rest: the mallet drives the puck into the cushion, a chain the
        vel[:] = 0.0      # solver settles (a mallet alone on a cushion just rests there)
    for w in (plain, traced):
        w.set_state(velocities=vel)
    fixed = (solver or {}).get("mode") == "fixed"
    recorded = 0
    settled = 0
    for _ in range(STEPS):
        forces = {int(i): (rng.uniform(-6, 6, (batch, 2)) if push is None else push)
                  for i in np.flatnonzero(plain.driven)}
        for w in (plain, traced):
            for i, f in forces.items():
                w.set_force(i, f)
        start = traced.get_state()["state"].copy()
        c = plain.step(golden.DT)
        settled += int(plain.last_step.fallback.sum())
        times_all = np.zeros((batch, SIZE))
        states_all = np.zeros((batch, SIZE, n, 6))
        counts = np.zeros((batch, len(TRACE_COUNT)), dtype=np.int64)
        traced.run(TRACED_STEP, golden.DT, times_all, states_all, counts, dt=golden.DT)
        buf = traced.buffers
        for b in range(batch):
            k = int(counts[b, TRACE_ENTRIES])
            assert counts[b, TRACE_DROPPED] == 0
            recorded += k
            times = times_all[b, :k]
            mine = c.time[c.batch == b]
            if fixed:  # one state per substep
                assert k == 8
            elif not plain.last_step.fallback[b]:  # a state per contact instant
                np.testing.assert_array_equal(np.unique(times), np.unique(mine))
            assert (np.diff(times) >= 0).all()
            # the start of the step and the recorded states, flown to its end: its end state
            key_time = np.concatenate([[0.0], times])
            key_state = np.concatenate([start[b][None], states_all[b, :k]])
            end = np.empty((1, n, 6))
            sample_trace(buf.fbuf, buf.ibuf, b, key_time, key_state, np.array([golden.DT]),
                         end)
            np.testing.assert_allclose(end[0], traced.get_state()["state"][b], rtol=0,
                                       atol=1e-12)
        np.testing.assert_array_equal(traced.get_state()["state"], plain.get_state()["state"])
    assert recorded > 0
    assert (settled > 0) == (name == "pressed_settles")
