"""A World shared between threads (walk W26b): its kernels run without the GIL, so a step, an
edit, a snapshot and a second step from another thread overlapped, and each lost or mixed up
steps silently (an edit wrote back copies over the other thread's steps; two stepping threads
lost steps below the parallel batch; a snapshot held the state of one step and the clock of
another). Each is serialised by the world's lock (``World.lock``), so every test here checks a
free-flying rod, whose position must be where its clock says, after threads raced on it.
"""

import threading

import numpy as np
import pytest

from spinstrike import physics

DT, VY = 1e-3, 0.01


def _flying(batch=1):
    """rod_control with a frictionless table and the rod flying at VY, clear of everything for
    the tests' 20 s: its y is y0 + VY * time exactly when no step is lost."""
    world = physics.World("rod_control", batch_size=batch)
    world.set_table(friction=0.0)
    world.set_state(body="rod", velocities=[[0.0, VY]], omegas=0.0)
    return world, world.state.positions[:, 0, 1].copy()


def _lag(world, y0):
    """How many steps the rod's position lags behind the world's clock, per element."""
    return (y0 + VY * world.time - world.state.positions[:, 0, 1]) / (VY * DT)


def _race(work, other):
    """Run ``other`` in a thread, looping until ``work()`` (in this one) returns; the errors
    ``other`` raised."""
    stop, errors = threading.Event(), []

    def loop():
        while not stop.is_set():
            try:
                other()
            except Exception as err:  # noqa: BLE001 (reported below)
                errors.append(err)

    thread = threading.Thread(target=loop)
    thread.start()
    try:
        work()
    finally:
        stop.set()
        thread.join()
    return errors


def test_an_edit_from_another_thread_never_undoes_steps():
    """An edit of the mallet (already at rest) from a second thread while the first steps:
    10 of 10 runs lost steps (up to 9,290 of 20,000, the clock reading 20 s), the edit's
    copies written back over them. The setters now hold the lock from copy to write: none is
    refused, none loses a step."""
    world, y0 = _flying()
    errors = _race(lambda: [world.step(DT) for _ in range(20_000)],
                   lambda: world.set_state(body="mallet", velocities=[[0.0, 0.0]]))
    assert errors == []
    assert world.time[0] == pytest.approx(20.0)
    assert abs(_lag(world, y0)[0]) < 1e-6


