"""RLlib's creator seeds its runners' envs apart across runs too (walk W26a F11), without Ray:
RLlib resets runner ``w``'s env with ``seed + w`` and passes the creator an ``EnvContext``, the
env config dict with the runner's ``worker_index``, which a dict subclass stands for here."""

import numpy as np

from spinstrike.envs.rllib import make_env

STRIKE = "SpinStrike/RodSpin-v0"


class EnvContext(dict):
    """RLlib's ``EnvContext``: the env config, with the runner's index."""

    def __init__(self, config, worker_index):
        super().__init__(config)
        self.worker_index = worker_index


def _first_tasks(seed, worker, n=4):
    env = make_env(STRIKE, EnvContext({"num_envs": n}, worker))
    obs, _ = env.reset(seed=seed + worker)  # as RLlib resets runner w
    env.close()
    return [row.tobytes() for row in obs]


def test_runs_of_other_seeds_share_no_task_stream():
    """``--seed 0``'s runner 2 drew exactly ``--seed 1``'s runner 1's tasks (both reset with
    2: elements seeded ``2 * n + i``): consecutive seeds shared half their training tasks with
    2 runners, (k - 1) / k with k. Every (seed, runner, element) now has its own stream, and the
    same ones again on a second run."""
    tasks = {(s, w): _first_tasks(s, w) for s in range(3) for w in (1, 2)}
    every = [t for firsts in tasks.values() for t in firsts]
    assert len(set(every)) == len(every) == 24
    assert _first_tasks(1, 2) == tasks[1, 2]
    # called directly (no runner index) the vector env keeps seeding s * num_envs + i
    direct = make_env(STRIKE, {"num_envs": 2})
    obs, _ = direct.reset(seed=3)
    single = [make_env(STRIKE).reset(seed=3 * 2 + i)[0] for i in range(2)]
    np.testing.assert_array_equal(obs, np.stack(single))
