"""Rollout videos (issue 13), from the user's side: ``render_mode="rgb_array_list"`` through
``gym.make``, the recording wrapper, ``spinstrike record``, and the laws a strike's frames obey
(they lie on the trajectory the solver computed, one at each contact instant, slowed so that
the strike lasts at least a second)."""

import dataclasses
import hashlib
import math
import pickle
import time
import warnings

import gymnasium as gym
import imageio.v3 as iio
import imageio_ffmpeg
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers import RecordVideo, RenderCollection
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from spinstrike import envs
from spinstrike.agents.cli import main
from spinstrike.agents.oracle import oracle_for
from spinstrike.envs import fast
from spinstrike.envs.recording import RecordEveryFrame, VideoWriter, tile
from spinstrike.envs.rendering import COLOURS, Frame, Marker, Renderer, strike_times
from spinstrike.envs.strike import CHUNK
from spinstrike.physics.layout import ANGLE, OMEGA, VX, VY, X, Y

ENV_IDS = list(envs.ENV_IDS)
STRIKE_IDS = ["SpinStrike/RodSpin-v0", "SpinStrike/PuckSpeed-v0", "SpinStrike/PuckSpeed-v1"]
CONTROL_IDS = ["SpinStrike/RodSpinControl-v0", "SpinStrike/PuckSpeedControl-v0"]
MODES = [None, "rgb_array", "rgb_array_list", "human"]


def _strike(env_id, seed, action=None, **kwargs):
    """One strike in list mode: (env, frames of the strike, info)."""
    env = gym.make(env_id, render_mode="rgb_array_list", **kwargs)
    obs, _ = env.reset(seed=seed)
    assert len(env.render()) == 1  # the reset frame
    if action is None:
        action = oracle_for(env_id)(env, obs)
    *_, info = env.step(action)
    return env, env.render(), info


def _actions(space, n, seed):
    return np.random.default_rng(seed).uniform(-1, 1, (n, *space.shape)).astype(np.float32)


def _gap(task, S):
    """Surface distance (m) between the striker and the target (a capsule or a disk) in the
    state rows ``S``, computed here from the geometry."""
    w, it, js = task.world, task.it, task.js
    h, rt, rs = w.half_length[0, it], w.radius[0, it], w.radius[0, js]
    u = np.array([math.cos(S[it, ANGLE]), math.sin(S[it, ANGLE])])
    d = S[js, X:Y + 1] - S[it, X:Y + 1]
    s = np.clip(d @ u, -h, h)
    return np.linalg.norm(d - s * u) - rt - rs


# --- the render modes --------------------------------------------------------------------------

@pytest.mark.parametrize("env_id", ENV_IDS)
def test_list_mode_is_the_envs_own(env_id):
    """The env lists rgb_array_list, so gym.make passes it through (no RenderCollection)."""
    env = gym.make(env_id, render_mode="rgb_array_list")
    assert "rgb_array_list" in env.unwrapped.metadata["render_modes"]
    assert env.unwrapped.render_mode == "rgb_array_list"
    wrapper = env
    while wrapper is not env.unwrapped:
        assert not isinstance(wrapper, RenderCollection)
        wrapper = wrapper.env


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("mode", ["rgb_array_list", "human"])
def test_checkers_pass_without_warnings_in_every_render_mode(env_id, mode, monkeypatch):
    play = Renderer.show
    # the window shows every frame, without waiting for the pace (a strike plays >= 1 s, and
    # check_env strikes a dozen times); the pace is tested below
    monkeypatch.setattr(Renderer, "show", lambda self, image, fps: play(self, image, 1e6))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Gymnasium's notice that PuckSpeed-v0 has a v1 (intended; the checkers stay strict)
        warnings.filterwarnings("ignore", message=".*PuckSpeed-v0 is out of date")
        env = gym.make(env_id, render_mode=mode)
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped)
        env.close()


@pytest.mark.parametrize("env_id", STRIKE_IDS)
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_a_strike_is_at_least_a_second_of_frames(env_id, seed):
    rng = np.random.default_rng(seed)
    action = None if seed % 2 == 0 else rng.uniform(-1, 1, 3).astype(np.float32)
    env, frames, info = _strike(env_id, seed, action)
    fps = env.metadata["render_fps"]
    clip = env.unwrapped.task.clip
    assert fps == 30 and len(frames) >= fps and len(frames) / fps >= 1.0
    assert len(frames) == len(clip.times)
    # the smallest whole slow-motion factor that makes the strike last a second
    T = info["sim_time"]
    assert clip.duration == T and clip.times[0] == 0.0 and clip.times[-1] == T
    assert clip.slow_motion == max(1, math.ceil(1 / T - 1e-9))
    assert T * clip.slow_motion >= 1 - 1e-9 and T * (clip.slow_motion - 1) < 1
    want, _ = strike_times(T, fps, clip.contacts[:, fast.TC_TIME])
    np.testing.assert_array_equal(clip.times, want)
    assert env.render() == []  # cleared by the render() before
    assert clip.dropped == 0


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_control_envs_render_one_frame_per_step(env_id):
    env = gym.make(env_id, render_mode="rgb_array_list")
    env.reset(seed=0)
    assert len(env.render()) == 1
    for a in _actions(env.action_space, 7, 0):
        env.step(a)
    frames = env.render()
    assert len(frames) == 7 and env.render() == []
    assert all(not np.array_equal(a, b) for a, b in zip(frames, frames[1:], strict=False))
    # a reset clears the frames not yet returned, and starts with its own frame
    env.step(env.action_space.sample())
    env.reset(seed=1)
    assert len(env.render()) == 1


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_frames_have_the_configured_size(env_id):
    env = gym.make(env_id, render_mode="rgb_array_list")
    env.reset(seed=0)
    frame = env.render()[0]
    assert frame.shape == (480, 720, 3) and frame.dtype == np.uint8  # >= 640 wide by default
    env = gym.make(env_id, render_mode="rgb_array_list", render_size=(640, 360))
    env.reset(seed=0)
    env.step(env.action_space.sample())
    assert {f.shape for f in env.render()} == {(360, 640, 3)}


@pytest.mark.parametrize("env_id", STRIKE_IDS)
def test_strike_frames_are_distinct_and_move(env_id):
    env, frames, _ = _strike(env_id, 5)
    assert all(not np.array_equal(a, b) for a, b in zip(frames, frames[1:], strict=False))
    states = env.unwrapped.task.clip.states
    striker = env.unwrapped.task.js
    assert (np.diff(states[:, striker, X:Y + 1], axis=0) != 0).any(axis=1).all()


@pytest.mark.parametrize("env_id", STRIKE_IDS)
@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_a_frame_at_each_contact_with_the_bodies_touching(env_id, seed):
    rng = np.random.default_rng(100 + seed)
    action = None if seed == 0 else rng.uniform(-1, 1, 3).astype(np.float32)
    env, frames, info = _strike(env_id, seed, action)
    task = env.unwrapped.task
    clip = task.clip
    times = clip.contacts[:, fast.TC_TIME]
    # the recorded contacts are the ones info reports
    assert len(times) == info["n_contacts"]
    if len(times):
        assert times[0] == info["first_contact_time"]
        assert clip.contacts[0, fast.TC_J] == info["first_impulse"]
        assert clip.contacts[:, fast.TC_J].sum() == pytest.approx(info["impulse"], rel=1e-12)
    tol = task.world.tolerance
    drawn = task.step_frames()
    for q, t in enumerate(times):
        (f,) = np.flatnonzero(clip.times == t)  # exactly one frame at the contact instant
        assert abs(_gap(task, clip.states[f])) <= tol
        # its marker, at full strength, is the push on the target: away from the striker
        (m,) = [m for m in drawn[f].markers if m.fade == 1.0 and
                m.j == clip.contacts[q, fast.TC_J]]
        striker = clip.states[f][task.js, X:Y + 1]
        assert (m.x - striker[0]) * m.nx + (m.y - striker[1]) * m.ny > 0
    # and no frame shows the bodies overlapping
    assert min(_gap(task, S) for S in clip.states) >= -tol


