"""Vector envs across processes and threads, from the user's side (``gym.make_vec``).

From ``PARALLEL_BATCH`` (256) elements a world runs numba's parallel kernels. GNU OpenMP, numba's
threading layer here, kills a forked child at its first parallel region when the parent has run
one (multiprocessing's default start method on Linux up to Python 3.13), and a ``Pool`` then
waits for the lost task forever; numba's workqueue layer (its fallback where neither TBB nor
OpenMP is installed) aborts the whole process when two threads run parallel regions at once.
"""

from __future__ import annotations

import ast
import multiprocessing
import os
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest

import spinstrike  # noqa: F401  (registers the ids)

ENV_ID = "SpinStrike/RodSpinControl-v0"
N = 256  # the parallel kernels' batch


def rollout(n: int = N, seed: int = 0, steps: int = 20) -> np.ndarray:
    env = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point")
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, *_ = env.step(rng.uniform(-1, 1, (n, 2)))
    return obs


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_forked_worker_of_a_process_that_ran_the_parallel_kernels_steps_a_vector_env():
    """The worker printed 'fork() called from a process already using GNU OpenMP, this is
    unsafe', died, and ``Pool.apply_async(...).get()`` never returned. A forked child of a
    process that ran parallel kernels now runs the serial ones: the same numbers."""
    want = rollout()
    with multiprocessing.get_context("fork").Pool(1) as pool:
        got = pool.apply_async(rollout).get(timeout=300)
    np.testing.assert_array_equal(got, want)


def test_two_threads_step_vector_envs_at_once_under_numbas_workqueue_layer():
    """Under the workqueue layer two threads each stepping a vector env of 256 elements aborted
    the process ('Concurrent access has been detected'); parallel kernels now run one at a
    time, and each thread's rollout equals the same rollout run alone."""
    script = textwrap.dedent("""
        import threading
        import numpy as np
        from tests.envs.test_processes import rollout
        alone = [rollout(seed=s) for s in (1, 2)]
        got = {}
        threads = [threading.Thread(target=lambda s=s: got.__setitem__(s, rollout(seed=s)))
                   for s in (1, 2)]
        [t.start() for t in threads]
        [t.join() for t in threads]
        assert all(np.array_equal(got[s], a) for s, a in zip((1, 2), alone))
        import numba
        print("layer", numba.threading_layer())
    """)
    env = dict(os.environ, NUMBA_THREADING_LAYER="workqueue")
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    done = subprocess.run([sys.executable, "-c", script], cwd=root, env=env,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "layer workqueue" in done.stdout


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_workers_started_together_on_a_cold_cache_compile_each_kernel_once(tmp_path):
    """SB3's ``SubprocVecEnv`` with workers that each make the env, on an empty kernel cache:
    every worker compiled the same kernels at once (4 RodSpin-v0 workers on 2 cores: 59 s to
    the first step against 28 s for one). The workers now take turns: one compiles the env's
    strike kernel, the others wait and load it from the cache (30 s)."""
    script = textwrap.dedent("""
        import gymnasium as gym, numpy as np
        from numba.core import types
        from stable_baselines3.common.vec_env import SubprocVecEnv
        import spinstrike
        from spinstrike.envs import fast

        class Compiles(gym.Wrapper):
            def kernel_compiles(self):  # (literal signatures compiled, loaded from the cache)
                stats = fast.strike_body.stats
                literal = lambda sig: any(isinstance(t, types.Literal) for t in sig)
                return (sum(n for s, n in stats.cache_misses.items() if literal(s)),
                        sum(stats.cache_hits.values()))

        if __name__ == "__main__":
            v = SubprocVecEnv([lambda: Compiles(gym.make("SpinStrike/PuckSpeed-v0"))] * 3,
                              start_method="fork")
            v.reset()
            v.step(np.zeros((3, 3), np.float32))
            print(v.env_method("kernel_compiles"))
            v.close()
    """)
    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(tmp_path / "cache"), SPINSTRIKE_QUIET="1")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True,
                         cwd=tmp_path, timeout=900)
    assert out.returncode == 0, out.stderr
    compiled, loaded = zip(*ast.literal_eval(out.stdout.strip().splitlines()[-1]), strict=True)
    assert sum(compiled) == 1 and sorted(loaded) == [0, 1, 1], out.stdout
