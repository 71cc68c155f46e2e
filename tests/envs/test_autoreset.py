"""Autoreset modes of the native vector env, from the user's side (``gym.make_vec``).

Each mode (``NEXT_STEP``, the default; ``SAME_STEP``; ``DISABLED``) is compared bit for bit with
Gymnasium's own ``SyncVectorEnv`` of single envs in the same mode, for every env id, over
episodes with resets: observations, rewards, terminated, truncated and the info dicts (values,
``_key`` masks, ``final_obs`` / ``final_info``; zeros under a False mask, as SyncVectorEnv
leaves them). Gymnasium's vector wrappers run on the native
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
    kwargs = _short(env_id) | kwargs
    native = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, **kwargs)
    sync = gym.make_vec(env_id, num_envs=n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kwargs)
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


def _run(env_id: str, mode: AutoresetMode, n: int = 3, steps: int = 14, seed: int = 5,
         **kwargs) -> int:
    native, sync = _pair(env_id, n, mode, **kwargs)
    assert native.metadata["autoreset_mode"] is mode
    rng = np.random.default_rng(seed)
    acts = rng.uniform(-1, 1, (steps, n, native.single_action_space.shape[0]))
    acts = acts.astype(np.float32)
    got, want = native.reset(seed=seed), sync.reset(seed=seed)
    for part, g, w in zip(("obs", "info"), got, want, strict=True):
        assert_same(g, w, f"reset {part}")
    episodes = 0
    for k in range(steps):
        got, want = native.step(acts[k]), sync.step(acts[k])
        for part, g, w in zip(("obs", "reward", "terminated", "truncated", "info"), got, want,
                              strict=True):
            assert_same(g, w, f"step {k} {part}")
        done = got[2] | got[3]
        episodes += int(done.sum())
        if mode is AutoresetMode.DISABLED and done.any():
            opts = {"reset_mask": done.copy()}
            got = native.reset(options=dict(opts))
            want = sync.reset(options=dict(opts))
            assert_same(got[0], want[0], f"reset {k} obs")
            assert_same(got[1], want[1], f"reset {k} info")
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
            assert_same(g, w, f"step {k} {part}")
        if k in (1, 6):
            mask = np.zeros(n, dtype=bool)
            mask[k % n] = True
            got = native.reset(options={"reset_mask": mask})
            want = sync.reset(options={"reset_mask": mask.copy()})
            assert_same(got[0], want[0], "masked reset obs")
            assert_same(got[1], want[1], "masked reset info")


def _same_step(got, want, where: str) -> None:
    for part, g, w in zip(("obs", "reward", "terminated", "truncated", "info"), got, want,
                          strict=True):
        assert_same(g, w, f"{where} {part}")


@pytest.mark.parametrize("bad", ["nan", "shape"])
def test_a_refused_action_while_some_elements_autoreset_leaves_no_trace(bad):
    """NEXT_STEP with one element due for its autoreset and one not: a step refused for its
    action (NaN in the running element, a wrong shape) had already drawn the resetting
    element's next task, so the retried step started it from the draw after, and the seeded
    run left its reference. Now the action is checked first; the message shows the actions as
    given (the resetting element's were shown zeroed)."""
    env_id = "SpinStrike/RodSpinControl-v0"

    def out_of_step():
        env = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point",
                           max_episode_steps=2)
        env.reset(seed=0)
        env.step(np.zeros((2, 2)))
        env.reset(options={"reset_mask": np.array([True, False])})
        env.step(np.zeros((2, 2)))  # element 1 truncates; element 0 runs on
        return env

    reference, env = out_of_step(), out_of_step()
    if bad == "nan":
        with pytest.raises(ValueError, match=r"\[\[nan, 0.0\], \[0.3, 0.7\]\]"):
            env.step(np.array([[np.nan, 0.0], [0.3, 0.7]]))
    else:
        with pytest.raises(ValueError, match=r"expected shape \(2, 2\), got \(3, 2\)"):
            env.step(np.zeros((3, 2)))
    rng = np.random.default_rng(3)
    for k in range(6):  # the resetting element's new task, and the steps after
        a = rng.uniform(-1, 1, (2, 2))
        _same_step(env.step(a), reference.step(a), f"step {k}")
    # a NaN in the resetting element's row is not used (as SyncVectorEnv ignores it)
    _, sync = _pair(env_id, 2, AutoresetMode.NEXT_STEP, max_episode_steps=2)
    native = out_of_step()
    sync.reset(seed=0)
    sync.step(np.zeros((2, 2)))
    sync.reset(options={"reset_mask": np.array([True, False])})
    sync.step(np.zeros((2, 2)))
    ignored = np.array([[0.2, -0.1], [np.nan, np.nan]])
    _same_step(native.step(ignored), sync.step(ignored), "NaN in the resetting element")


