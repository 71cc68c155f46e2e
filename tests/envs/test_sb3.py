"""SB3 trains through the native batched VecEnv adapter and through SubprocVecEnv of single envs
(tiny budgets: this checks the plumbing, not learning)."""

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3 import PPO, SAC
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import SubprocVecEnv

from spinstrike import envs  # noqa: F401
from spinstrike.envs.sb3 import make_sb3_vec_env


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/PuckSpeedControl-v0"])
def test_ppo_trains_on_native_vecenv(env_id):
    vec = make_sb3_vec_env(env_id, n_envs=4, seed=0)
    model = PPO("MlpPolicy", vec, n_steps=16, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(64)
    assert model.num_timesteps == 64
    vec.close()


def test_adapter_reports_episodes_like_monitor():
    vec = make_sb3_vec_env("SpinStrike/RodSpinControl-v0", n_envs=3, seed=1,
                           env_kwargs={"max_episode_steps": 4})
    obs = vec.reset()
    assert obs.shape == (3, 11)
    total = np.zeros(3)
    for _ in range(4):
        obs, rew, done, infos = vec.step(np.zeros((3, 2), np.float32))
        total += rew
    assert done.all()
    for i, info in enumerate(infos):
        assert info["TimeLimit.truncated"] is True
        assert info["episode"]["l"] == 4
        assert info["episode"]["r"] == pytest.approx(total[i])
        assert info["terminal_observation"].shape == (11,)
    vec.close()


def test_adapter_seeding_is_deterministic():
    def run():
        vec = make_sb3_vec_env("SpinStrike/RodSpin-v0", n_envs=2, seed=5)
        vec.reset()
        out = [vec.step(np.full((2, 3), 0.3, np.float32))[1] for _ in range(3)]
        vec.close()
        return np.array(out)

    assert np.array_equal(run(), run())


def test_adapter_set_attr_refuses_to_set_some_envs_only():
    """The adapter's envs are one batched world: set_attr on some indices used to set the
    attribute for every env, silently; get_attr answers once per index."""
    vec = make_sb3_vec_env("SpinStrike/RodSpin-v0", n_envs=3, seed=0)
    with pytest.raises(ValueError, match=r"set_attr: the 3 envs are one batched world"):
        vec.set_attr("render_fps_note", 1, indices=[1])
    vec.set_attr("render_fps_note", 2)  # every env: accepted
    vec.set_attr("render_fps_note", 3, indices=[2, 0, 1])
    assert vec.get_attr("render_fps_note", indices=[0, 2]) == [3, 3]


def test_adapter_env_method_acts_once_on_the_batched_world():
    """SB3's ``env_method`` on the adapter calls the vector env's method once: it used to call
    it once per index, so ``env_method("step", a)`` stepped all three envs three times."""
    vec = make_sb3_vec_env("SpinStrike/RodSpinControl-v0", n_envs=3, seed=0)
    vec.reset()
    t0 = vec.venv.world.time.copy()
    out = vec.env_method("step", np.zeros((3, 2), np.float32))
    assert len(out) == 3 and all(o is out[0] for o in out)
    np.testing.assert_allclose(vec.venv.world.time - t0, vec.venv.cfg.dt)
    vec.close()


def test_sac_trains_through_subprocvecenv():
    # worker processes import the package through the "spinstrike:" prefix of the id
    vec = make_vec_env("spinstrike:SpinStrike/RodSpin-v0", n_envs=2, seed=0,
                       vec_env_cls=SubprocVecEnv)
    model = SAC("MlpPolicy", vec, learning_starts=8, batch_size=8, train_freq=4, seed=0,
                device="cpu")
    model.learn(24)
    assert model.num_timesteps == 24
    vec.close()


def test_her_trains_on_goal_conditioned_env():
    from stable_baselines3 import HerReplayBuffer

    env = gym.make("SpinStrike/PuckSpeed-v0", obs_mode="dict")
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={"n_sampled_goal": 2, "goal_selection_strategy": "final"},
                learning_starts=10, batch_size=8, seed=0, device="cpu")
    model.learn(20)
    assert model.num_timesteps == 20