@pytest.mark.parametrize("batch", [1, 64])
def test_two_threads_stepping_one_world_take_turns(batch):
    """Two threads each step the same world 10,000 times: the clock counted every step while
    the state kept those of one kernel written over the other's (below the parallel batch,
    whose kernels took turns under the process's lock; 10 of 10 runs at 64 elements, rarely at
    one). Now every step counts. Each thread takes exactly 10,000 steps: a thread looping until
    the other finished took ~30,000 in CI and flew the rod into the cushion (a lag of 14,205
    steps with every step counted)."""
    world, y0 = _flying(batch)
    start, errors = threading.Barrier(2), []

    def steps():  # 10,000 each, no more: the rod reaches the cushion after ~39 s of clock
        start.wait()
        try:
            for _ in range(10_000):
                world.step(DT)
        except Exception as err:  # noqa: BLE001 (reported below)
            errors.append(err)

    threads = [threading.Thread(target=steps) for _ in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == []
    assert world.time == pytest.approx(20.0)
    assert np.abs(_lag(world, y0)).max() < 1e-6


def test_a_snapshot_from_another_thread_is_of_one_step():
    """``get_state`` while another thread steps: its state, forces and clock were copied one
    after another around the other's kernels (a snapshot's clock up to 1,458 steps ahead of its
    positions, and ``restore`` took it). A snapshot is now of one step, and so is what is read
    under ``world.lock``."""
    world, y0 = _flying()
    lags, locked = [], []

    def snap():
        s = world.get_state()
        lags.append((y0[0] + VY * s["time"][0] - s["state"][0, 0, 1]) / (VY * DT))
        with world.lock:
            locked.append(_lag(world, y0)[0])

    errors = _race(lambda: [world.step(DT) for _ in range(20_000)], snap)
    assert errors == [] and len(lags) > 100
    assert np.abs(lags).max() < 1e-6 and np.abs(locked).max() < 1e-6


def test_a_copy_or_pickle_made_while_another_thread_steps_is_of_one_step():
    """``copy.deepcopy`` and ``pickle`` of a world another thread stepped tore 4-9 % of the
    copies (the buffers pickled after ``__getstate__`` returned them, mid-step)."""
    import copy
    import pickle

    world, y0 = _flying()
    lags = []

    def twin():
        for other in (copy.deepcopy(world), pickle.loads(pickle.dumps(world))):
            lags.append(_lag(other, y0)[0])

    errors = _race(lambda: [world.step(DT) for _ in range(20_000)], twin)
    assert errors == [] and len(lags) > 20
    assert np.abs(lags).max() < 1e-6


def test_an_open_edit_block_holds_the_world():
    """Inside ``with world.edit() as e:`` the world is the block's: another thread's step waits
    for the commit, so the block's copies are never stale and the commit is never refused."""
    world, _ = _flying()
    started, stepped = threading.Event(), []

    def step():
        started.set()
        world.step(DT)
        stepped.append(world.time[0])

    with world.edit() as e:
        e.set_state(body="mallet", velocities=[[0.1, 0.0]])
        thread = threading.Thread(target=step)
        thread.start()
        started.wait()
        thread.join(0.2)
        assert thread.is_alive() and not stepped  # waiting for the edit
    thread.join()
    assert stepped == [pytest.approx(DT)]
    assert world.state.velocities[0, 1, 0] == pytest.approx(0.1)


def test_the_lock_is_not_pickled_and_copies_have_their_own():
    import copy
    import pickle

    world, _ = _flying()
    for twin in (pickle.loads(pickle.dumps(world)), copy.deepcopy(world), copy.copy(world)):
        assert twin.lock is not world.lock
        with world.lock:  # held here: the twin steps on its own lock
            twin.step(DT)
        assert twin.time[0] == pytest.approx(DT) and world.time[0] == 0.0


def test_a_child_forked_while_another_thread_holds_the_world_steps_its_copy():
    """The world's lock, held by a thread stepping or editing at a fork (multiprocessing's
    default on Linux), came over to the child held by a thread the child does not have: the
    child's first step of its copy of the world waited for ever. A forked child gets each world
    a lock of its own."""
    import multiprocessing

    world, y0 = _flying()
    held, release = threading.Event(), threading.Event()

    def hold():
        with world.lock:
            held.set()
            release.wait(60)

    def child(pipe):  # the forked copy of this world, not a pickle of it
        world.step(DT)
        pipe.send(float(_lag(world, y0)[0]))

    thread = threading.Thread(target=hold)
    thread.start()
    assert held.wait(10)
    ours, theirs = multiprocessing.get_context("fork").Pipe()
    process = multiprocessing.get_context("fork").Process(target=child, args=(theirs,))
    try:
        process.start()
        got = ours.poll(30)
        lag = ours.recv() if got else None
    finally:
        release.set()
        thread.join()
        process.join(5)
        if process.is_alive():
            process.kill()
    assert got, "the forked child's step hung on the world's lock"
    assert abs(lag) < 1e-6


FORK_WHILE_LOADING = """
import multiprocessing, threading, time
from spinstrike import physics
from spinstrike.physics import cache

real, loading = cache.KernelCache.load_overload, threading.Event()

def slow_load(self, sig, target_context):  # a load as long as a cold compile's, for the fork
    loading.set()
    time.sleep(1.0)
    return real(self, sig, target_context)

cache.KernelCache.load_overload = slow_load

def child(pipe):
    world = physics.World("rod_control")  # loads the exact solver's kernels
    world.step(1e-3)
    pipe.send(float(world.time[0]))

loader = threading.Thread(target=physics.World, args=("rod_control",),
                          kwargs={"solver": {"mode": "fixed"}})
loader.start()
assert loading.wait(120)
ours, theirs = multiprocessing.get_context("fork").Pipe()
process = multiprocessing.get_context("fork").Process(target=child, args=(theirs,))
process.start()
got = ours.poll(60)
if not got:
    process.kill()
print("child", ours.recv() if got else "hung")
process.join()
loader.join()
"""


def test_a_child_forked_while_another_thread_loads_a_kernel_loads_its_own():
    """Walk W26b F4: a fork (multiprocessing's default on Linux) while another thread built a
    first World, i.e. loaded a kernel holding numba's compiler lock, gave the child that lock
    held by a thread it does not have: the child's own first World waited for ever (5 of 5). The
    fork now waits for the load to end (here stretched to a second, so that the fork falls
    inside one), in a fresh process where no kernel is loaded yet."""
    import os
    import subprocess
    import sys

    if not hasattr(os, "fork"):
        pytest.skip("needs fork")
    done = subprocess.run([sys.executable, "-c", FORK_WHILE_LOADING], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["child", "0.001"], done.stdout + done.stderr