@pytest.mark.parametrize("bad", [np.zeros((7, 5)), "hello", np.zeros((2, 3), dtype=bool)])
def test_the_step_that_resets_every_element_refuses_actions_of_another_shape_or_type(bad):
    """NEXT_STEP on a one-strike env: every other step resets every element and uses none of
    the actions; actions of shape (7, 5) or a string passed there (W18b; SyncVectorEnv raises).
    They are refused now as on the other steps, and the env goes on as if never asked; NaN
    still passes there, as SyncVectorEnv's resetting envs ignore it."""
    env_id = "SpinStrike/RodSpin-v0"

    def struck():
        env = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point")
        env.reset(seed=0)
        env.step(np.zeros((2, 3)))  # every element's strike: the next step resets them all
        return env

    env, reference = struck(), struck()
    with pytest.raises(ValueError, match="action: "):
        env.step(bad)
    rng = np.random.default_rng(3)
    for k in range(4):
        a = rng.uniform(-1, 1, (2, 3))
        _same_step(env.step(a), reference.step(a), f"step {k}")
    native, sync = _pair(env_id, 2, AutoresetMode.NEXT_STEP)
    for vec in (native, sync):
        vec.reset(seed=0)
        vec.step(np.zeros((2, 3)))
    ignored = np.full((2, 3), np.nan)
    _same_step(native.step(ignored), sync.step(ignored), "NaN in the resetting elements")


@pytest.mark.parametrize("mode", ["vector_entry_point", "sync"])
def test_seeds_that_are_not_integers_are_refused_as_gymnasium_refuses_them(mode):
    """The native vector env truncated float seeds (1.5 and 2.7 seeded 1 and 2, silently) and
    said ``'float' object is not iterable`` for a float given alone; now both raise
    Gymnasium's ``Error`` as a single env and SyncVectorEnv do. numpy integers are exact and
    kept."""
    env = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, vectorization_mode=mode)
    with pytest.raises(gym.error.Error, match="Seed must be a python integer"):
        env.reset(seed=[1.5, 2.7])
    with pytest.raises(gym.error.Error, match="Seed must be a python integer"):
        gym.make("SpinStrike/RodSpin-v0").reset(seed=1.5)
    if mode == "vector_entry_point":
        with pytest.raises(gym.error.Error, match=r"Seed must be a python integer or a list of 2"
                                                  r" \(integers or None\), actual type: "
                                                  r"<class 'float'>"):
            env.reset(seed=1.5)
        with pytest.raises(gym.error.Error, match="Seed must be a python integer"):
            env.reset(seed=["a", "b"])
        ints = env.reset(seed=[1, 2])[0]
        np.testing.assert_array_equal(env.reset(seed=np.array([1, 2]))[0], ints)
        np.testing.assert_array_equal(env.reset(seed=np.int64(1))[0], ints)
        assert env.unwrapped.np_random_seed == (1, 2)
        assert not np.array_equal(env.reset(seed=[3, 4])[0], ints)


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


def _version_tuple(version: str) -> tuple[int, ...]:
    return tuple(int(part) for part in version.split(".")[:2])


def test_same_step_returns_are_where_the_readme_says():
    """The README sent a CleanRL-style SAME_STEP loop to ``info["final_info"]["episode"]``,
    which is not there (a KeyError); ``RecordEpisodeStatistics`` puts the returns in the step's
    own ``info["episode"]``, masked by ``info["_episode"]``, as over Gymnasium's own envs; the
    strike's info is in ``info["final_info"]``."""
    vec = gym.wrappers.vector.RecordEpisodeStatistics(
        gym.make_vec("SpinStrike/RodSpin-v0", 4, autoreset_mode="same_step"))
    vec.reset(seed=0)
    vec.action_space.seed(0)
    # Gymnasium 1.2.2 (Ray's pin) reports zeros for the episode that ends right after another
    # in SAME_STEP (its wrapper's bug, on its own SyncVectorEnv too); 1.4 reports every one
    steps = 3 if _version_tuple(gym.__version__) >= (1, 4) else 1
    for _ in range(steps):
        _, reward, term, _, info = vec.step(vec.action_space.sample())
        assert term.all() and info["_episode"].all() and "episode" not in info["final_info"]
        np.testing.assert_allclose(info["episode"]["r"], reward, rtol=1e-6)
        np.testing.assert_array_equal(info["episode"]["l"], 1)
        np.testing.assert_array_equal(info["final_info"]["reward_spin"], reward)


