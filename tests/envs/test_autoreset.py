"""Autoreset modes of the native vector env, from the user's side (``gym.make_vec``).

Each mode (``NEXT_STEP``, the default; ``SAME_STEP``; ``DISABLED``) is compared bit for bit with
Gymnasium's own ``SyncVectorEnv`` of single envs in the same mode, for every env id, over
episodes with resets: observations, rewards, terminated, truncated and the info dicts (values,
``_key`` masks, ``final_obs`` / ``final_info``). Gymnasium's vector wrappers run on the native
env in NEXT_STEP mode (they refuse SAME_STEP).
"""

from __future__ import annotations

import gc

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import spinstrike  # noqa: F401  (registers the ids)
from spinstrike.envs import ENV_IDS, ConfigError

MODES = [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED]
IDS = list(ENV_IDS)


def _short(env_id: str) -> dict:
    """Control episodes cut short, so a short run crosses several resets."""
    return {"max_episode_steps": 4} if "Control" in env_id else {}


def _pair(env_id: str, n: int, mode: AutoresetMode, **kwargs):
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, **_short(env_id), **kwargs)
    sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **_short(env_id), **kwargs)
    return native, sync


def assert_same(got, want, where: str) -> None:
    """Bit-for-bit equality of batched outputs: arrays (values and dtype), dicts (the same
    keys), object arrays of ``final_obs`` (None where the mask is False)."""
    if isinstance(want, dict):
        assert isinstance(got, dict), where
        assert sorted(got) == sorted(want), f"{where}: keys {sorted(got)} != {sorted(want)}"
        for k in want:
            assert_same(got[k], want[k], f"{where}[{k!r}]")
        return
    want, got = np.asarray(want), np.asarray(got)
    if want.dtype == object:
        assert got.dtype == object and got.shape == want.shape, where
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            if w is None:
                assert g is None, f"{where}[{i}]"
            else:
                assert_same(g, w, f"{where}[{i}]")
        return
    assert got.dtype == want.dtype, f"{where}: dtype {got.dtype} != {want.dtype}"
    np.testing.assert_array_equal(got, want, err_msg=where)


def _masked_info(info: dict) -> dict:
    """An info dict with the values under False masks zeroed (they are unspecified: Gymnasium
    leaves zeros there, a batched env what its batch holds)."""
    out = {}
    for k, v in info.items():
        if isinstance(v, dict):
            out[k] = _masked_info(v)
        elif not k.startswith("_") and f"_{k}" in info and isinstance(v, np.ndarray) \
                and v.dtype != object:
            v = v.copy()
            v[~info[f"_{k}"]] = 0
            out[k] = v
        else:
            out[k] = v
    return out


def _run(env_id: str, mode: AutoresetMode, n: int = 3, steps: int = 14, seed: int = 5) -> int:
    native, sync = _pair(env_id, n, mode)
    assert native.metadata["autoreset_mode"] is mode
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, (steps, n, native.single_action_space.shape[0]))
    acts = acts.astype(np.float32)
    got, want = native.reset(seed=seed), sync.reset(seed=seed)
    for part, g, w in zip(("obs", "info"), got, want, strict=True):
        assert_same(_masked_info(g) if part == "info" else g,
                    _masked_info(w) if part == "info" else w, f"reset {part}")
    episodes = 0
    for k in range(steps):
        got, want = native.step(acts[k]), sync.step(acts[k])
        for part, g, w in zip(("obs", "reward", "terminated", "truncated", "info"), got, want,
                              strict=True):
            assert_same(_masked_info(g) if part == "info" else g,
                        _masked_info(w) if part == "info" else w, f"step {k} {part}")
        done = got[2] | got[3]
        episodes += int(done.sum())
        if mode is AutoresetMode.DISABLED and done.any():
            opts = {"reset_mask": done.copy()}
            got = native.reset(options=dict(opts))
            want = sync.reset(options=dict(opts))
            assert_same(got[0], want[0], f"reset {k} obs")
            assert_same(_masked_info(got[1]), _masked_info(want[1]), f"reset {k} info")
    native.close()
    sync.close()
    return episodes


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
@pytest.mark.parametrize("env_id", IDS)
def test_native_vector_env_matches_sync_vector_env_in_every_mode(env_id, mode):
    episodes = _run(env_id, mode)
    assert episodes >= 6  # several resets happened inside the compared run


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/RodSpinControl-v0"])
def test_next_step_after_a_partial_reset_matches_sync_vector_env(env_id):
    """Elements out of step (one reset by mask mid-episode, then NEXT_STEP autoresets of some
    but not all elements in one step): still bit for bit."""
    mode = AutoresetMode.NEXT_STEP
    n = 3
    native, sync = _pair(env_id, n, mode)
    native.reset(seed=1)
    sync.reset(seed=1)
    rng = np.random.default_rng(2)
    for k in range(12):
        a = rng.uniform(-1, 1, (n, native.single_action_space.shape[0])).astype(np.float32)
        got, want = native.step(a), sync.step(a)
        for part, g, w in zip(("obs", "reward", "terminated", "truncated", "info"), got, want,
                              strict=True):
            assert_same(_masked_info(g) if part == "info" else g,
                        _masked_info(w) if part == "info" else w, f"step {k} {part}")
        if k in (1, 6):
            mask = np.zeros(n, dtype=bool)
            mask[k % n] = True
            got = native.reset(options={"reset_mask": mask})
            want = sync.reset(options={"reset_mask": mask.copy()})
            assert_same(got[0], want[0], "masked reset obs")
            assert_same(_masked_info(got[1]), _masked_info(want[1]), "masked reset info")