@pytest.mark.parametrize(("kwargs", "seed"), [({"restitution": 0.3, "striker_mass": 50.0}, 19),
                                              ({"restitution": 0.0}, 0)])
def test_a_strike_of_thousands_of_contacts_is_filmed_on_its_trajectory(kwargs, seed):
    """A heavy striker or e = 0 makes a strike of >10,000 contacts. Its trace filled (4096
    solver states) and the frames after that flew the bodies freely from the last state kept:
    the striker drawn 2.6-27 mm inside the rod, and a frame at each of 1,024 contacts made a
    1.1 s strike a 35 s video. Now the strike is run again with room for its whole trace (the
    same strike: the outcome equals an unfilmed env's bit for bit), no frame shows an overlap,
    and only the first ``MAX_CONTACT_FRAMES`` contacts get frames of their own."""
    from spinstrike.envs.strike import MAX_CONTACT_FRAMES

    env_id = "SpinStrike/RodSpin-v0"
    space = gym.make(env_id).action_space
    space.seed(seed)
    action = space.sample()  # (the walk's strikes: the striker pins the rod)
    env, frames, info = _strike(env_id, seed, action, **kwargs)
    plain = gym.make(env_id, **kwargs)
    plain.reset(seed=seed)
    *_, plain_info = plain.step(action)
    assert info["n_contacts"] > 5000 and info["n_contacts"] == plain_info["n_contacts"]
    np.testing.assert_array_equal(env.unwrapped.world.state.positions,
                                  plain.unwrapped.world.state.positions)
    task = env.unwrapped.task
    clip = task.clip
    assert clip.dropped == 0
    # (the settled steps of a pinned rod leave overlaps of a few tolerances; the bug drew mm)
    assert min(_gap(task, S) for S in clip.states) >= -10 * task.world.tolerance
    grid = math.floor(clip.duration * 30 * clip.slow_motion + 1e-9) + 2
    assert len(frames) <= grid + MAX_CONTACT_FRAMES
    assert len(clip.contacts) > MAX_CONTACT_FRAMES


