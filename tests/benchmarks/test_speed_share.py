"""The speed benchmark's "share of SB3 PPO's wall time spent in the env" row, measured as
``spinstrike train`` trains: torch on one thread. On torch's default (a thread a core) the share
on a busy 2-core host came out 10-20x lower (0.005-0.008 against the documented 0.097, docs
walk W11), a figure nobody could reproduce."""

from __future__ import annotations

import pytest

from spinstrike.benchmarks import speed


def test_the_ppo_env_share_trains_on_one_torch_thread_and_gives_the_threads_back(monkeypatch):
    torch = pytest.importorskip("torch")
    pytest.importorskip("stable_baselines3")
    import spinstrike.envs.sb3 as sb3

    seen: list[int] = []
    make = sb3.make_sb3_vec_env

    def spied(*args, **kwargs):
        vec = make(*args, **kwargs)
        step_wait = vec.step_wait

        def counted():
            seen.append(torch.get_num_threads())
            return step_wait()

        vec.step_wait = counted
        return vec

    monkeypatch.setattr(sb3, "make_sb3_vec_env", spied)
    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        share = speed._ppo_env_share(256)
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(threads)
    assert 0.0 < share < 1.0
    assert seen and set(seen) == {1}