def test_one_strike_next_step_alternates_strikes_and_resets():
    vec = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=4)
    assert vec.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP  # the default
    obs0, info0 = vec.reset(seed=0)
    a = np.zeros((4, 3), np.float32)
    obs1, r1, term1, _, _ = vec.step(a)
    assert term1.all() and np.any(r1 != 0)
    np.testing.assert_array_equal(obs1, obs0)  # the last observation of the episode
    obs2, r2, term2, trunc2, info2 = vec.step(a)  # the reset step: the action is ignored
    assert not term2.any() and not trunc2.any() and np.all(r2 == 0)
    assert info2["_target_spin"].all() and not np.array_equal(obs2, obs0)
    assert "final_obs" not in info2


@pytest.mark.parametrize("spelling", ["next_step", "NextStep", "SAME_STEP", "same-step",
                                      "disabled"])
def test_autoreset_mode_accepts_strings(spelling):
    vec = gym.make_vec("SpinStrike/PuckSpeed-v0", num_envs=2, autoreset_mode=spelling)
    want = {"n": AutoresetMode.NEXT_STEP, "s": AutoresetMode.SAME_STEP,
            "d": AutoresetMode.DISABLED}[spelling[0].lower()]
    assert vec.metadata["autoreset_mode"] is want


def test_autoreset_mode_is_per_instance():
    a = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, autoreset_mode="same_step")
    b = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, autoreset_mode="disabled")
    c = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2)
    assert a.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    assert b.metadata["autoreset_mode"] is AutoresetMode.DISABLED
    assert c.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert type(c).metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP


def test_bad_autoreset_mode_names_the_field():
    with pytest.raises(ValueError, match="autoreset_mode.*next_step"):
        gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, autoreset_mode="sometimes")


def test_disabled_mode_needs_a_masked_reset():
    vec = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=3, autoreset_mode="disabled")
    vec.reset(seed=0)
    _, _, term, _, _ = vec.step(np.zeros((3, 3), np.float32))
    assert term.all()
    with pytest.raises(gym.error.ResetNeeded, match="reset_mask"):
        vec.step(np.zeros((3, 3), np.float32))
    mask = np.array([True, False, True])
    vec.reset(options={"reset_mask": mask})
    with pytest.raises(gym.error.ResetNeeded, match=r"\[1\]"):
        vec.step(np.zeros((3, 3), np.float32))
    vec.reset(options={"reset_mask": ~mask})
    vec.step(np.zeros((3, 3), np.float32))
    for bad, err in [([True, False, True], TypeError), (np.ones(2, bool), ValueError),
                     (np.ones(3), TypeError), (np.zeros(3, bool), ValueError)]:
        with pytest.raises(err, match="reset_mask"):
            vec.reset(options={"reset_mask": bad})


def test_gymnasium_vector_wrappers_run_in_next_step_mode():
    n = 4
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", num_envs=n, max_episode_steps=5)
    vec = gym.wrappers.vector.ClipAction(vec)
    vec = gym.wrappers.vector.NormalizeObservation(vec)
    vec = gym.wrappers.vector.RecordEpisodeStatistics(vec)
    vec.reset(seed=0)
    rewards = np.zeros(n)
    episodes = []
    for _ in range(12):
        # out-of-box actions: ClipAction brings them into [-1, 1]
        obs, r, term, trunc, info = vec.step(np.full((n, 2), 3.0, np.float32))
        rewards += r
        assert np.all(np.isfinite(obs))
        if "episode" in info:
            for i in np.flatnonzero(info["_episode"]):
                episodes.append((info["episode"]["r"][i], info["episode"]["l"][i], rewards[i]))
                rewards[i] = 0.0
    assert len(episodes) == 2 * n
    for r, length, mine in episodes:
        assert length == 5
        assert r == pytest.approx(mine)
    # the normaliser saw the observations: its running mean moved off zero
    assert np.any(vec.env.obs_rms.mean != 0)


def test_vector_env_whose_init_raises_prints_no_attribute_error(capfd):
    with pytest.raises(ConfigError):
        gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, no_such_key=1)
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, autoreset_mode="never")
    gc.collect()
    err = capfd.readouterr().err
    assert "AttributeError" not in err and "Exception ignored" not in err
