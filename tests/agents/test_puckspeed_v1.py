"""``SpinStrike/PuckSpeed-v1`` (the strike's velocity as a vector) through ``gym.make``: the
checkers, determinism, the oracle, bad actions, and the reason it exists (v0's heading angle
wraps at +-pi, where the best action jumps from one end of the box to the other)."""

import math
import subprocess
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from spinstrike import envs
from spinstrike.agents.evaluate import run_episodes
from spinstrike.agents.oracle import oracle_for

V1 = "SpinStrike/PuckSpeed-v1"
V0 = "SpinStrike/PuckSpeed-v0"


def test_v1_is_registered_beside_v0_and_v0_points_to_it():
    assert V1 in envs.ENV_IDS and V0 in envs.ENV_IDS
    with pytest.warns(DeprecationWarning, match="v1"):
        gym.make(V0).close()
    env = gym.make(V1)
    assert env.action_space == gym.spaces.Box(-1, 1, (3,), np.float32)
    assert env.unwrapped.task.ACTIONS == ("offset", "velocity_x", "velocity_y")
    assert "velocity_x" in type(env.unwrapped).__doc__ and "v1" in type(env.unwrapped).__doc__
    env.close()


def test_v1_passes_gymnasium_and_sb3_checkers():
    env = gym.make(V1)
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(gym.make(V1))
    vec = gym.make_vec(V1, num_envs=8)
    obs, _ = vec.reset(seed=3)
    obs2, r, term, trunc, _ = vec.step(vec.action_space.sample())
    assert obs2.shape == (8, 5) and r.shape == (8,) and term.all()
    vec.close()


def _rollout(seed, actions):
    env = gym.make(V1)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, r, term, trunc, info = env.step(a)
        out += [obs, r, info["velocity"], info["spin"]]
        obs, _ = env.reset()
        out.append(obs)
    env.close()
    return out


def test_v1_is_deterministic_given_the_seed():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (6, 3)).astype(np.float32)
    a, b = _rollout(7, actions), _rollout(7, actions)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    c = _rollout(8, actions)
    assert not np.array_equal(a[0], c[0])


def test_v1_oracle_reaches_the_reward_everywhere():
    ev = run_episodes(oracle_for(V1), V1, 40, seed=1000)
    assert ev.mean >= 0.99 and min(ev.returns) >= 0.95, ev.returns


def test_v1_action_is_the_striker_velocity():
    """The striker leaves along (a1, a2) at speed_range[1] * |(a1, a2)|, clipped into range."""
    env = gym.make(V1, friction=0.0)
    for heading in (math.pi - 0.01, -math.pi + 0.01, 0.3):
        obs, _ = env.reset(seed=1)
        task = env.unwrapped.task
        lo, hi = task.cfg.speed_range
        speed = 2.0
        a = np.array([0.0, math.cos(heading) * speed / hi, math.sin(heading) * speed / hi],
                     np.float32)
        _, _, _, _, info = env.step(a)
        gain = info["analytic_speed_gain"]
        v = info["velocity"]
        assert math.hypot(*v) == pytest.approx(gain * speed, rel=1e-4)
        assert math.atan2(v[1], v[0]) == pytest.approx(heading, abs=1e-4)
    # a zero vector strikes along +x at the slowest speed; a long one at the fastest
    for vel, speed in (((0.0, 0.0), lo), ((1.0, 1.0), hi)):
        env.reset(seed=2)
        _, _, _, _, info = env.step(np.array([0.0, *vel], np.float32))
        assert math.hypot(*info["velocity"]) == pytest.approx(gain * speed, rel=1e-4)
    env.close()


@pytest.mark.parametrize("bad, match", [
    (np.array([0.0, np.nan, 0.2], np.float32), "NaN|finite"),
    (np.array([0.0, 0.2], np.float32), "shape"),
    (np.array(["a", "b", "c"]), "number|numeric|dtype"),
])
def test_v1_bad_actions_raise_a_clear_error(bad, match):
    env = gym.make(V1, disable_env_checker=True)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.unwrapped.step(bad)
    env.close()


def test_v0_heading_wraps_where_v1_is_continuous():
    """The cause v1 fixes: for targets on either side of the -x axis, v0's best actions sit at
    opposite ends of the heading box, v1's are neighbours."""
    actions = {}
    for env_id in (V0, V1):
        env = gym.make(env_id)
        oracle = oracle_for(env_id)
        out = []
        for sign in (1, -1):
            env.reset(seed=4)
            task = env.unwrapped.task
            speed = math.hypot(*task.goal[0])
            heading = sign * (math.pi - 0.02)
            task.goal[0] = speed * math.cos(heading), speed * math.sin(heading)
            a = oracle(env, None)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, r, *_ = env.step(a)
            assert r > 0.99
            out.append(a)
        actions[env_id] = np.abs(out[0] - out[1]).max()
        env.close()
    assert actions[V0] > 1.9 and actions[V1] < 0.05, actions


def test_the_cli_says_v0_is_out_of_date_once_in_plain_text(tmp_path):
    """``spinstrike train --env SpinStrike/PuckSpeed-v0`` printed Gymnasium's deprecation four
    times, in terminal colour codes (its "once" filter forgets whenever a library changes the
    warning filters). Through the console script, as a user runs it: once, plain."""
    out = subprocess.run(["spinstrike", "train", "--algo", "ppo", "--env", V0, "--timesteps",
                          "256", "--n-envs", "2", "--eval-episodes", "2", "--no-progress",
                          "--out", str(tmp_path / "run")],
                         capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stderr.count("PuckSpeed-v0 is out of date") == 1, out.stderr
    assert "\x1b[" not in out.stderr and "warning: The environment" in out.stderr
    assert (tmp_path / "run" / "rollout.mp4").is_file()