# --- the adapter behaves as SB3's DummyVecEnv of single envs (gym.make), the user's side -----

CONTROL = "SpinStrike/RodSpinControl-v0"


def _pair(env_id, n_envs=2, seed=0, **env_kwargs):
    """(DummyVecEnv of ``gym.make`` envs, the native adapter), made and seeded alike."""
    dummy = make_vec_env(env_id, n_envs, seed=seed, env_kwargs=env_kwargs)
    native = make_sb3_vec_env(env_id, n_envs, seed=seed, env_kwargs=env_kwargs)
    return dummy, native


@pytest.mark.parametrize("dt", [0.02, 0.05, 0.4])
def test_adapter_forwards_render_fps_to_vecvideorecorder(dt, tmp_path):
    """SB3's VecVideoRecorder read no ``render_fps`` from the adapter's metadata and filmed at
    its 30 fps fallback; DummyVecEnv forwards the env's (50 at dt=0.02, 20 at dt=0.05, 2.5 at
    dt=0.4: real time, where it was rounded to 2 and played at 0.8x)."""
    from stable_baselines3.common.vec_env import VecVideoRecorder

    dummy, native = _pair(CONTROL, render_mode="rgb_array", dt=dt)
    fps = gym.make(CONTROL, dt=dt).metadata["render_fps"]
    assert native.metadata["render_fps"] == dummy.metadata["render_fps"] == fps
    assert fps * dt == pytest.approx(1.0, rel=1e-12)
    recorders = [VecVideoRecorder(v, str(tmp_path / name), lambda step: False)
                 for name, v in (("dummy", dummy), ("native", native))]
    assert [r.frames_per_sec for r in recorders] == [fps, fps]
    for r in recorders:
        r.close()


def _run_both(dummy, native, steps, seed=0):
    """Step both with the same random actions, yielding each step's pair of
    (obs, reward, done, infos)."""
    rng = np.random.default_rng(seed)
    shape = (dummy.num_envs, *dummy.action_space.shape)
    for _ in range(steps):
        a = rng.uniform(-1, 1, shape).astype(np.float32)
        yield dummy.step(a), native.step(a)


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/PuckSpeedControl-v0"])
def test_adapter_episode_return_is_rounded_as_monitor(env_id):
    """SB3's Monitor rounds ``episode["r"]`` to 6 digits; the adapter reported the raw sum
    (8e-23 where Monitor says 0.0, 0.06375796820394647 for 0.063758)."""
    dummy, native = _pair(env_id, 3, seed=2, max_episode_steps=20)
    dummy.reset(), native.reset()
    ended = 0
    for (_, _, dd, di), (_, _, nd, ni) in _run_both(dummy, native, 40):
        assert np.array_equal(dd, nd)
        for i in np.flatnonzero(dd):
            assert ni[i]["episode"]["r"] == di[i]["episode"]["r"]
            assert ni[i]["episode"]["l"] == di[i]["episode"]["l"]
            ended += 1
    assert ended >= 6


def _assert_same_info(native: dict, dummy: dict, skip=("episode", "terminal_observation")):
    """Same keys, and per key the same value of the same type (arrays: equal, same dtype)."""
    assert sorted(native) == sorted(dummy)
    for k, v in dummy.items():
        if k in skip:
            continue
        assert type(native[k]) is type(v), k
        if isinstance(v, np.ndarray):
            assert native[k].dtype == v.dtype and np.array_equal(native[k], v), k
        else:
            assert native[k] == v, k


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/PuckSpeed-v1",
                                    "SpinStrike/PuckSpeedControl-v0"])