@pytest.mark.parametrize("env_id", STRIKE_IDS)
def test_strike_frames_lie_on_the_solvers_trajectory(env_id):
    """A World replay of the strike from its launch, chunk by chunk, has the clip's contact
    instants and end state bit for bit, and at every frame instant (stepped to it) its state."""
    env, _, info = _strike(env_id, 7, np.array([0.6, -0.3, 0.4], np.float32))
    task = env.unwrapped.task
    clip = task.clip
    assert info["n_contacts"] >= 1
    start = clip.states[0]

    def launched():
        w = pickle.loads(pickle.dumps(task.world))
        w.set_state(positions=start[None, :, X:Y + 1], angles=start[None, :, ANGLE],
                    velocities=start[None, :, VX:VY + 1], omegas=start[None, :, OMEGA])
        return w

    w = launched()
    chunks = round(clip.duration / CHUNK)
    contact_times = []
    starts = []
    for k in range(chunks):
        starts.append(pickle.loads(pickle.dumps(w)))
        c = w.step(CHUNK)
        contact_times += list(k * CHUNK + c.time)
    np.testing.assert_array_equal(contact_times, clip.contacts[:, fast.TC_TIME])
    end = np.concatenate([w.state.positions[0], w.state.angles[0][:, None],
                          w.state.velocities[0], w.state.omegas[0][:, None]], axis=1)
    np.testing.assert_array_equal(end, clip.states[-1])
    for t, S in zip(clip.times[1:-1:3], clip.states[1:-1:3], strict=True):
        k = min(int(t // CHUNK), chunks - 1)
        ref = pickle.loads(pickle.dumps(starts[k]))
        ref.step(t - k * CHUNK)
        np.testing.assert_allclose(ref.state.positions[0], S[:, X:Y + 1], atol=1e-9)
        np.testing.assert_allclose(ref.state.angles[0], S[:, ANGLE], atol=1e-9)


@pytest.mark.parametrize("env_id", STRIKE_IDS)
@pytest.mark.parametrize("solver", [{"mode": "fixed", "substeps": 8}, {"mode": "pymunk"}])
def test_other_solvers_film_their_own_strike(env_id, solver):
    env, frames, info = _strike(env_id, 2, np.array([0.1, 0.2, 0.5], np.float32),
                                solver=solver)
    clip = env.unwrapped.task.clip
    assert len(frames) >= 30 and len(clip.contacts) == info["n_contacts"] >= 1
    assert set(clip.contacts[:, fast.TC_TIME]) <= set(clip.times)
    end = env.unwrapped.world.state
    np.testing.assert_array_equal(clip.states[-1][:, X:Y + 1], end.positions[0])


# --- determinism, outcome, the other modes ------------------------------------------------------

@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_frames(env_id):
    def run(seed):
        env = gym.make(env_id, render_mode="rgb_array_list")
        env.reset(seed=seed)
        out = env.render()
        for a in _actions(env.action_space, 3, 1):
            *_, term, trunc, _ = env.step(a)
            out += env.render()
            if term or trunc:
                env.reset()
                out += env.render()
        return out

    a, b, c = run(4), run(4), run(5)
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert len(a) != len(c) or any(not np.array_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_outcome_does_not_depend_on_the_render_mode(env_id):
    """The traced strike and the plain one agree bit for bit: observations, rewards, info."""
    runs = []
    for mode in MODES:
        env = gym.make(env_id, render_mode=mode, render_size=(64, 48))
        obs, _ = env.reset(seed=9)
        rows = [obs]
        for a in _actions(env.action_space, 3, 2):
            obs, r, term, trunc, info = env.step(a)
            rows.append((obs, r, term, trunc, info))
            if term or trunc:
                rows.append(env.reset()[0])
        runs.append(rows)
        env.close()
    for rows in runs[1:]:
        for x, y in zip(runs[0], rows, strict=True):
            if isinstance(x, tuple):
                np.testing.assert_array_equal(x[0], y[0])
                assert x[1:4] == y[1:4] and x[4].keys() == y[4].keys()
                for k in x[4]:
                    np.testing.assert_array_equal(x[4][k], y[4][k], err_msg=k)
            else:
                np.testing.assert_array_equal(x, y)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rgb_array_returns_the_last_frame_of_the_list(env_id):
    action = np.full(gym.make(env_id).action_space.shape, 0.3, np.float32)
    single = gym.make(env_id, render_mode="rgb_array")
    listed = gym.make(env_id, render_mode="rgb_array_list")
    for env in (single, listed):
        env.reset(seed=6)
        env.step(action)
    last = listed.render()[-1]
    np.testing.assert_array_equal(single.render(), last)
    np.testing.assert_array_equal(single.render(), last)  # and keeps returning it


@pytest.mark.parametrize("env_id", ["SpinStrike/PuckSpeed-v1", "SpinStrike/RodSpin-v0"])
def test_a_strikes_bodies_stay_in_its_frames(env_id):
    """On the strike envs' unbounded table the view was fixed about the origin, so a fast puck,
    rod or striker ended half out of the picture (6 of 60 random PuckSpeed-v1 strikes). A
    strike's frames now widen the view, one scale for the whole strike, where its bodies go
    beyond it: no body's colour touches the frame's edge, and the rest are drawn as before."""
    env = gym.make(env_id, render_mode="rgb_array_list")
    env.action_space.seed(0)
    colours = [COLOURS[name] for name in env.unwrapped.world.names]
    widened = 0
    for seed in range(30):
        env.reset(seed=seed)
        env.step(env.action_space.sample())
        frames = np.stack(env.render())
        edges = np.concatenate([frames[:, 0], frames[:, -1], frames[:, :, 0], frames[:, :, -1]],
                               axis=1)
        for colour in colours:
            assert not (edges == colour).all(axis=-1).any(), (seed, colour)
        zoom = env.unwrapped.task.frame(0).zoom
        widened += zoom > 1
        assert zoom >= 1
    assert widened >= 1  # (PuckSpeed-v1: seeds 7, 20, 25, 27; RodSpin-v0: 25)


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", "SpinStrike/RodSpinControl-v0"])
def test_human_mode_plays_the_frames_at_the_env_pace(env_id, monkeypatch):
    shown = []
    play = Renderer.show

    def spy(self, image, fps):
        shown.append((image, fps))
        play(self, image, fps)

    monkeypatch.setattr(Renderer, "show", spy)
    env = gym.make(env_id, render_mode="human")
    env.reset(seed=3)
    action = np.full(env.action_space.shape, 0.2, np.float32)
    began = time.perf_counter()
    env.step(action)
    took = time.perf_counter() - began
    assert env.render() is None
    env.close()
    fps = env.metadata["render_fps"]
    assert {f for _, f in shown} == {fps}
    if env_id in STRIKE_IDS:
        want = _strike(env_id, 3, action)[1]
        step_frames = [img for img, _ in shown[1:-1]]  # after the reset's, before render()'s
        assert len(step_frames) == len(want) >= fps
        assert all(np.array_equal(a, b) for a, b in zip(step_frames, want, strict=True))
        assert took >= (len(want) - 1) / fps * 0.9  # played at the slowed pace, not at once
    else:
        assert len(shown) == 3  # reset, step, render


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_no_render_mode_records_nothing(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    task = env.unwrapped.task
    assert not task.record_trace and task._renderer is None
    if env_id in STRIKE_IDS:
        assert task.clip is None and task._strace.events.count.sum() == 0


# --- pixel observations are not the video ------------------------------------------------------

#: sha-256 (first 16 hex) of the default pixel observations, recorded before the video work
#: (reset seed 3, then three steps of ``default_rng(0)`` actions, resets in between), with
#: pygame-ce 2.5.8
PIXELS_BEFORE = {
    "SpinStrike/RodSpin-v0": ["f4f79c2b73e106e3", "6d260f5c5df9b6e3", "3fcfc77c44d12cd0",
                              "0cb717f90611294e", "28c5735a487b2829", "a78193beb74d1734",
                              "07f2c3e8f48c1f81"],
    "SpinStrike/PuckSpeed-v0": ["1e86f669db4a7f60", "6dceb7981d6a2ed3", "7fcfa0a197ea0981",
                                "ea43eb41aec5ac6c", "a81c27ceba0e5dc7", "4c4cc8b41ea8d864",
                                "0c7fb20d51ae5bc7"],
    # v1: v0's task with another action, so the same reset frames, other strikes
    "SpinStrike/PuckSpeed-v1": ["1e86f669db4a7f60", "c4c27f43e31871ce", "7fcfa0a197ea0981",
                                "21d44278e7056581", "a81c27ceba0e5dc7", "e1f22a5d6f837a7c",
                                "0c7fb20d51ae5bc7"],
    "SpinStrike/RodSpinControl-v0": ["7a92fae74dad6456", "7f9a8a8b8aa05f28",
                                     "0aa56224aa5601aa", "3a7a594c36a74efe"],
    "SpinStrike/PuckSpeedControl-v0": ["10c70ab4b5e1e743", "de65b2c55240a94b",
                                       "67396e81ac123baa", "91289de10d585ef6"],
}


def _pixel_run(env_id, **kwargs):
    env = gym.make(env_id, obs_mode="pixels", **kwargs)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    seq = [obs]
    for _ in range(3):
        obs, *_, term, trunc, _ = env.step(
            rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        seq.append(obs)
        if term or trunc:
            seq.append(env.reset()[0])
    return seq


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_pixel_observations_are_unchanged(env_id):
    import pygame

    plain = _pixel_run(env_id)
    assert plain[0].shape == (320, 480, 3)
    # independent of the video's size and of the render mode
    video = _pixel_run(env_id, render_mode="rgb_array_list", render_size=(1280, 720))
    assert all(np.array_equal(a, b) for a, b in zip(plain, video, strict=True))
    small = _pixel_run(env_id, obs_size=(224, 64))
    assert small[0].shape == (64, 224, 3)
    if pygame.version.ver != "2.5.8":
        pytest.skip("the recorded hashes are of pygame-ce 2.5.8's drawing")
    assert [hashlib.sha256(o.tobytes()).hexdigest()[:16] for o in plain] == \
        PIXELS_BEFORE[env_id]


# --- recording -------------------------------------------------------------------------------

def _mp4_frames(path):
    return imageio_ffmpeg.count_frames_and_secs(str(path))[0]


def _decode(path):
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    w, h = meta["size"]
    return [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]


@pytest.mark.parametrize("env_id", STRIKE_IDS)
def test_record_every_frame_writes_whole_strikes(env_id, tmp_path):
    env = gym.make(env_id, render_mode="rgb_array_list", render_size=(320, 215))
    env = RecordEveryFrame(env, str(tmp_path / "v"), episode_trigger=lambda e: True,
                           name_prefix="strike")
    # the same episodes, through a twin env, tell how many frames each has
    twin = gym.make(env_id, render_mode="rgb_array_list", render_size=(320, 215))
    wanted = []
    for seed in (0, 1):
        action = np.array([0.2 * seed, 0.1, 0.3], np.float32)
        env.reset(seed=seed)
        env.step(action)
        twin.reset(seed=seed)
        twin.step(action)
        wanted.append(twin.render())
    env.close()
    files = sorted((tmp_path / "v").glob("*.mp4"))
    assert [f.name for f in files] == ["strike-episode-0.mp4", "strike-episode-1.mp4"]
    for f, frames in zip(files, wanted, strict=True):
        assert len(frames) >= 31  # the reset frame and a second of strike
        assert _mp4_frames(f) == len(frames)
        decoded = _decode(f)
        assert len(decoded) == len(frames)
        # lossy, but the same pictures in the same order (odd height: padded by a row)
        for a, b in zip(decoded, frames, strict=True):
            assert a.shape == (216, 320, 3)
            assert np.abs(a[:215].astype(int) - b).mean() < 4
        from moviepy import VideoFileClip

        clip = VideoFileClip(str(f))
        assert sum(1 for _ in clip.iter_frames()) == len(frames)
        clip.close()


def test_gymnasium_record_video_keeps_one_frame_per_strike(tmp_path):
    """Why the wrapper exists: RecordVideo films a strike as one frame."""
    env = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array_list",
                   render_size=(160, 108))
    env = RecordVideo(env, str(tmp_path / "v"), episode_trigger=lambda e: True)
    env.reset(seed=0)
    env.step(np.zeros(3, np.float32))
    env.close()
    (video,) = (tmp_path / "v").glob("*.mp4")
    assert _mp4_frames(video) <= 2


def test_record_every_frame_cuts_videos_to_length(tmp_path):
    env = gym.make("SpinStrike/RodSpinControl-v0", render_mode="rgb_array_list",
                   render_size=(160, 108))
    env = RecordEveryFrame(env, str(tmp_path / "v"), step_trigger=lambda s: s % 20 == 0,
                           video_length=10)
    env.reset(seed=0)
    for a in _actions(env.action_space, 45, 3):
        env.step(a)
    env.close()
    files = sorted((tmp_path / "v").glob("*.mp4"))
    assert [f.name for f in files] == ["rl-video-step-0.mp4", "rl-video-step-20.mp4",
                                       "rl-video-step-40.mp4"]
    assert [_mp4_frames(f) for f in files] == [10, 10, 5]
    assert env.videos == [str(f) for f in files]


def test_record_every_frame_dropped_without_close_warns_and_leaves_no_partial_video(tmp_path):
    """Wrappers made in a loop and dropped without ``close()`` left ``*.partial.mp4`` files
    behind, silently; Gymnasium's ``RecordVideo`` warns there, and so does this one now."""
    import gc

    env = gym.make("SpinStrike/RodSpinControl-v0", render_mode="rgb_array_list",
                   render_size=(160, 108))
    env = RecordEveryFrame(env, str(tmp_path / "v"), episode_trigger=lambda e: True)
    env.reset(seed=0)
    for a in _actions(env.action_space, 5, 3):
        env.step(a)
    with pytest.warns(UserWarning, match="Did you call close"):
        del env
        gc.collect()
    assert list((tmp_path / "v").iterdir()) == []


def test_record_every_frame_refuses_modes_without_frames(tmp_path):
    with pytest.raises(ValueError, match="render_mode: RecordEveryFrame needs"):
        RecordEveryFrame(gym.make("SpinStrike/RodSpin-v0"), str(tmp_path))
    with pytest.raises(ValueError, match="video path: must end in one of"):
        VideoWriter(tmp_path / "x.avi", 30)


def test_video_writer_keeps_the_users_files(tmp_path):
    """The frames went to a fixed ``NAME.partial.mp4``, which replaced a file of the user's of
    that name, silently; a folder at the video's path was found only at the end, after the
    whole film, leaving the partial file behind. The partial file now has a name of its own,
    the folder is refused at once, and the video gets the user's default permissions."""
    import os
    import stat

    mine = tmp_path / "a.partial.mp4"
    mine.write_text("precious")
    with VideoWriter(tmp_path / "a.mp4", 30) as w:
        for _ in range(3):
            w.write(np.zeros((16, 16, 3), np.uint8))
    assert mine.read_text() == "precious"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4", "a.partial.mp4"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE((tmp_path / "a.mp4").stat().st_mode) == 0o666 & ~umask
    (tmp_path / "d.gif").mkdir()
    with pytest.raises(IsADirectoryError, match=r"is a folder; the video needs a file name"):
        VideoWriter(tmp_path / "d.gif", 30)
    assert list((tmp_path / "d.gif").iterdir()) == []
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4", "a.partial.mp4", "d.gif"]


def test_record_world_films_what_it_is_asked_and_keeps_bodies_in_view(tmp_path):
    """``record_world`` filmed one step of dt where seconds < dt (the CLI refused it) and
    rounded seconds / dt half to even; on a table without cushions, bodies flew out of the view
    fixed from where they started (the striker's pixels went to none). Now: refused, at least
    ``seconds``, and the view widens to keep every body in it."""
    from spinstrike import physics
    from spinstrike.agents.record import record_world

    with pytest.raises(ValueError, match=r"dt: a frame per step of 0.02 s is longer than the "
                                         r"0.001 s to film"):
        record_world(physics.World("rod_spin"), tmp_path / "x.mp4", seconds=0.001)
    assert not list(tmp_path.iterdir())
    world = physics.World("rod_spin")  # unbounded; its striker flies off at 3 m/s
    assert not world.walls
    striker = world.names.index("striker")
    velocities = np.zeros((1, world.n_bodies, 2))
    velocities[0, striker] = [3.0, 0.5]
    world.set_state(velocities=velocities)
    result = record_world(world, tmp_path / "fly.gif", seconds=1.03, size=(240, 160))
    assert result["frames"] == 1 + 52  # ceil(1.03 / 0.02) steps
    from PIL import Image, ImageSequence

    last = np.asarray(list(ImageSequence.Iterator(Image.open(tmp_path / "fly.gif")))[-1]
                      .convert("RGB"))
    assert (last == COLOURS["striker"]).all(axis=2).sum() > 0  # still in the picture
    assert world.state.positions[0, striker, 0] > 3.0


def test_video_writer_and_tile(tmp_path):
    frames = [np.full((9, 15, 3), 40 * k, np.uint8) for k in range(5)]
    with VideoWriter(tmp_path / "a.mp4", 30) as w:
        for f in frames:
            w.write(f)
    # the file's size: H.264 (yuv420p) needs even sizes, the last row and column are repeated
    assert w.frames == 5 and w.size == (16, 10) and _mp4_frames(tmp_path / "a.mp4") == 5
    assert iio.imread(tmp_path / "a.mp4", index=0).shape == (10, 16, 3)
    with VideoWriter(tmp_path / "a.gif", 30) as w:
        for f in frames:
            w.write(f)
    from PIL import Image

    assert Image.open(tmp_path / "a.gif").n_frames == 5 and w.size == (15, 9)
    assert Image.open(tmp_path / "a.gif").size == (15, 9)
    grid = tile([frames[1], None, frames[2]], 2)
    assert grid.shape == (18, 30, 3)
    assert (grid[:9, :15] == 40).all() and (grid[:9, 15:] == 0).all()
    assert (grid[9:, :15] == 80).all() and (grid[9:, 15:] == 0).all()
    w = VideoWriter(tmp_path / "b.mp4", 30)
    w.write(frames[0])
    with pytest.raises(ValueError, match="differs from the video's"):
        w.write(np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(ValueError, match=r"must be \(height, width, 3\) uint8"):
        w.write(np.zeros((9, 15), np.uint8))
    w.close()


def test_impulse_markers_show_the_push_on_the_target():
    n = (0.6, 0.8)  # from body a to body b
    assert (Marker.on(1, 0, 1, (0, 0), n, 0.5).nx, Marker.on(1, 0, 1, (0, 0), n, 0.5).ny) == n
    m = Marker.on(0, 0, 1, (0, 0), n, 0.5)
    assert (m.nx, m.ny) == (-0.6, -0.8)
    m = Marker.on(1, 0, 4, (0.1, 0.2), n, 0.5)  # body 0 against a cushion: the push on body 0
    assert (m.x, m.y, m.nx, m.ny, m.j) == (0.1, 0.2, -0.6, -0.8, 0.5)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_small_video_frames_show_the_table_not_the_panel(env_id):
    """``render_size`` takes 16 to 4096 pixels a side, but the panel's band took >= 44 px: at
    64 x 48 the table was a 4 px strip under the text, and at 16 x 16 the view's scale went
    negative (the table mirrored, the bodies drawn off the frame). A frame whose band would
    take more than half its height shows no panel; the view fills it."""
    for size, panel in [((16, 16), False), ((64, 48), False), ((160, 120), True),
                        ((720, 480), True)]:
        env = gym.make(env_id, render_mode="rgb_array", render_size=size)
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (size[1], size[0], 3)
        task = env.unwrapped.task
        r = task.renderer
        hx, hy = task.view_half()
        assert (r.band > 0) is panel
        assert r.scale == pytest.approx(min(size[0] / (2 * hx), (size[1] - r.band) / (2 * hy)))
        assert r.scale > 0.5 * min(size[0] / (2 * hx), size[1] / (2 * hy))
        for x, y in task.world.state.positions[0]:
            px, py = r._px(x, y)
            assert 0 <= px < size[0] and r.band <= py < size[1]
        env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_a_narrow_video_frame_shrinks_its_text_to_fit(env_id, tmp_path):
    """W17: at ``render_size=(240, 300)`` PuckSpeed's caption was cut mid-word (the target's
    direction, the only place the video states its goal), and a 300 px wide scene film lost its
    contact count. A line wider than the frame is drawn in a smaller font that fits: no text
    reaches the frame's right margin."""
    from spinstrike.envs.rendering import PAD

    env = gym.make(env_id, render_mode="rgb_array", render_size=(240, 300))
    obs, _ = env.reset(seed=0)
    env.step(oracle_for(env_id)(env, obs))
    frame = env.render()
    band = env.unwrapped.task.renderer.band
    assert band > 0
    bright = frame[:band].min(axis=2) > 200  # the text's pixels
    assert bright[:, :-PAD].any() and not bright[:, -PAD:].any()
    env.close()
    if env_id == ENV_IDS[0]:  # a scene film through the command line, 300 px wide
        out = tmp_path / "tall.mp4"
        assert main(["record", "--scene", "break", "--seconds", "0.1", "--size", "300x900",
                     "--out", str(out)]) == 0
        top = _decode(out)[-1][:40].min(axis=2) > 150
        assert top[:, :150].any() and not top[:, -6:].any()


def test_an_impulse_label_at_the_frames_edge_is_drawn_whole():
    """An impulse's label beside a contact at the right cushion, or at a corner, is drawn whole:
    as many of its pixels as beside a contact in the middle of the table (it was cut at the
    frame's edge)."""
    r = Renderer((480, 320), (0.6, 0.4))

    def label_box(x, y, nx, ny):
        """(width, height) of the label's box, as drawn: the pixels of its background colour
        (the most common colour not the table's: the arrow of an impulse this small is 3 px
        long, and the contact's ring is thin)."""
        image = r.draw(Frame([], (math.inf, math.inf), markers=[Marker(x, y, nx, ny, 0.02)]))
        colours, counts = np.unique(image.reshape(-1, 3), axis=0, return_counts=True)
        ranked = [tuple(c) for c in colours[np.argsort(-counts)]]
        box = next(c for c in ranked if c != COLOURS["table"])
        rows, cols = np.nonzero((image == box).all(axis=2))
        return (int(np.ptp(cols)) + 1, int(np.ptp(rows)) + 1)

    whole = label_box(0.0, 0.0, 1.0, 0.0)
    assert whole[0] > 60 and whole[1] > 10
    for x, y, nx, ny in [(0.6, 0.0, 1.0, 0.0), (0.59, -0.4, 0.0, -1.0), (0.6, 0.4, 0.7, 0.7),
                         (-0.6, 0.4, -1.0, 0.0)]:
        assert label_box(x, y, nx, ny) == whole, (x, y)


def test_impulse_labels_do_not_pile_up():
    """Labels that would overlap are drawn once, the strongest's: 50 contacts at one point draw
    the frame one draws (the 50 translucent boxes had piled into one opaque block, and a jam's
    hundreds of contacts in a ``record --scene`` frame into an unreadable heap); labels apart
    are all drawn."""
    r = Renderer((720, 480), (1.0, 0.5))

    def image(markers):
        return r.draw(Frame([], (0.9, 0.4), True, markers=markers, smooth=True))

    one = Marker(0.2, 0.1, 1.0, 0.0, 0.3)
    assert np.array_equal(image([one] * 50), image([one]))
    apart = [one, Marker(-0.5, -0.2, 1.0, 0.0, 0.3)]
    background = (image(apart) != image([one])).any(axis=2).sum()
    assert background > 0.8 * (image([one]) != image([])).any(axis=2).sum()


def test_strike_times_law():
    times, factor = strike_times(0.1, 30, np.array([0.0123, 0.05]))
    assert factor == 10 and times[0] == 0 and times[-1] == 0.1
    assert 0.0123 in times and 0.05 in times
    assert len(times) == 31 + 1  # 31 grid instants (0.05 is one of them), one contact
    times, factor = strike_times(2.0, 30, np.array([]))
    assert factor == 1 and len(times) == 61


def test_cli_records_a_grid_and_a_gif(tmp_path, capsys):
    env_id = "SpinStrike/RodSpin-v0"
    lengths = []
    for k in range(3):
        env = gym.make(env_id, render_mode="rgb_array_list", render_size=(240, 160))
        obs, _ = env.reset(seed=50 + k)
        n = len(env.render())
        env.step(oracle_for(env_id)(env, obs))
        lengths.append(n + len(env.render()))
    video = tmp_path / "grid.mp4"
    assert main(["record", "--oracle", "--env", env_id, "--episodes", "3", "--grid",
                 "--size", "240x160", "--seed", "50", "--out", str(video)]) == 0
    assert "480x320" in capsys.readouterr().out  # 2 x 2 tiles
    assert _mp4_frames(video) == max(lengths) + 15  # the slowest episode, then 0.5 s held
    (first,) = _decode(video)[:1]
    assert first.shape == (320, 480, 3) and first[160:, 240:].mean() < 2  # no 4th episode
    gif = tmp_path / "strikes.gif"
    assert main(["record", "--oracle", "--env", env_id, "--episodes", "3", "--size",
                 "240x160", "--seed", "50", "--out", str(gif)]) == 0
    # one after the other (Pillow merges identical frames into one of the summed duration)
    assert _gif_milliseconds(gif) == round((sum(lengths) + 3 * 15) * 100 / 30) * 10


def test_cli_films_a_physics_scene(tmp_path, capsys):
    """``spinstrike record --scene``: a packaged scene by name (the break, sixteen bodies) or a
    user's YAML, a frame per step played in real time, the contacts it counts those the world's
    own steps resolve."""
    from spinstrike import physics

    gif = tmp_path / "break.gif"
    assert main(["record", "--scene", "break", "--seconds", "0.4", "--size", "320x180",
                 "--out", str(gif)]) == 0
    world = physics.World("break")
    contacts = sum(len(world.step(0.02)) for _ in range(20))
    assert contacts > 0  # the striker reaches the rack at ~0.18 s
    assert f"21 frames at 50 fps, 320x180; {contacts} contacts" in capsys.readouterr().out
    assert _gif_milliseconds(gif) == 21 * 20  # the first frame, then one per 20 ms step
    scene = tmp_path / "two.yaml"
    scene.write_text("bodies:\n"
                     "  - {name: a, shape: disk, radius: 0.05, mass: 1, position: [-0.3, 0],"
                     " velocity: [2, 0]}\n"
                     "  - {name: b, shape: rod, length: 0.3, thickness: 0.02, mass: 1}\n")
    video = tmp_path / "two.mp4"
    assert main(["record", "--scene", str(scene), "--seconds", "0.3", "--dt", "0.01",
                 "--out", str(video)]) == 0
    assert "31 frames at 100 fps, 720x480; 1 contacts" in capsys.readouterr().out
    frames = _decode(video)
    assert len(frames) == 31 and not np.array_equal(frames[0], frames[-1])


def _gif_milliseconds(path):
    from PIL import Image, ImageSequence

    return sum(f.info["duration"] for f in ImageSequence.Iterator(Image.open(path)))


def test_readme_media_command_writes_the_readme_images_and_help_writes_nothing(tmp_path):
    """``python -m spinstrike.agents.record docs/images`` (the README's command) writes exactly
    the images the README and docs/design.md show, the current ids' (no deprecated
    PuckSpeed-v0, no warning); its ``--help`` prints usage instead of writing images into a
    folder named ``--help``."""
    import re
    import subprocess
    import sys
    from pathlib import Path

    root = Path(envs.__file__).resolve().parent.parent
    docs = (root / "README.md").read_text() + (root / "docs" / "design.md").read_text()
    shown = set(re.findall(r"images/((?:rodspin|puckspeed|break)\w*\.(?:png|gif))", docs))
    assert "break.gif" in shown  # docs/design.md's many-body break
    run = [sys.executable, "-W", "error::DeprecationWarning", "-m", "spinstrike.agents.record"]
    out = subprocess.run([*run, "--help"], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.startswith("usage:")
    assert list(tmp_path.iterdir()) == []
    out = subprocess.run([*run, "images"], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]
    assert {p.name for p in (tmp_path / "images").iterdir()} == shown


@pytest.mark.parametrize("env_id", ["SpinStrike/RodSpin-v0", *CONTROL_IDS])
@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copied_env_renders_what_the_original_would(env_id, how):
    """A copy of an env mid-episode (deepcopy; pickle, as SubprocVecEnv and Ray ship envs)
    keeps the video's memory: the frames not yet rendered (``rgb_array_list``), a strike's
    clip, the motion trails and the return on the frame. A copy used to start with none."""
    import copy

    def clone(e):
        return copy.deepcopy(e) if how == "deepcopy" else pickle.loads(pickle.dumps(e))

    steps = 1 if env_id in STRIKE_IDS else 6
    for mode in ("rgb_array_list", "rgb_array"):
        env = gym.make(env_id, render_mode=mode).unwrapped
        env.reset(seed=3)
        actions = [env.action_space.sample() for _ in range(steps + 1)]
        for a in actions[:steps]:
            env.step(a)
        twin = clone(env)
        mine, theirs = env.render(), twin.render()
        if mode == "rgb_array_list":
            assert len(theirs) == len(mine) > steps  # the reset's frame, then the steps'
            mine, theirs = np.stack(mine), np.stack(theirs)
        np.testing.assert_array_equal(theirs, mine)
        if env_id in CONTROL_IDS:  # and the trails go on growing alike
            for e in (env, twin):
                e.step(actions[steps])
            np.testing.assert_array_equal(np.stack(twin.render()) if mode == "rgb_array_list"
                                          else twin.render(),
                                          np.stack(env.render()) if mode == "rgb_array_list"
                                          else env.render())
        env.close()
        twin.close()


def _native_and_sync(env_id, n, mode, max_episode_steps, seed):
    """A native vector env and a SyncVectorEnv of single envs, alike (small rgb_array frames),
    both reset with ``seed``."""
    kw = dict(render_mode="rgb_array", max_episode_steps=max_episode_steps,
              render_size=(240, 160))
    native = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                          autoreset_mode=mode, **kw)
    sync = gym.make_vec(env_id, n, vectorization_mode="sync",
                        vector_kwargs={"autoreset_mode": mode}, **kw)
    for vec in (native, sync):
        vec.reset(seed=seed)
    return native, sync


@pytest.mark.parametrize("env_id", CONTROL_IDS)
@pytest.mark.parametrize("mode", [AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP])
def test_a_native_control_vector_envs_frames_are_the_single_envs(env_id, mode):
    """A native control vector env's ``render()`` is ``SyncVectorEnv``'s of single envs, bit for
    bit, over episodes longer than the motion trail and across autoresets: every element's
    frame has its trail and its return (they were element 0's only, and the native frames had
    neither)."""
    n = 3
    native, sync = _native_and_sync(env_id, n, mode, 25, seed=5)
    chase = oracle_for(env_id)  # chase-and-hit, which hits: the returns are not all zero
    returns = np.zeros(n)
    for _ in range(60):
        a = np.stack([chase(e, None) for e in sync.envs])
        _, reward, *_ = native.step(a)
        sync.step(a)
        returns += reward
        for mine, theirs in zip(native.render(), sync.render(), strict=True):
            np.testing.assert_array_equal(mine, theirs)
    assert returns.any()  # the panels' returns were not all zero
    trails = native.unwrapped.task.frame(n - 1).trails
    assert trails and len(trails[0]) > 1
    native.close()
    sync.close()


def _hit(env, chase, steps=400):
    """Chase-and-hit steps from the env's state until one hits (contacts and a reward): the
    frame after it has impulse markers and a step reward (the test's premise)."""
    for _ in range(steps):
        _, reward, *_, info = env.step(chase(env, None))
        if info["hits"] > 0 and reward != 0:
            frame = env.unwrapped.task.frame(0)
            assert frame.markers and "reward +0.000" not in frame.panel[2]
            return
    raise AssertionError(f"no hit in {steps} steps")


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_a_control_envs_frame_after_a_reset_is_the_new_episodes(env_id):
    """The first frame after ``reset()`` of an episode that ended on a hit drew that hit's
    impulse arrows and its step reward at t = 0 (W18b: ``rgb_array``, the first frame of
    every ``rgb_array_list`` video after the first, ``human``): it is now a fresh env's reset
    frame, bit for bit."""
    kw = dict(render_size=(240, 160), max_episode_steps=-1)
    for mode in ("rgb_array", "rgb_array_list"):
        env, fresh = (gym.make(env_id, render_mode=mode, **kw) for _ in range(2))
        env.reset(seed=1)
        _hit(env, oracle_for(env_id))
        for e in (env, fresh):
            e.reset(seed=5)
        mine, theirs = env.render(), fresh.render()
        if mode == "rgb_array_list":  # (the list holds the first episode's frames too)
            mine, theirs = mine[-1], theirs[-1]
        np.testing.assert_array_equal(mine, theirs)
        env.close()
        fresh.close()


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_a_native_control_vector_env_frames_an_element_reset_alone_as_sync_does(env_id):
    """DISABLED autoreset: an element reset alone (``reset_mask``) after a hit is framed as a
    new episode, as SyncVectorEnv's single env frames it, beside the others' last steps (the
    two differed: both frames were of the old episode's hit before the reset cleared it, and
    SyncVectorEnv's single env kept it after)."""
    n = 2
    native, sync = _native_and_sync(env_id, n, AutoresetMode.DISABLED, -1, seed=3)
    chase = oracle_for(env_id)
    for _ in range(400):
        a = np.stack([chase(e, None) for e in sync.envs])
        _, reward, *_, info = native.step(a)
        sync.step(a)
        hit = (info["hits"] > 0) & (reward != 0)
        if hit.any():
            break
    assert hit.any()
    mask = hit.copy()
    for vec in (native, sync):
        vec.reset(options={"reset_mask": mask})
    for b, (mine, theirs) in enumerate(zip(native.render(), sync.render(), strict=True)):
        np.testing.assert_array_equal(mine, theirs)
        if mask[b]:
            frame = native.unwrapped.task.frame(b)
            assert not frame.markers and frame.panel[2].startswith("reward +0.000 (step)")
    native.close()
    sync.close()


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_a_control_envs_hit_is_framed_alike_in_a_copy_and_a_state_put_back(env_id):
    """A state taken just after a hit carries the hit's frame (its impulse arrows and step
    reward): a pickled copy renders what the env does, and an env given the state frames the
    same arrows and panel (its trail starts at the state: see above); a copy drew neither. The
    next reset clears them in each."""
    env = gym.make(env_id, render_mode="rgb_array").unwrapped
    env.reset(seed=1)
    _hit(env, oracle_for(env_id))
    twin = pickle.loads(pickle.dumps(env))
    other = gym.make(env_id, render_mode="rgb_array").unwrapped
    other.reset(seed=2)
    other.step(other.action_space.sample())
    other.set_physics_state(env.get_physics_state())
    np.testing.assert_array_equal(twin.render(), env.render())
    mine, theirs = env.task.frame(0), other.task.frame(0)
    assert theirs.markers == mine.markers and theirs.panel == mine.panel
    fresh = gym.make(env_id, render_mode="rgb_array").unwrapped
    for e in (env, twin, other, fresh):
        e.reset(seed=5)
    for e in (env, twin, other):
        np.testing.assert_array_equal(e.render(), fresh.render())


def test_a_native_vector_envs_frame_says_the_strike_is_done():
    """The native vector env films no strike clip; an element's frame after its strike (NEXT_STEP
    keeps the struck state until the next step) said "before the strike" and "reward: after
    the last contact" beside the spin already gained. It now says after, with the reward."""
    vec = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, render_mode="rgb_array",
                       vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    before = vec.unwrapped.task.frame(1).panel
    assert "before the strike" in before[0] and before[2] == "reward: after the last contact"
    _, reward, *_ = vec.step(np.tile(vec.single_action_space.sample(), (2, 1)))
    after = vec.unwrapped.task.frame(1).panel
    assert "after the strike" in after[0] and after[2] == f"reward {reward[1]:.3f}"
    assert len(vec.render()) == 2
    vec.step(np.zeros((2, 3), np.float32))  # NEXT_STEP: the reset step
    assert "before the strike" in vec.unwrapped.task.frame(1).panel[0]
    vec.close()


def test_a_state_put_back_is_framed_as_it_was():
    """A state from before the strike, put back after one, is framed "before the strike"
    (and one from after it, after), not as the env's last step left the caption."""
    env = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array").unwrapped
    env.reset(seed=0)
    before = env.get_physics_state()
    _, reward, *_ = env.step(env.action_space.sample())
    after = env.get_physics_state()
    env.set_physics_state(before)
    assert "before the strike" in env.task.frame(0).panel[0]
    env.set_physics_state(after)
    panel = env.task.frame(0).panel
    assert "after the strike" in panel[0] and panel[2] == f"reward {reward:.3f}"


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_a_control_state_put_back_is_framed_as_the_source_env_frames_it(env_id):
    """A control env given another's state kept its own motion trail: the next frame joined
    its old poses to the new ones with streaks across the table, and its panel showed its own
    return. The trail now starts at the restored pose, and the panel has the source's return;
    stepped alike after that, the two frames agree (the trail as far back as the restore)."""
    a, b = (gym.make(env_id, render_mode="rgb_array") for _ in range(2))
    for env, seed in ((a, 1), (b, 2)):
        env.reset(seed=seed)
        for action in _actions(env.action_space, 30, seed):
            env.step(action)
    b.unwrapped.set_physics_state(a.unwrapped.get_physics_state())
    for k, action in enumerate(_actions(a.action_space, 6, 9)):
        fa, fb = a.unwrapped.task.frame(0), b.unwrapped.task.frame(0)
        assert fb.panel == fa.panel
        assert fb.trails == [trail[-(k + 1):] for trail in fa.trails]
        for env in (a, b):
            env.step(action)
    assert np.array_equal(a.unwrapped.task.world.state.positions,
                          b.unwrapped.task.world.state.positions)


def test_a_fast_gif_keeps_frames_viewers_play_in_real_time(tmp_path, capsys):
    """``record --scene ... --dt 0.002`` wrote GIF frames of 0 and 10 ms, which viewers play as
    100 ms (10x slow). A GIF above 50 fps keeps every k-th frame: each lasts 20 ms or more and
    the whole lasts the scene's time; an mp4 keeps every frame."""
    from PIL import Image

    gif = tmp_path / "fast.gif"
    assert main(["record", "--scene", "break", "--seconds", "0.2", "--dt", "0.002", "--size",
                 "160x90", "--out", str(gif)]) == 0
    assert "101 frames at 500 fps" in capsys.readouterr().out
    with Image.open(gif) as im:
        durations = []
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info["duration"])
    assert min(durations) >= 20 and sum(durations) == 220  # 101 frames of 2 ms, 10 per kept frame
    assert _gif_milliseconds(gif) == 220
    for fps in (30, 50, 60, 144):
        with VideoWriter(tmp_path / f"{fps}.gif", fps) as w:
            for k in range(fps):  # one second, every frame different
                w.write(np.full((4, 4, 3), k, np.uint8))
        with Image.open(tmp_path / f"{fps}.gif") as im:
            got = []
            for k in range(im.n_frames):
                im.seek(k)
                got.append(im.info["duration"])
        assert min(got) >= 20 and abs(sum(got) - 1000) <= 20, (fps, got)


def test_a_fast_gif_ends_on_the_last_frame_and_says_what_it_keeps(tmp_path, capsys):
    """W17: a GIF above 50 fps kept frames 0, k, 2k, ... only, so where the last frame was not
    one of them the film stopped short of the final state (``--dt 0.003``: its last frame read
    t = 2.98 s of 3 s), and the command's line counted frames the file does not have. The
    last frame is kept now (in the place of the kept one before it when the two would be
    under 20 ms apart), and the line says how many the GIF keeps."""
    from PIL import Image, ImageSequence

    gif, mp4 = tmp_path / "scene.gif", tmp_path / "scene.mp4"
    said = {}
    for out in (gif, mp4):
        assert main(["record", "--scene", "break", "--seconds", "0.3", "--dt", "0.003",
                     "--size", "160x90", "--out", str(out)]) == 0
        said[out] = capsys.readouterr().out
    # (101 frames at 333 fps: every 7th, 0..98, then 100 in the place of 98)
    with Image.open(gif) as im:
        kept = [np.asarray(f.convert("RGB"), dtype=float) for f in ImageSequence.Iterator(im)]
        ms = [f.info["duration"] for f in ImageSequence.Iterator(im)]
    assert "101 frames at 333.333 fps; the GIF keeps 15 of them" in said[gif], said[gif]
    assert "101 frames at 333.333 fps" in said[mp4] and "keeps" not in said[mp4]
    assert len(kept) == 15 and min(ms) >= 20 and abs(sum(ms) - 300) <= 20, ms
    films = _decode(mp4)
    assert len(films) == 101
    # the GIF's last frame is the final state's (closer to the mp4's last frame than to any
    # other of its frames: the header's clock, the bodies moved)
    off = [np.abs(kept[-1] - f.astype(float)).mean() for f in films]
    assert int(np.argmin(off)) == 100, off[-10:]
    for fps, n in ((144, 144), (60, 61), (333.3, 101), (51, 3), (200, 2)):
        path = tmp_path / f"{fps}-{n}.gif"
        with VideoWriter(path, fps) as w:
            for k in range(n):  # every frame different
                w.write(np.full((4, 4, 3), k, np.uint8))
        with Image.open(path) as im:
            last = np.asarray(list(ImageSequence.Iterator(im))[-1].convert("RGB"))
            got = [f.info["duration"] for f in ImageSequence.Iterator(im)]
        assert last[0, 0, 0] == n - 1 and w.kept == len(got), (fps, n)
        # (two frames 5 ms apart: each shown 20 ms, the least viewers play)
        lasts = max(1000 * n / fps, 20 * len(got))
        assert min(got) >= 20 and abs(sum(got) - lasts) <= 20, (fps, n, got)


def test_a_gif_holds_its_frames_as_the_gif_does(tmp_path):
    """A GIF's frames were held as RGB arrays until the end (every one, those a fast GIF drops
    too): a 4-episode control grid took 3.1 GB, its mp4 0.4 GB. They are held now as Pillow's
    GIF writer converts them (a palette, a byte a pixel), and only those kept: the file is the
    same, byte for byte, and the Python-side memory is no longer the frames'."""
    import tracemalloc

    from PIL import Image

    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 255, (240, 360, 3), dtype=np.uint8) for _ in range(12)]
    path = tmp_path / "w.gif"
    tracemalloc.start()
    try:
        with VideoWriter(path, 30) as w:
            for f in frames:
                w.write(f)
            held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert held < frames[0].nbytes  # 12 RGB frames were 3.1 MB
    pillow = tmp_path / "pillow.gif"
    ends = np.round(np.arange(len(frames) + 1) * 100 / 30) * 10
    images = [Image.fromarray(f) for f in frames]
    images[0].save(pillow, save_all=True, append_images=images[1:], loop=0,
                   duration=np.diff(ends).astype(int).tolist(), optimize=True)
    assert path.read_bytes() == pillow.read_bytes()


@pytest.mark.parametrize("env_id", CONTROL_IDS)
def test_a_body_resting_on_a_cushion_is_drawn_against_it_not_sunk_in(env_id):
    """A video frame's cushions lie outside the cloth, whose edge is the wall: a target put
    touching the right cushion (``set_physics_state``) is drawn up to the cushion's inner edge,
    at most a pixel of rounding into it (the cushions were drawn 5 px inside the cloth, and a
    body at rest against one seemed sunk 5-6 px into it). Pixel observations keep their
    pixels: there the cushions stay inside the cloth's rectangle."""
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    u = env.unwrapped
    w = u.task.world
    hw = float(w.table_half_size[0, 0])
    target, mallet = u.task.it, u.task.im
    reach = float(w.radius[0, target] + w.half_length[0, target])
    state = u.get_physics_state()
    s = state["world"]["state"].copy()
    # a rod along x, its cap at the wall; a puck's spin mark turned away from the row measured
    angle = 0.0 if w.half_length[0, target] > 0 else math.pi / 2
    s[0, target, [X, Y, ANGLE]] = (hw - reach, 0.1, angle)
    s[0, mallet, [X, Y]] = (-hw / 2, 0.0)
    state["world"]["state"] = s
    u.set_physics_state(state)
    frame = env.render()
    cushion = np.all(frame == COLOURS["cushion"], axis=-1)
    body = np.all(frame == COLOURS[u.task.TARGET], axis=-1)
    ren = u.task.renderer
    _, row = ren._px(hw, 0.1)
    _, empty = ren._px(0.0, -0.1)
    half = ren.width // 2
    inner = np.flatnonzero(cushion[empty, half:])[0] + half
    assert np.flatnonzero(body[row])[-1] <= inner  # at most the rounding pixel
    assert np.flatnonzero(cushion[empty, inner:]).size == 5  # the cushion's width, whole
    env.close()
    env = gym.make(env_id, obs_mode="pixels")
    obs, _ = env.reset(seed=0)
    env.close()
    row = obs[obs.shape[0] // 2]
    cloth = np.flatnonzero(np.any(row != COLOURS["cloth_edge"], axis=-1))
    cushion = np.flatnonzero(np.all(row == COLOURS["cushion"], axis=-1))
    assert cushion.size == 10 and cushion[0] == cloth[0] and cushion[-1] == cloth[-1]


def _pixels_of(image: np.ndarray, colour, tol: int = 8) -> int:
    return int(np.all(np.abs(image.astype(int) - np.array(colour)) <= tol, axis=-1).sum())


def test_impulse_labels_keep_the_striker_in_sight():
    """At 360 x 240 a strike's impulse label covered the striker whole in some frames (walk
    W22b: 9 frames of 40 strikes showed no striker pixel): labels keep clear of the disks."""
    env = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array_list", render_size=(360, 240))
    env.action_space.seed(0)
    hidden = []
    for episode in range(11):
        env.reset(seed=100 + episode)
        env.render()
        env.step(env.action_space.sample())
        for k, image in enumerate(env.render()):
            if not (_pixels_of(image, COLOURS["rod"]) and _pixels_of(image, COLOURS["striker"])):
                hidden.append((episode, k))
    assert not hidden


def test_a_mallet_at_rest_on_the_cushions_gets_no_impulse_markers():
    """A mallet pushed into a corner rests on two cushions: their impulses (1e-7 N s) were drawn
    as markers labelled "j = 0.000 N s" every step; an impulse too small to draw is not. Nor
    is the cushions' push while they hold it, recorded since walk W24a F1 (``held``, 0.05 N s
    a step): the video marks impacts."""
    env = gym.make("SpinStrike/PuckSpeedControl-v0", render_mode="rgb_array")
    env.reset(seed=0)
    for _ in range(150):
        env.step(np.array([-1.0, -1.0], dtype=np.float32))
    held = env.unwrapped.world.last_contacts.held
    assert held.sum() == 2  # the two cushions' pushes, recorded
    assert env.unwrapped.world.last_contacts.impulse[held].min() > 1e-2
    frame = env.unwrapped.task.frame(0)
    assert frame.markers and max(m.j for m in frame.markers) < 1e-4  # resting contacts
    bare = env.unwrapped.task.draw(dataclasses.replace(frame, markers=[]))
    np.testing.assert_array_equal(env.render(), bare)


def test_a_native_vector_env_names_the_route_to_the_other_render_modes():
    """The native vector env renders ``rgb_array`` only: its refusal of the list mode names
    ``vectorization_mode='sync'``, which takes it (walk W22b), and that route films."""
    with pytest.raises(envs.ConfigError, match="vectorization_mode='sync'"):
        gym.make_vec("SpinStrike/RodSpinControl-v0", 2, render_mode="rgb_array_list")
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", 2, vectorization_mode="sync",
                       render_mode="rgb_array_list")
    vec.reset(seed=0)
    vec.step(np.zeros((2, 2), dtype=np.float32))
    frames = vec.render()
    assert len(frames) == 2 and all(len(f) == 2 for f in frames)  # the reset's and the step's
    vec.close()