def test_vector_env_whose_init_raises_prints_no_attribute_error(capfd):
    with pytest.raises(ConfigError):
        gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, no_such_key=1)
    with pytest.raises(ValueError, match="autoreset_mode"):
        gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, autoreset_mode="never")
    gc.collect()
    err = capfd.readouterr().err
    assert "AttributeError" not in err and "Exception ignored" not in err


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
def test_unmasked_infos_match_sync_vector_env_too(mode):
    """Values under a False ``_key`` mask are zeros, as SyncVectorEnv leaves them (the native
    env left the batch's values there: the same masked values, other unmasked means)."""
    native, sync = _pair("SpinStrike/RodSpinControl-v0", 3, mode, max_episode_steps=3)
    native.reset(seed=2)
    sync.reset(seed=2)
    a = np.full((3, 2), 0.8, np.float32)
    native.step(a)
    sync.step(a)
    native.reset(options={"reset_mask": np.array([True, False, False])})  # out of step
    sync.reset(options={"reset_mask": np.array([True, False, False])})
    for k in range(8):
        got, want = native.step(a), sync.step(a)
        assert_same(got[4], want[4], f"step {k} info")
        if mode is AutoresetMode.DISABLED and (got[2] | got[3]).any():
            opts = {"reset_mask": got[2] | got[3]}
            assert_same(native.reset(options=dict(opts))[1],
                        sync.reset(options=dict(opts))[1], "reset info")


@pytest.mark.parametrize("mode", MODES, ids=lambda m: m.name)
def test_masks_are_fresh_arrays_each_step(mode):
    """A user editing one ``_key`` mask in place (e.g. to drop an element) changes nothing
    else: every mask was one shared array, so the edit hid element 0 in every later step."""
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", num_envs=3, autoreset_mode=mode)
    vec.reset(seed=0)
    a = np.zeros((3, 2), np.float32)
    info = vec.step(a)[4]
    masks = [v for k, v in info.items() if k.startswith("_")]
    assert len({id(m) for m in masks}) == len(masks)
    for m in masks:
        m[0] = False
    later = vec.step(a)[4]
    assert all(v[0] for k, v in later.items() if k.startswith("_")), later


@pytest.mark.parametrize("limit", [None, -1, 1, 3])
@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/RodSpinControl-v0"])
def test_max_episode_steps_reads_as_gymnasium_reads_it(env_id, limit):
    """``max_episode_steps`` as ``gym.make`` and SyncVectorEnv read it: None is the registered
    limit (the native env had none), -1 no limit (the native env truncated every step), and
    the step that reaches the limit is truncated also when it terminates (one-strike envs)."""
    for mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        native, sync = _pair(env_id, 2, mode, max_episode_steps=limit)
        native.reset(seed=3)
        sync.reset(seed=3)
        a = np.zeros((2, native.single_action_space.shape[0]), np.float32)
        ends = 0
        for k in range(260 if "Control" in env_id else 4):
            got, want = native.step(a), sync.step(a)
            for part, g, w in zip(("obs", "reward", "terminated", "truncated", "info"), got,
                                  want, strict=True):
                assert_same(g, w, f"{mode.name} step {k} {part}")
            ends += int(got[3].sum())
        expected = {None: 2 if "Control" in env_id else 0, -1: 0}.get(limit)
        if expected is not None:
            assert ends == expected, (limit, ends)
        native.close()
        sync.close()


@pytest.mark.parametrize("bad", [0, -2, 2.5, "10", True])
@pytest.mark.parametrize(("env_id", "limit"), [("SpinStrike/RodSpinControl-v0", "250"),
                                               ("SpinStrike/RodSpin-v0", "none")])
def test_a_bad_max_episode_steps_names_the_argument(bad, env_id, limit):
    # a strike env's registered limit read "None", as if it were the value to give
    with pytest.raises(ConfigError, match=r"max_episode_steps: must be an int >= 1, -1 \(no "
                       rf"limit\) or None \(the registered limit, {limit}\) \(got "):
        gym.make_vec(env_id, num_envs=2, max_episode_steps=bad)


@pytest.mark.parametrize("bad", [2.5, "2", 0, True])
def test_a_bad_num_envs_names_the_argument(bad):
    with pytest.raises(ConfigError, match=r"num_envs: must be an int >= 1"):
        gym.make_vec("SpinStrike/RodSpinControl-v0", num_envs=bad,
                     vectorization_mode="vector_entry_point")


def test_registered_limits_are_the_vector_envs_defaults():
    for env_id in IDS:
        spec = gym.spec(env_id)
        module, name = spec.vector_entry_point.split(":")
        import importlib
        cls = getattr(importlib.import_module(module), name)
        assert cls.MAX_EPISODE_STEPS == spec.max_episode_steps, env_id