def test_adapter_fills_reset_infos_as_dummyvecenv(env_id):
    """``reset_infos`` stayed ``[{}, {}]``; DummyVecEnv fills it at reset() and at each
    autoreset (RodSpin's ``target_spin``, PuckSpeed's ``target_velocity``)."""
    dummy, native = _pair(env_id, 3, seed=4, max_episode_steps=5)
    dummy.reset(), native.reset()
    assert len(native.reset_infos) == 3
    for n, d in zip(native.reset_infos, dummy.reset_infos, strict=True):
        _assert_same_info(n, d)
    if env_id == "SpinStrike/RodSpin-v0":
        assert all("target_spin" in i for i in native.reset_infos)
    for _ in _run_both(dummy, native, 12):
        for n, d in zip(native.reset_infos, dummy.reset_infos, strict=True):
            _assert_same_info(n, d)


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/PuckSpeed-v1",
                                    "SpinStrike/RodSpinControl-v0",
                                    "SpinStrike/PuckSpeedControl-v0"])
def test_adapter_step_infos_as_dummyvecenv(env_id):
    """The adapter's step infos held only terminal_observation / TimeLimit.truncated / episode:
    the env's own step info (RodSpin's spin, best_reward, n_contacts; the control envs' hits,
    reward_hit, ...) that DummyVecEnv passes was missing. ``step_infos=True``: every element's,
    as DummyVecEnv; the default: the info of the elements whose episode ended (what SB3 reads)."""
    dummy, native = _pair(env_id, 3, seed=3, max_episode_steps=6)
    full = make_sb3_vec_env(env_id, 3, seed=3, env_kwargs={"max_episode_steps": 6},
                            step_infos=True)
    dummy.reset(), native.reset(), full.reset()
    rng = np.random.default_rng(1)
    ended = 0
    for _ in range(14):
        a = rng.uniform(-1, 1, (3, *dummy.action_space.shape)).astype(np.float32)
        _, _, dd, di = dummy.step(a)
        _, _, nd, ni = native.step(a)
        fo, _, fd, fi = full.step(a)
        assert np.array_equal(dd, nd) and np.array_equal(dd, fd)
        for i in range(3):
            _assert_same_info(fi[i], di[i])
            if dd[i]:
                _assert_same_info(ni[i], di[i])
                for got in (ni[i], fi[i]):
                    assert [got["episode"][k] for k in "rl"] == [di[i]["episode"][k]
                                                                  for k in "rl"]
                    np.testing.assert_array_equal(got["terminal_observation"],
                                                  di[i]["terminal_observation"])
                ended += 1
            else:
                assert ni[i] == {"TimeLimit.truncated": False}
    assert ended >= 6
    # each info's arrays are its own (DummyVecEnv deep-copies): editing one edits no other
    key = "force" if "force" in fi[0] else "first_contact_point"
    fi[0][key][:] = 123.0
    assert not np.any(fi[1][key] == 123.0)


def test_adapter_env_method_reset_resets_only_the_indices_asked():
    """``env_method("reset", indices=[0])`` reset every element and left the adapter's episode
    counters running (the next ``episode`` infos said l=350 for episodes truncated at 250). As
    DummyVecEnv: only the elements asked restart (seeded as asked), with their counters, and
    each one's (obs, info) is returned."""
    dummy, native = _pair(CONTROL, 3, seed=0, max_episode_steps=25)
    dummy.reset(), native.reset()
    for call in ({"indices": [0]}, {"indices": [2], "seed": 7}):
        for _ in _run_both(dummy, native, 5):
            pass
        got, want = native.env_method("reset", **call), dummy.env_method("reset", **call)
        assert len(got) == len(want) == 1
        np.testing.assert_array_equal(got[0][0], want[0][0])
        _assert_same_info(got[0][1], want[0][1])
    ends = []
    for (dobs, _, dd, di), (nobs, _, nd, ni) in _run_both(dummy, native, 30, seed=1):
        np.testing.assert_array_equal(nobs, dobs)
        assert np.array_equal(nd, dd)
        for i in np.flatnonzero(dd):
            assert ni[i]["episode"]["l"] == di[i]["episode"]["l"] == 25
            ends.append(i)
    assert sorted(ends) == [0, 1, 2]
