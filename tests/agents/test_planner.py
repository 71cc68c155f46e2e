"""The CEM planner (agents/planner.py) through gym.make and the CLI: it beats the scripted
chase-and-hit on a fixed set of short episodes, it is deterministic given its seed, its what-if
model is the env itself, and bad settings fail with the field named."""

import json

import gymnasium as gym
import imageio_ffmpeg
import numpy as np
import pytest

from spinstrike.agents.cli import main
from spinstrike.agents.evaluate import run_episodes
from spinstrike.agents.oracle import ChaseAndHit
from spinstrike.agents.planner import CEMPlanner

CONTROL = ["SpinStrike/RodSpinControl-v0", "SpinStrike/PuckSpeedControl-v0"]
SHORT = {"max_episode_steps": 60}


@pytest.mark.parametrize("env_id", CONTROL)
def test_planner_beats_chase_and_hit_on_fixed_short_episodes(env_id):
    planner = run_episodes(CEMPlanner(horizon=15, samples=32, elites=4), env_id, 3, 1000, SHORT)
    chase = run_episodes(ChaseAndHit(), env_id, 3, 1000, SHORT)
    print(env_id, planner.returns, chase.returns)
    assert planner.mean >= 2.0 * chase.mean and planner.mean >= chase.mean + 0.5, \
        (planner.returns, chase.returns)


def _actions(env_id, seed, planner):
    env = gym.make(env_id, max_episode_steps=15)
    obs, _ = env.reset(seed=seed)
    out, done = [], False
    while not done:
        a = planner(env, obs)
        out.append(a)
        obs, r, term, trunc, _ = env.step(a)
        done = term or trunc
    env.close()
    return np.array(out)


def test_planner_is_deterministic_and_reseeds_per_episode():
    env_id = CONTROL[1]
    planner = CEMPlanner(horizon=8, samples=16, elites=3, seed=5)
    a = _actions(env_id, 3, planner)
    b = _actions(env_id, 3, planner)  # same object, next episode: reseeded at the clock's 0
    c = _actions(env_id, 3, CEMPlanner(horizon=8, samples=16, elites=3, seed=5))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)
    d = _actions(env_id, 3, CEMPlanner(horizon=8, samples=16, elites=3, seed=6))
    assert not np.array_equal(a, d)


@pytest.mark.parametrize("env_id", CONTROL)
def test_planner_what_if_copy_predicts_the_env(env_id):
    """Element k of the scratch batch, stepped with the same actions as the env, returns the
    env's rewards exactly: the planner's model is the env's own world."""
    env = gym.make(env_id)
    obs, _ = env.reset(seed=11)
    planner = CEMPlanner(horizon=4, samples=4, elites=2, seed=0)
    for _ in range(30):  # get the bodies moving
        obs, *_ = env.step(ChaseAndHit()(env, obs))
    task = env.unwrapped.task
    scratch = planner._scratch_for(task)
    scratch.world.load_element(task.world, 0)
    rng = np.random.default_rng(0)
    seq = rng.uniform(-1, 1, (40, 2))
    for a in seq:
        predicted = scratch.step(np.repeat(a[None], 4, 0), batch_info=False)[0]
        obs, reward, *_ = env.step(a.astype(np.float32))
        assert np.all(predicted == predicted[0])
        assert predicted[0] == pytest.approx(reward, abs=1e-9)
        np.testing.assert_allclose(scratch.observe()[0], obs, atol=1e-5)


@pytest.mark.parametrize("kwargs, match", [
    ({"horizon": 0}, "horizon: must be an integer >= 1"),
    ({"samples": 1}, "samples: must be an integer >= 2"),
    ({"samples": 8, "elites": 9}, "elites: must be <= samples"),
    ({"init_std": 0.0}, "init_std: must be > 0"),
    ({"gamma": 1.5}, r"gamma: must be in \(0, 1\]"),
])
def test_planner_bad_settings(kwargs, match):
    with pytest.raises(ValueError, match=match):
        CEMPlanner(**kwargs)


def test_planner_refuses_a_strike_env():
    env = gym.make("SpinStrike/RodSpin-v0")
    obs, _ = env.reset(seed=0)
    with pytest.raises(TypeError, match="control envs"):
        CEMPlanner()(env, obs)


def test_cli_record_planner(tmp_path, capsys):
    video = tmp_path / "planner.mp4"
    assert main(["record", "--planner", "--env", "SpinStrike/PuckSpeedControl-v0", "--out",
                 str(video), "--episodes", "1", "--size", "240x160"]) == 0
    frames, _ = imageio_ffmpeg.count_frames_and_secs(str(video))
    assert frames == 251 + 25
    assert main(["record", "--planner", "--env", "SpinStrike/RodSpin-v0", "--out",
                 str(tmp_path / "x.mp4")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: --planner: drives the control envs only")
    assert main(["record", "--planner"]) == 2
    assert "--planner: needs --env" in capsys.readouterr().err


@pytest.mark.parametrize("warm_start", [True, False])
def test_planner_without_warm_start_acts_on_the_state_alone(warm_start):
    """warm_start=False: the decision at a state is the same whatever the planner decided
    before (given the same draws), as a reactive policy's is; the default carries its last plan
    over, so there it differs."""
    env = gym.make(CONTROL[0])
    obs, _ = env.reset(seed=4)
    used = CEMPlanner(horizon=6, samples=16, elites=3, seed=3, warm_start=warm_start)
    for _ in range(15):
        obs, *_ = env.step(used(env, obs))
    task = env.unwrapped.task
    used.rng = np.random.default_rng(3)  # the same draws as a fresh planner's
    a = used.plan(task)
    b = CEMPlanner(horizon=6, samples=16, elites=3, seed=3, warm_start=warm_start).plan(task)
    assert np.array_equal(a, b) == (not warm_start)
    env.close()


@pytest.mark.parametrize("common_noise", [True, False])
def test_common_noise_makes_the_reactive_planner_a_function_of_the_state(common_noise):
    """warm_start=False, common_noise=True: every decision draws the same samples, so the
    action at a state is one value, whatever the planner did before and however often it is
    asked (no reseeding by hand); with fresh noise two decisions at one state differ."""
    kw = dict(horizon=6, samples=16, elites=3, seed=5, warm_start=False,
              common_noise=common_noise)
    env = gym.make(CONTROL[0])
    obs, _ = env.reset(seed=4)
    used = CEMPlanner(**kw)
    for _ in range(15):
        obs, *_ = env.step(used(env, obs))
    first, again = used(env, obs), used(env, obs)
    fresh = CEMPlanner(**kw)(env, obs)
    assert np.array_equal(first, again) == common_noise
    assert np.array_equal(first, fresh) == common_noise
    # and the state's action is not the same constant everywhere
    obs, *_ = env.step(first)
    assert not np.array_equal(used(env, obs), first)
    env.close()


def test_warm_start_table_rows():
    """``python -m spinstrike.agents.planner --warm-start-table``'s rows (tiny searches)."""
    from spinstrike.agents.planner import warm_start_table

    text = warm_start_table(CONTROL[1], episodes=1, settings=((True, 4, 1, 2, False),
                                                              (False, 4, 1, 2, True)))
    rows = [r for r in text.splitlines() if r.startswith("| | ")]
    assert [r.split("|")[2].strip() for r in rows] == ["yes", "no"]
    assert [r.split("|")[3].strip() for r in rows] == ["fresh", "common"]
    for r in rows:
        assert r.split("|")[4].strip() == "4 x 1"
        assert np.isfinite(float(r.split("|")[5].split("+/-")[0]))


def test_cli_evaluate_planner_reports_its_hits(capsys, tmp_path):
    """``spinstrike evaluate --planner --env ID`` (the planner module's own example) scores the
    planner beside random and chase-and-hit, and for a control env says what the hits gained
    and lost; a one-strike env's report has no such columns."""
    assert main(["evaluate", "--planner", "--env", CONTROL[1], "--episodes", "1"]) == 0
    table = capsys.readouterr().out
    assert main(["evaluate", "--planner", "--env", CONTROL[1], "--episodes", "1",
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)  # the JSON alone
    assert list(report) == ["planner", "random", "oracle"]
    assert "| planner |" in table and "gained by hits / ep." in table
    assert "| oracle (chase-and-hit) |" in table  # as the README and baselines call it
    for row in report.values():  # rewards are paid in steps with a hit only
        hits = row["hits"]
        assert hits["gained"] + hits["lost"] == pytest.approx(row["mean"], abs=1e-9)
        assert hits["gained"] >= 0 >= hits["lost"]
    assert report["planner"]["hits"]["hit_steps"] >= 10
    assert report["planner"]["mean"] > 2 * report["oracle"]["mean"]
    assert main(["evaluate", "--oracle", "--env", "SpinStrike/RodSpin-v0", "--episodes", "2",
                 "--json"]) == 0
    assert "hits" not in json.loads(capsys.readouterr().out)["oracle"]
    assert main(["evaluate", "--oracle", "--env", "SpinStrike/RodSpin-v0", "--episodes", "2"]) == 0
    text = capsys.readouterr().out
    assert "gained by hits" not in text and "| oracle | 1.0000 |" in text
    assert main(["evaluate", "--planner", "--env", "SpinStrike/RodSpin-v0"]) == 2
    assert "--planner: drives the control envs only" in capsys.readouterr().err


def test_planner_module_writes_its_part_and_keeps_the_notes(tmp_path, capsys):
    """``python -m spinstrike.agents.planner --out FILE`` replaces the generated part and
    keeps the notes written by hand (it rewrote docs/planner.md whole: 95 lines to 20, the
    warm-start study gone); without ``--out`` it prints only; bad options are one line."""
    from spinstrike.agents.baselines import END
    from spinstrike.agents.planner import BEGIN
    from spinstrike.agents.planner import main as planner_main

    doc = tmp_path / "planner.md"
    tiny = ["--episodes", "1", "--steps", "5", "--horizons", "2", "--samples", "4",
            "--envs", CONTROL[1]]
    assert planner_main(tiny) == 0 and not doc.exists()
    assert planner_main([*tiny, "--out", str(doc)]) == 0
    doc.write_text("Intro by hand.\n\n" + doc.read_text() + "\n## Notes (by hand)\n\nKept.\n")
    assert planner_main([*tiny, "--out", str(doc)]) == 0
    text = doc.read_text()
    assert text.startswith("Intro by hand.\n\n" + BEGIN)
    assert text.endswith(END + "\n\n## Notes (by hand)\n\nKept.\n")
    assert text.count("| horizon \\ samples |") == 1
    # the report names the command that ran (it named the defaults' always)
    assert f"`python -m spinstrike.agents.planner {' '.join(tiny)} --out {doc}`" in text
    assert f"wrote {doc}" in capsys.readouterr().err
    # the shipped document has the markers, so a rerun keeps its warm-start study
    from pathlib import Path

    shipped = (Path(__file__).parents[2] / "docs" / "planner.md").read_text()
    assert shipped.count(BEGIN) == shipped.count(END) == 1
    assert shipped.index(END) < shipped.index("## Warm start")
    for bad, words in ((["--samples", "1"], "--samples: must be >= 2"),
                       (["--steps", "0"], "--steps: must be >= 1"),
                       (["--envs", "SpinStrike/RodSpin-v0"], "drives the control envs only")):
        with pytest.raises(SystemExit):
            planner_main(bad)
        assert words in capsys.readouterr().err


def test_planner_refuses_a_vector_env():
    """It planned element 0 alone and handed back one action for the whole batch."""
    vec = gym.make_vec(CONTROL[0], num_envs=2)
    obs, _ = vec.reset(seed=0)
    with pytest.raises(TypeError, match="not a vector env"):
        CEMPlanner(samples=4, elites=2)(vec, obs)
