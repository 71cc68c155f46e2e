"""Ray RLlib, from the user's side: ``spinstrike.envs.rllib`` and ``spinstrike train --backend
rllib`` (marker ``rllib``: run with ``pytest -m rllib`` in a venv with the ``rllib`` extra; Ray
pins its own gymnasium). Iterations are tiny: the point is the plumbing (runner processes, data
integrity, fault tolerance, a cluster of two nodes, Tune), not learning.
"""

from __future__ import annotations

import functools
import json
import os
import pickle
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

ray = pytest.importorskip("ray")

from ray.rllib.algorithms.ppo import PPOConfig  # noqa: E402
from ray.rllib.callbacks.callbacks import RLlibCallback  # noqa: E402

import spinstrike  # noqa: E402, F401  (registers the ids)
from spinstrike.envs import ConfigError  # noqa: E402
from spinstrike.envs.rllib import (  # noqa: E402
    check_config,
    configure,
    make_env,
    register_envs,
    resolve,
)

pytestmark = pytest.mark.rllib

STRIKE, CONTROL = "SpinStrike/RodSpin-v0", "SpinStrike/RodSpinControl-v0"


@pytest.fixture
def local_ray():
    """A local Ray of 2 CPUs (the machine's), shut down after the test."""
    if ray.is_initialized():
        ray.shutdown()
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        yield
    finally:
        ray.shutdown()


def tiny(config, runners: int = 2, envs: int = 4, fragment: int = 16):
    """A PPO config small enough for a 2-core machine."""
    return (config.env_runners(num_env_runners=runners, num_envs_per_env_runner=envs,
                               rollout_fragment_length=fragment)
            .training(train_batch_size_per_learner=runners * envs * fragment or envs * fragment,
                      minibatch_size=32, num_epochs=1)
            .rl_module(model_config={"fcnet_hiddens": [16]}))


def _sampled(result: dict) -> int:
    return int(result["env_runners"]["num_env_steps_sampled_lifetime"])


@pytest.mark.parametrize("env_id", [STRIKE, CONTROL])
def test_ppo_trains_two_iterations_with_two_env_runners(local_ray, env_id):
    config = tiny(configure(PPOConfig(), env_id, {"max_episode_steps": 20}
                            if env_id == CONTROL else {}))
    assert config.gym_env_vectorize_mode == "vector_entry_point"
    algo = config.build_algo()
    try:
        r1 = algo.train()
        r2 = algo.train()
        assert _sampled(r2) > _sampled(r1) > 0
        assert np.isfinite(r2["env_runners"]["episode_return_mean"])
        # each runner holds one native vector env (one batched world) in NEXT_STEP mode
        modes = algo.env_runner_group.foreach_env_runner(
            lambda r: (type(r.env.unwrapped).__name__, r.env.unwrapped.num_envs,
                       r.env.unwrapped.metadata["autoreset_mode"].name), local_env_runner=False)
        assert len(modes) == 2
        assert all(m[1] == 4 and m[2] == "NEXT_STEP" and m[0].endswith("VectorEnv")
                   for m in modes)
    finally:
        algo.stop()


def test_seeded_runners_draw_different_tasks(local_ray):
    """With a seed (``spinstrike train --backend rllib`` always sets one) RLlib resets runner
    ``w`` with ``seed + w`` and a vector env seeds element ``i`` with ``seed + i``: runner 1's
    element ``i + 1`` drew runner 2's element ``i``'s tasks, 3 of 4 streams twice in each batch.
    Now no task is drawn by both runners."""
    config = tiny(configure(PPOConfig(), STRIKE)).debugging(seed=0)
    algo = config.build_algo()
    try:
        tasks = algo.env_runner_group.foreach_env_runner(
            lambda r: [e.get_observations(0).tobytes() for e in r.sample(num_timesteps=32)],
            local_env_runner=False)
    finally:
        algo.stop()
    first, second = (set(t) for t in tasks)
    assert len(first) >= 12 and len(second) >= 12
    assert not first & second


def test_bad_env_config_raises_in_the_driver_before_runners_start():
    assert not ray.is_initialized()
    with pytest.raises(ConfigError, match="no_such_key"):
        configure(PPOConfig(), STRIKE, {"no_such_key": 1})
    with pytest.raises(ConfigError, match="restitution"):
        configure(PPOConfig(), STRIKE, {"restitution": 7.0})
    # what only a built env refuses (was an IndexError in the driver after the runners died,
    # or a minute's wait for samples that never came, the reason in the runners' logs)
    from spinstrike.envs.config import load_packaged_scene

    scene = load_packaged_scene("rod_control")
    post = dict(scene["bodies"][0], name="post", position=[0.5, 0.3])
    pinned = [dict(b, pivot=True) if b["name"] == "rod" else b for b in scene["bodies"]]
    for bad, words in ((dict(scene, bodies=[*scene["bodies"], post]), "are not this env's"),
                       (dict(scene, bodies=pinned), "'rod' is pivot")):
        for vectorize in (True, False):
            with pytest.raises(ConfigError, match=words):
                configure(PPOConfig(), CONTROL, {"scene": bad}, vectorize=vectorize)
    with pytest.raises(ConfigError, match=r"env: unknown id 'SpinStrike/Nope-v0'; allowed: "
                                          r"\['SpinStrike/RodSpin-v0'"):
        configure(PPOConfig(), "SpinStrike/Nope-v0")
    # RLlib replaces num_envs with num_envs_per_env_runner: given alone it was ignored
    with pytest.raises(ConfigError, match=r"env_config\['num_envs'\].*num_envs_per_env_runner"):
        configure(PPOConfig(), CONTROL, {"num_envs": 4})
    assert not ray.is_initialized()  # nothing started


def test_the_evaluation_runners_env_config_is_checked_in_the_driver(local_ray):
    """An ``env_config`` set by ``.evaluation(evaluation_config=...)`` (RLlib merges it over the
    main one for the evaluation runners) was checked nowhere: a bad key failed in the
    evaluation runners, and ``build_algo()`` raised ``IndexError: list index out of range``.
    ``check_config`` (and ``configure``, for an evaluation set before it) raise the env's
    ``ConfigError`` in the driver, naming ``evaluation_config``; a good override reaches the
    evaluation runners' worlds, merged over the main env_config."""
    def evaluating(config, env_config):
        return config.evaluation(evaluation_interval=1, evaluation_num_env_runners=1,
                                 evaluation_duration=2, evaluation_config=PPOConfig.overrides(
                                     env_config=env_config))

    bad = evaluating(tiny(configure(PPOConfig(), STRIKE, {"restitution": 0.5}), runners=1),
                     {"restitutoin": 0.9})
    with pytest.raises(ConfigError, match=r"^evaluation_config: restitutoin: unknown argument"):
        check_config(bad)
    with pytest.raises(ConfigError, match=r"^evaluation_config: restitution: .*less than or"):
        configure(evaluating(PPOConfig(), {"restitution": 1.5}), STRIKE)
    with pytest.raises(ConfigError, match=r"^evaluation_config: env_config\['render_mode'\]"):
        check_config(PPOConfig().environment(STRIKE).evaluation(
            evaluation_config={"env_config": {"render_mode": "human"}}).env_runners(
                gym_env_vectorize_mode="vector_entry_point"))
    with pytest.raises(ConfigError, match=r"^env_config: restitution"):
        check_config(PPOConfig().environment(STRIKE, env_config={"restitution": -1}))
    # the prefixed id RLlib makes itself (gym.make imports the package): checked, not refused
    check_config(configure(PPOConfig(), STRIKE).evaluation(
        evaluation_config={"env": "spinstrike:" + STRIKE}))
    with pytest.raises(ConfigError, match=r"^evaluation_config: restitutoin: unknown argument"):
        check_config(configure(PPOConfig(), STRIKE).evaluation(evaluation_config={
            "env": "spinstrike:" + STRIKE, "env_config": {"restitutoin": 0.5}}))
    check_config(PPOConfig().environment("CartPole-v1"))  # not ours: left to RLlib

    good = evaluating(tiny(configure(PPOConfig(), STRIKE, {"restitution": 0.5,
                                                            "striker_mass": 0.25}),
                           runners=1, envs=2, fragment=16), {"restitution": 0.9})
    check_config(good)
    algo = good.build_algo()
    try:
        def worlds(group):
            return group.foreach_env_runner(
                lambda r: (r.env.unwrapped.world.restitution("rod", "striker").tolist(),
                           r.env.unwrapped.cfg.striker_mass),
                local_env_runner=False)

        assert worlds(algo.env_runner_group) == [([0.5, 0.5], 0.25)]
        assert worlds(algo.eval_env_runner_group) == [([0.9, 0.9], 0.25)]
        assert "evaluation" in algo.train()
    finally:
        algo.stop()


def test_check_config_checks_what_the_runners_will_make(tmp_path, monkeypatch, user_module):
    """Found by a walk of RLlib from a user's side; each passed ``check_config`` (or was refused
    by it wrongly) and then failed in the runners with RLlib's ``IndexError``, or not at all:

    * the ``spinstrike:`` id in a plain ``config.environment(...)`` (documented; RLlib makes it
      with ``gym.make``) was refused, and the message hid the typo in its env_config; its
      ``autoreset_mode`` other than NEXT_STEP lost data silently;
    * a scene file named by a relative path outside ``configure``'s env_config stayed a path,
      which runners in another folder could not open;
    * an evaluation env with other spaces (``obs_mode: dict``, another env) than the module
      trained on;
    * a variant registered with ``kwargs={"config": {...}}`` was refused (``config``: unknown);
    * ``num_envs_per_env_runner=2.7`` was silently 2."""
    from spinstrike.envs.config import load_packaged_scene

    prefixed = "spinstrike:" + STRIKE
    check_config(PPOConfig().environment(prefixed, env_config={"restitution": 0.5}))
    with pytest.raises(ConfigError, match=r"^env_config: restitutoin: unknown argument"):
        check_config(PPOConfig().environment(prefixed, env_config={"restitutoin": 0.5}))
    with pytest.raises(ConfigError, match=r"^env_config: autoreset_mode 'same_step': RLlib's "
                                          r"runners assume NEXT_STEP"):
        check_config(PPOConfig().environment(prefixed, env_config={"autoreset_mode": "same_step"})
                     .env_runners(gym_env_vectorize_mode="vector_entry_point"))
    check_config(PPOConfig().environment(prefixed, env_config={"autoreset_mode": "next_step"})
                 .env_runners(gym_env_vectorize_mode="vector_entry_point"))
    # configure says it alike (it said "autoreset_mode: unknown argument", next_step too)
    with pytest.raises(ConfigError, match=r"^env_config: autoreset_mode 'same_step': RLlib's "
                                          r"runners assume NEXT_STEP"):
        configure(PPOConfig(), STRIKE, {"autoreset_mode": "same_step"})
    assert configure(PPOConfig(), STRIKE, {"autoreset_mode": "next_step"}).env_config == {}

    scene = load_packaged_scene("rod_control")
    scene["bodies"] = [dict(b, length=0.25) if b["name"] == "rod" else b for b in scene["bodies"]]
    monkeypatch.chdir(tmp_path)
    Path("s.yaml").write_text(yaml.safe_dump(scene))
    plain = PPOConfig().environment(CONTROL, env_config={"scene": "s.yaml"})
    evaluated = configure(PPOConfig(), CONTROL).evaluation(
        evaluation_config={"env_config": {"scene": "s.yaml"}})
    for config in (plain, evaluated):
        check_config(config)
    assert plain.env_config["scene"] == scene
    assert evaluated.evaluation_config["env_config"]["scene"] == scene
    assert pickle.loads(pickle.dumps(evaluated)).get_evaluation_config_object() \
        .env_config["scene"] == scene

    for override, seen in (({"env_config": {"obs_mode": "dict"}}, "Dict"),
                           ({"env": "SpinStrike/PuckSpeed-v1"}, "Box")):
        with pytest.raises(ConfigError, match=rf"^evaluation_config: its env's spaces "
                                              rf"\(observations {seen}.*are not the training "
                                              rf"env's"):
            check_config(configure(PPOConfig(), STRIKE).evaluation(evaluation_config=override))
    # another library's env is left to RLlib: no spaces to compare the evaluation env's with
    check_config(PPOConfig().environment("CartPole-v1").evaluation(
        evaluation_config={"env": STRIKE}))

    user_module("spinstrike_rllib_config_lab", (
        "import gymnasium as gym\n"
        "gym.register('ConfigLab/Rod-v0', entry_point='spinstrike.envs.strike:RodSpinEnv',"
        " kwargs={'config': {'restitution': 0.3}}, max_episode_steps=1)\n"))
    config = configure(PPOConfig(), "spinstrike_rllib_config_lab:ConfigLab/Rod-v0")
    assert config.env_config == {"restitution": 0.3, "max_episode_steps": 1}
    # an env_config that is not a dict: "dictionary update sequence element #0 has length 9"
    with pytest.raises(ConfigError, match=r"^env_config: must be a mapping.*got list"):
        configure(PPOConfig(), CONTROL, ["max_force", 8.0])
    # a Tune search space in configure's env_config: "max_force: Input should be a valid
    # number (got {'grid_search': [...]})"; then refused whole ("set it after configure"), and
    # check_config refused one set after configure with that same advice (W18a). Each value a
    # grid_search or a choice gives, and a range's ends, are checked now, at any depth; a space
    # with none to check is refused, saying where it can go
    from ray import tune

    for space in (tune.grid_search([4.0, 8.0]), tune.uniform(4.0, 8.0), tune.choice([4, 8]),
                  tune.randint(1, 9)):
        config = configure(PPOConfig(), CONTROL, {"max_force": space})
        assert config.env_config == {"max_force": space}
        check_config(config)
    for space, words in (
            ({"max_force": tune.grid_search([4.0, -8.0])},
             r"\['max_force'\] = -8.0 \(a value of its tune.grid_search\): max_force: Input "
             r"should be greater than 0"),
            ({"restitution": tune.uniform(0.5, 1.2)},
             r"\['restitution'\] = 1.2 \(an end of its range\): restitution: Input should be "
             r"less than or equal to 1"),
            ({"randomize": {"restitution": tune.grid_search([[0.1, 0.5], [0.5, 1.9]])}},
             r"\['randomize'\]\['restitution'\] = \[0.5, 1.9\] \(a value of its "
             r"tune.grid_search\): randomize: restitution: must lie in \[0, 1\]"),
            ({"max_force": tune.sample_from(lambda _: 4.0)},
             r"\['max_force'\]: a Tune search space \(Function\) with no values to check in "
             r"the driver.*set it after them")):
        with pytest.raises(ConfigError, match="^env_config" + words):
            configure(PPOConfig(), CONTROL, space)
        with pytest.raises(ConfigError, match="^env_config: env_config" + words):
            check_config(configure(PPOConfig(), CONTROL).environment(env_config=space))
    for bad in (2.7, True, "8", 0):
        with pytest.raises(ConfigError, match=r"^num_envs_per_env_runner: must be an int >= 1"):
            configure(PPOConfig(), STRIKE, num_envs_per_env_runner=bad)


def test_configure_holds_the_scene_a_path_names_not_the_path(tmp_path, monkeypatch):
    """A scene given as a file path is read by ``configure``: RLlib's env_config (the runners,
    a checkpoint) held the path, which a restore from another folder could not open (an
    IndexError in the driver) and a later edit of the file changed under a continued run."""
    from spinstrike.envs.config import load_packaged_scene

    scene = load_packaged_scene("rod_control")
    scene["bodies"] = [dict(b, length=0.25) if b["name"] == "rod" else b for b in scene["bodies"]]
    monkeypatch.chdir(tmp_path)
    Path("s.yaml").write_text(yaml.safe_dump(scene))
    config = configure(PPOConfig(), CONTROL, {"scene": "s.yaml"})
    Path("s.yaml").write_text(yaml.safe_dump(load_packaged_scene("rod_control")))  # an edit
    monkeypatch.chdir(tmp_path.parent)
    held = pickle.loads(pickle.dumps(config)).env_config  # as a runner or a checkpoint gets it
    assert held["scene"] == scene
    env = make_env(CONTROL, dict(held, num_envs=2))  # RLlib's creator, in another folder
    w = env.unwrapped.world if hasattr(env, "unwrapped") else env.world
    assert w.half_length[0, w.index("rod")] == pytest.approx(0.125)


def test_creator_returns_a_single_env_or_the_native_vector_env():
    register_envs()
    single = make_env(CONTROL, {"max_force": 5.0})
    assert isinstance(single, gym.Env) and single.unwrapped.cfg.max_force == 5.0
    vec = make_env(CONTROL, {"max_force": 5.0, "num_envs": 3})
    assert vec.num_envs == 3 and vec.cfg.max_force == 5.0
    assert vec.metadata["autoreset_mode"] is gym.vector.AutoresetMode.NEXT_STEP
    assert vec.max_episode_steps == 250
    # a runner's elements are seeded seed * num_envs + i, so runners seeded 0 and 1 (RLlib's
    # seed + worker index) share no task stream
    tasks = [set(map(bytes, vec.reset(seed=s)[0])) for s in (0, 1)]
    assert len(tasks[0]) == len(tasks[1]) == 3 and not tasks[0] & tasks[1]
    # max_episode_steps as gym.make reads it: None the registered 250 (was int(None), a
    # TypeError in every runner, after check_env_config had passed it), -1 no limit
    for limit, steps in ((None, 250), (-1, None), (7, 7)):
        cfg = {"max_episode_steps": limit}
        configure(PPOConfig(), CONTROL, cfg)  # checked in the driver: accepted
        assert make_env(CONTROL, cfg | {"num_envs": 2}).max_episode_steps == steps
        single = make_env(CONTROL, cfg)
        assert single.spec.max_episode_steps == (steps if limit != -1 else None)
    with pytest.raises(ConfigError, match=r"env_config\['max_episode_steps'\]: must be an int"):
        configure(PPOConfig(), CONTROL, {"max_episode_steps": 2.5})


def _counting_creator(env_id):
    """A creator whose vector env counts, per element, the env steps (not NEXT_STEP's reset
    steps) and rewards it produced (defined in a function: Ray pickles it by value)."""

    class Counting(gym.vector.VectorWrapper):
        def __init__(self, env):
            super().__init__(env)
            self.steps = 0
            self.reward = 0.0
            self.episodes_done = 0
            self._pending = np.zeros(env.num_envs, bool)

        def reset(self, **kwargs):
            self._pending[:] = False
            return self.env.reset(**kwargs)

        def step(self, actions):
            obs, r, term, trunc, info = self.env.step(actions)
            next_step = self.env.metadata["autoreset_mode"] is gym.vector.AutoresetMode.NEXT_STEP
            real = ~self._pending if next_step else np.ones_like(term)
            self.steps += int(real.sum())
            self.reward += float(r[real].sum())
            self.episodes_done += int((term | trunc)[real].sum())
            self._pending = term | trunc
            return obs, r, term, trunc, info

    def create(cfg):
        from spinstrike.envs.rllib import make_env as make

        return Counting(make(env_id, cfg))

    return create


@pytest.mark.parametrize("random_actions", [True, False], ids=["random", "module"])
@pytest.mark.parametrize("env_id", [STRIKE, CONTROL])
def test_every_env_step_and_reward_reaches_rllibs_episodes(env_id, random_actions):
    """Sampled by an env runner (random actions, or the module's): the steps and rewards in
    RLlib's episodes are exactly those the env produced, and control episodes have their full
    length. (One kind of action per runner: switching ``random_actions`` between calls with
    episodes under way fails RLlib's own episode check, on CartPole-v1 too.)"""
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner
    from ray.tune.registry import register_env

    name = f"counting-{env_id}"
    register_env(name, _counting_creator(env_id))
    limit = 7
    config = (PPOConfig().environment(name, env_config={"max_episode_steps": limit}
                                      if env_id == CONTROL else {})
              .env_runners(num_envs_per_env_runner=5, gym_env_vectorize_mode="vector_entry_point"))
    runner = SingleAgentEnvRunner(config=config)
    try:
        counter = runner.env.env
        steps, reward, lengths = 0, 0.0, []
        for _ in range(3):
            for ep in runner.sample(num_timesteps=60, random_actions=random_actions):
                steps += len(ep)
                reward += float(ep.get_return())
                if ep.is_done:
                    lengths.append(len(ep))
        assert steps == counter.steps >= 180
        assert reward == pytest.approx(counter.reward, rel=1e-9, abs=1e-12)
        if env_id == STRIKE:
            assert set(lengths) == {1} and len(lengths) == counter.episodes_done
        else:
            assert lengths and all(n <= limit for n in lengths)
            assert limit in lengths  # a truncated episode keeps its first step
    finally:
        runner.stop()


def test_training_on_a_simulated_two_node_cluster():
    from ray.cluster_utils import Cluster

    if ray.is_initialized():
        ray.shutdown()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1,
                                                            "include_dashboard": False})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        ray.init(address=cluster.address, log_to_driver=False)
        assert len([n for n in ray.nodes() if n["Alive"]]) == 2
        algo = tiny(configure(PPOConfig(), STRIKE)).build_algo()
        try:
            result = algo.train()
            assert _sampled(result) > 0
            nodes = algo.env_runner_group.foreach_env_runner(
                lambda r: ray.get_runtime_context().get_node_id(), local_env_runner=False)
            assert len(set(nodes)) == 2  # one runner on each node (1 CPU each)
        finally:
            algo.stop()
    finally:
        ray.shutdown()
        cluster.shutdown()


def test_a_killed_env_runner_is_replaced_and_training_goes_on(local_ray):
    config = tiny(configure(PPOConfig(), STRIKE)).fault_tolerance(
        restart_failed_env_runners=True)
    algo = config.build_algo()
    try:
        before = _sampled(algo.train())
        group = algo.env_runner_group
        victim = group.healthy_env_runner_ids()[0]
        group.foreach_env_runner(lambda r: os._exit(1), remote_worker_ids=[victim],
                                 local_env_runner=False)
        # training goes on with one runner while Ray restarts the other; a new runner process
        # imports Ray, RLlib and torch first, which took over 2 min on a loaded 2-core machine
        # (the CI once failed when this loop gave up after 4 iterations, a few seconds)
        after, deadline = before, time.monotonic() + 600
        while time.monotonic() < deadline:
            after = _sampled(algo.train())
            if group.num_remote_worker_restarts() >= 1 and \
                    group.num_healthy_remote_env_runners() == 2:
                break
            time.sleep(1.0)
        assert group.num_remote_worker_restarts() >= 1
        assert group.num_healthy_remote_env_runners() == 2
        assert after > before
        # the replacement samples: a further iteration uses both runners
        steps = group.foreach_env_runner(lambda r: r.env.unwrapped.num_envs,
                                         local_env_runner=False)
        assert steps == [4, 4]
        assert _sampled(algo.train()) > after
    finally:
        algo.stop()


# importing RLlib's algorithm registry builds DreamerV3's debug CartPole, which warns
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_tune_sweep_over_two_seeds(local_ray, tmp_path):
    from ray import tune

    config = tiny(configure(PPOConfig(), STRIKE), runners=1)
    config = config.debugging(seed=tune.grid_search([0, 1]))
    tuner = tune.Tuner("PPO", param_space=config,
                       run_config=tune.RunConfig(stop={"training_iteration": 1},
                                                 storage_path=str(tmp_path), verbose=0))
    results = tuner.fit()
    assert len(results) == 2 and not results.errors
    seeds = sorted(r.config["seed"] for r in results)
    assert seeds == [0, 1]
    for r in results:
        assert r.metrics["env_runners"]["num_env_steps_sampled_lifetime"] > 0


class _TrialEnv(RLlibCallback):
    """Puts what the runner's env really has (not the config's echo) in each result."""

    def on_train_result(self, *, algorithm, result, **kwargs):
        def env_of(runner):
            world = runner.env.unwrapped.world
            return (float(world.restitution("rod", "striker")[0]),
                    float(world.mass[0, world.index("striker")]))

        seen = algorithm.env_runner_group.foreach_env_runner(env_of, local_env_runner=False)
        result["seen_restitution"], result["seen_striker_mass"] = seen[0]


# importing RLlib's algorithm registry builds DreamerV3's debug CartPole, which warns
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_tune_sweep_of_env_arguments_runs_each_trial_on_its_own_env(local_ray, tmp_path,
                                                                         rllib_lab, capsys):
    """W18a: ``configure`` merged its env_config into the one the config held (RLlib's
    ``environment()`` deep-merges), so a config configured for one variant and then for another
    env kept the first one's arguments: a sweep loop ran DeadRod with HeavyRod's rod, silently.
    And a search space in configure's env_config was refused ("set it after configure"). Now a
    grid in configure's env_config is checked value by value and each trial's runners make the
    env of exactly ``gym.make(id, **env_config)``, nothing left from the config's past."""
    from ray import tune

    variant = f"{LAB}:RLlibLab/BouncyRod-v0"  # restitution 0.95, 3-step episodes
    again = configure(configure(PPOConfig(), variant), STRIKE, {"striker_mass": 0.25})
    assert again.env_config == {"striker_mass": 0.25}  # (was the variant's arguments too)
    env = make_env(again.env, again.env_config)
    assert env.unwrapped.world.restitution("rod", "striker")[0] == \
        gym.make(STRIKE).unwrapped.world.restitution("rod", "striker")[0] != 0.95
    base = configure(PPOConfig(), variant)
    assert base.env_config == {"restitution": 0.95, "max_episode_steps": 3}
    config = configure(base, STRIKE, {"striker_mass": tune.grid_search([0.25, 0.5])})
    assert config.env_config == {"striker_mass": {"grid_search": [0.25, 0.5]}}
    config = tiny(config, runners=1, envs=2, fragment=16).callbacks(_TrialEnv)
    tuner = tune.Tuner("PPO", param_space=config,
                       run_config=tune.RunConfig(
                           stop={"training_iteration": 1}, storage_path=str(tmp_path),
                           verbose=0, checkpoint_config=tune.CheckpointConfig(
                               checkpoint_at_end=True)))
    results = tuner.fit()
    assert len(results) == 2 and not results.errors
    # each trial's folder is scored by `spinstrike evaluate` on its own env (it was "not a
    # run": W18a), as its RLModule scores there
    from ray.rllib.core.rl_module.rl_module import RLModule

    from spinstrike.agents.cli import main
    from spinstrike.agents.evaluate import evaluate
    from spinstrike.agents.rllib_train import module_policy

    for r in results:
        mass = r.config["env_config"]["striker_mass"]
        capsys.readouterr()  # (Tune's tables)
        assert main(["evaluate", r.path, "--episodes", "3", "--json", "--no-save"]) == 0
        scores = json.loads(capsys.readouterr().out)
        module = RLModule.from_checkpoint(str(Path(r.checkpoint.path) / "learner_group" /
                                              "learner" / "rl_module" / "default_policy"))
        mine = evaluate(STRIKE, module_policy(module), 3, 1000, {"striker_mass": mass},
                        baselines=False)[0].mean
        assert scores["agent"]["mean"] == pytest.approx(mine, abs=1e-12)
    plain = gym.make(STRIKE).unwrapped
    default_e = float(plain.world.restitution("rod", "striker")[0])
    assert default_e != 0.95
    seen = sorted((r.metrics["seen_striker_mass"], r.metrics["seen_restitution"])
                  for r in results)
    assert seen == [(0.25, default_e), (0.5, default_e)]


def test_rllib_learning_curves_of_every_seed_score_the_same_episodes(local_ray, tmp_path,
                                                                      monkeypatch):
    """The learning curve's evaluations run on the SB3 backend's fixed episodes (EVAL_SEED), so
    the curves of seeds 0..4 score one set of tasks, as the baselines' IQM curves need; the
    RLlib backend's ran on ``seed + 10,000``'s (W17), other tasks for every seed."""
    import spinstrike.agents.evaluate as evaluate
    from spinstrike.agents.rllib_train import train_rllib
    from spinstrike.agents.train import EVAL_SEED

    seen, real = [], evaluate.run_episodes

    def watched(policy, env_id, episodes, seed=1000, env_kwargs=None, name="policy"):
        seen.append(seed)
        return real(policy, env_id, episodes, seed, env_kwargs, name)

    monkeypatch.setattr(evaluate, "run_episodes", watched)
    for seed in (0, 3):
        train_rllib(STRIKE, seed=seed, timesteps=64, n_envs=4, num_env_runners=0,
                    out=tmp_path / f"s{seed}", evaluate=False, video=False,
                    eval_every=1, eval_episodes_during=2)
    assert len(seen) >= 2 and set(seen) == {EVAL_SEED}, seen


def test_cli_train_backend_rllib_writes_the_run_folder(tmp_path):
    """... with a scene given as a path relative to the working folder: config.yml holds the
    scene itself (it held the path: evaluate from another folder failed), as SB3's does."""
    from spinstrike.envs.config import load_packaged_scene

    out = tmp_path / "run"
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    scene = load_packaged_scene("rod_spin")
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(scene))
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", STRIKE, "--num-env-runners", "2", "--timesteps", "256", "--n-envs", "4",
           "--eval-episodes", "5", "--out", str(out), "--env-kwargs", "{scene: s.yaml}"]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900,
                          cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    entry = yaml.safe_load((out / "config.yml").read_text())["hyperparameters"][STRIKE]
    assert entry["env_kwargs"]["scene"] == scene
    (tmp_path / "s.yaml").unlink()
    assert done.returncode == 0, done.stderr[-3000:]
    for name in ("config.yml", "command.txt", "progress.csv", "evaluations.npz",
                 "learning_curve.png", "summary.md", "summary.json", "rollout.mp4"):
        assert (out / name).is_file(), name
    assert (out / "checkpoint").is_dir() and any((out / "checkpoint").iterdir())
    summary = (out / "summary.md").read_text()
    for policy in ("agent", "random", "oracle"):
        assert f"| {policy} |" in summary
    assert "agent:" in done.stdout and "oracle:" in done.stdout
    assert not Path(str(out) + ".partial").exists()
    # the run folder evaluates like an SB3 run's: the checkpoint's module gives the summary's
    # agent return on the same episodes
    evaluated = subprocess.run([sys.executable, "-m", "spinstrike.agents.cli", "evaluate",
                                str(out), "--episodes", "5", "--no-save"],
                               capture_output=True, text=True, env=env, timeout=300,
                               cwd=tmp_path.parent)
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    import json

    agent = next(r for r in json.loads((out / "summary.json").read_text())
                 if r["policy"] == "agent")
    assert f"{agent['mean']:.4f}" in evaluated.stdout


@pytest.mark.parametrize("kwargs,key", [("{no_such_key: 1}", "no_such_key"),
                                        ("{num_envs: 3}", "num_envs"),  # was: after Ray
                                        ("{max_episode_steps: 0}", "max_episode_steps"),
                                        # W17: a control env's episodes then never end, and
                                        # the run hung in its first evaluation
                                        ("{max_episode_steps: -1}", "max_episode_steps")])
def test_cli_backend_rllib_bad_input_exits_2_before_writing(tmp_path, kwargs, key):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", "SpinStrike/RodSpinControl-v0", "--env-kwargs", kwargs, "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and key in done.stderr and "Traceback" not in done.stderr
    assert "Started a local Ray" not in done.stderr
    assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_cli_backend_rllib_starts_its_own_ray_beside_a_running_cluster(tmp_path):
    """Without --address the CLI starts a local Ray, as documented: Ray's default joined any
    cluster on the machine (another job's) and died with an IndexError when it went away. Also
    PuckSpeed-v1's packaged entry, whose lin_ learning rate crashed the translation."""
    from ray.cluster_utils import Cluster

    if ray.is_initialized():
        ray.shutdown()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1,
                                                            "include_dashboard": False})
    try:
        out = tmp_path / "run"
        env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy",
                   MPLBACKEND="Agg")
        cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
               "--env", "SpinStrike/PuckSpeed-v1", "--num-env-runners", "1", "--timesteps",
               "256", "--n-envs", "4", "--eval-episodes", "2", "--no-video", "--out", str(out)]
        done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
        assert done.returncode == 0, done.stderr[-3000:]
        assert "Connecting to existing Ray cluster" not in done.stderr
        assert "does not use policy_kwargs.log_std_init" in done.stderr
        assert (out / "summary.md").is_file()
    finally:
        cluster.shutdown()


def test_cli_backend_rllib_address_auto_without_a_cluster_is_one_error_line(
        tmp_path, monkeypatch, capsys):
    """docs/rllib.md's ``--address auto`` with no Ray running ended in Ray's ConnectionError
    traceback, exit 1; it is one error line saying how to start a cluster, exit 2, and no run
    folder. Ray's "auto" joins any Ray running on the machine (another test's, in a parallel
    run), so its lookup is shown none: Ray's own ``ray.init`` then raises as on a machine
    without one."""
    from ray._private import services

    from spinstrike.agents.cli import main

    if ray.is_initialized():
        ray.shutdown()
    monkeypatch.setattr(services, "find_gcs_addresses", functools.lru_cache(lambda: []))
    monkeypatch.setattr(services, "find_bootstrap_address", lambda temp_dir: None)
    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--backend", "rllib", "--env", STRIKE, "--address", "auto",
                 "--timesteps", "256", "--no-video", "--out", "run"]) == 2
    err = capsys.readouterr().err
    [line] = [x for x in err.splitlines() if x.startswith("error:")]
    assert "--address auto: no Ray cluster to join" in line and "ray start --head" in line
    assert "Could not find any running Ray instance" in line  # Ray's own words, from ray.init
    assert "Traceback" not in err and not ray.is_initialized()
    assert not (tmp_path / "run").exists() and not (tmp_path / "run.partial").exists()


def test_cli_backend_rllib_address_where_nothing_answers_is_refused_at_once(
        tmp_path, monkeypatch, capsys):
    """``--address HOST:PORT`` where nothing listens (a typo, a head node not yet up) waited
    ~14 minutes in ``ray.init``, a Ray warning every ~35 s, before its error (RLlib walk W10):
    refused within seconds, one error line, no run folder, no Ray started."""
    import socket
    import time

    from spinstrike.agents.cli import main

    if ray.is_initialized():
        ray.shutdown()
    with socket.socket() as s:  # a port nothing listens on once closed
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    monkeypatch.chdir(tmp_path)
    start = time.monotonic()
    for address in (f"127.0.0.1:{port}", f"ray://127.0.0.1:{port}"):
        assert main(["train", "--backend", "rllib", "--env", STRIKE, "--address", address,
                     "--timesteps", "256", "--no-video", "--out", "run"]) == 2
        err = capsys.readouterr().err
        [line] = [x for x in err.splitlines() if x.startswith("error:")]
        assert f"--address {address}: no Ray cluster to join: nothing answers at " \
               f"127.0.0.1:{port}" in line and "ray start --head" in line
        assert "Traceback" not in err and not ray.is_initialized()
    assert time.monotonic() - start < 60
    assert not (tmp_path / "run").exists() and not (tmp_path / "run.partial").exists()


def test_cli_backend_rllib_refuses_more_runners_than_the_cluster_has_cpus(tmp_path):
    """Was a silent wait without end after "Started a local Ray instance" (Ray places one
    runner per CPU), and no run folder."""
    from ray.cluster_utils import Cluster

    if ray.is_initialized():
        ray.shutdown()
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1,
                                                            "include_dashboard": False})
    try:
        cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
               "--env", STRIKE, "--address", cluster.address, "--num-env-runners", "2",
               "--n-envs", "4", "--timesteps", "256", "--no-video", "--out",
               str(tmp_path / "run")]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                              env=dict(os.environ, SDL_VIDEODRIVER="dummy",
                                       SDL_AUDIODRIVER="dummy"))
        assert done.returncode == 2, done.stderr[-3000:]
        assert ("num_env_runners: 2 env runners need 2 CPUs, and the Ray cluster has 1"
                in done.stderr)
        assert not (tmp_path / "run").exists()
    finally:
        cluster.shutdown()


def _render_after_sampling(runner):
    """In a runner: sample a few steps, then the frames of its env's ``render()``."""
    runner.sample(num_timesteps=4, random_actions=True)
    return runner.env.unwrapped.render()


def test_render_mode_in_env_config_renders_in_a_runner(local_ray):
    """RLlib's creator gets env_config alone, and RLlib's video callbacks put render_mode
    there: a runner's env renders (was: ``ConfigError render_mode: unknown argument``)."""
    config = tiny(configure(PPOConfig(), STRIKE, {"render_mode": "rgb_array"}), runners=1,
                  envs=2)
    algo = config.build_algo()
    try:
        (frames,) = algo.env_runner_group.foreach_env_runner(_render_after_sampling,
                                                             local_env_runner=False)
    finally:
        algo.stop()
    assert len(frames) == 2  # one per element of the runner's native vector env
    for frame in frames:
        assert frame.shape == (480, 720, 3) and frame.dtype == np.uint8 and frame.std() > 0


class _FrameSizes(RLlibCallback):
    """docs/rllib.md's way to a frame in a callback: ``env.unwrapped.render()[env_index]``."""

    def on_episode_step(self, *, env, env_index, metrics_logger, **kwargs):
        frame = env.unwrapped.render()[env_index]
        metrics_logger.log_value("frame_height", frame.shape[0], reduce="max")
        metrics_logger.log_value("frame_width", frame.shape[1], reduce="max")
        metrics_logger.log_value("frame_std", float(frame.std()), reduce="min")


def test_a_callback_renders_an_element_of_the_native_vector_env(local_ray):
    """W17: RLlib's example render callback takes ``env.unwrapped.envs[0]``, which the native
    vector env lacks (every runner died, restarted without end). The frame of the element a
    callback is called for is ``env.unwrapped.render()[env_index]``, as docs/rllib.md says:
    a runner's callback gets it, every step, in the size asked."""
    config = tiny(configure(PPOConfig(), CONTROL, {"render_mode": "rgb_array",
                                                   "render_size": [96, 64],
                                                   "max_episode_steps": 20}),
                  runners=1, envs=2).callbacks(_FrameSizes)
    algo = config.build_algo()
    try:
        runners = algo.train()["env_runners"]
    finally:
        algo.stop()
    assert (runners["frame_height"], runners["frame_width"]) == (64, 96)
    assert runners["frame_std"] > 0 and runners["num_env_steps_sampled"] >= 32


def test_render_mode_in_env_config_of_single_envs_and_refused_modes():
    """vectorize=False (Gymnasium's SyncVectorEnv of single envs) takes every single-env mode;
    the native vector env renders rgb_array only, refused in the driver like any bad key."""
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner

    config = configure(PPOConfig(), STRIKE, {"render_mode": "rgb_array_list"},
                       vectorize=False).env_runners(num_envs_per_env_runner=2)
    runner = SingleAgentEnvRunner(config=config)
    try:
        strikes = _render_after_sampling(runner)
    finally:
        runner.stop()
    assert len(strikes) == 2 and all(len(frames) > 1 for frames in strikes)  # whole strikes
    assert not ray.is_initialized()
    with pytest.raises(ConfigError, match=r"render_mode'\]: must be one of \['rgb_array'\].*"
                                          r"native vector env \(got 'rgb_array_list'\)"):
        configure(PPOConfig(), STRIKE, {"render_mode": "rgb_array_list"})
    with pytest.raises(ConfigError, match=r"render_mode'\]: must be one of"):
        configure(PPOConfig(), STRIKE, {"render_mode": "ascii"}, vectorize=False)


def test_env_config_takes_gym_makes_nested_config_form_for_every_id(rllib_lab):
    """``env_config={"config": {...}}``, ``gym.make``'s own form, was laid flat for a variant
    and refused for a shipped id (``config: unknown argument``, W17); both are laid flat now,
    in the driver's check and in the env a runner makes."""
    for env_id in (STRIKE, f"spinstrike:{STRIKE}", f"{LAB}:RLlibLab/BouncyRod-v0"):
        config = configure(PPOConfig(), env_id, {"config": {"goal": "max"},
                                                 "restitution": 0.9})
        assert config.env == STRIKE and config.env_config["goal"] == "max", env_id
        env = make_env(env_id, {"config": {"goal": "max", "restitution": 0.5},
                                "restitution": 0.9})
        cfg = env.unwrapped.cfg
        assert (cfg.goal, cfg.restitution) == ("max", 0.9)  # the keywords win, as gym.make's
        env.close()


def test_configure_takes_the_spinstrike_prefixed_id():
    """The README's module-qualified id (``spinstrike:SpinStrike/...``) works in configure as in
    gym.make (was: ``ValueError env: must be one of [...]``); RLlib's name is the bare id."""
    from ray.rllib.env.single_agent_env_runner import SingleAgentEnvRunner

    config = configure(PPOConfig(), "spinstrike:" + CONTROL, {"max_episode_steps": 5})
    assert config.env == CONTROL
    runner = SingleAgentEnvRunner(config=config.env_runners(num_envs_per_env_runner=2))
    try:
        episodes = runner.sample(num_timesteps=12, random_actions=True)
    finally:
        runner.stop()
    assert [len(e) for e in episodes if e.is_done] == [5, 5]
    # any module prefix gym.make takes (here one that registers nothing) names the same env
    assert configure(PPOConfig(), "gymnasium:" + CONTROL).env == CONTROL
    with pytest.raises(ConfigError, match=r"'CartPole-v1': its entry point .* is not a "
                                          r"SpinStrike env class"):
        configure(PPOConfig(), "CartPole-v1")


@pytest.mark.parametrize("env_config,words", [
    ({"obs_mode": "dict"}, "obs_mode: 'dict' has no encoder in RLlib's default model"),
    ({"obs_mode": "pixels", "obs_size": [224, 96]},
     r"obs_mode: 'pixels' \(obs_size \[224, 96\], uint8\) does not work"),
])
def test_configure_refuses_observations_rllibs_default_model_cannot_encode(env_config, words):
    """Were RLlib's errors in every runner (no Dict encoder; no CNN layers for most sizes, and
    uint8 pixels against float layers at the sizes it has), then an IndexError in the driver.
    A config that brings its own model or connector says so."""
    with pytest.raises(ConfigError, match=words):
        configure(PPOConfig(), STRIKE, env_config)
    config = configure(PPOConfig(), STRIKE, env_config, default_encoders=False)
    assert config.env_config == env_config
    assert not ray.is_initialized()


@pytest.mark.parametrize("args,words", [
    # RLlib's minibatch (batch_size) must fit in the train batch (n_steps * n_envs): was
    # RLlib's ValueError traceback after Ray started
    (["--n-envs", "3", "--num-env-runners", "0"],
     ["batch_size: must be <= n_steps * n_envs", "batch_size 256 > 64 * 3 = 192",
      "raise --n-envs or n_steps, or lower batch_size"]),
    (["--n-envs", "1", "--num-env-runners", "2"],  # 1 env per runner: 2 in all
     ["batch_size 256 > 64 * 2 = 128", "n_envs 1 over 2 runners, 1 each"]),
    # observations RLlib's default model cannot encode: were a failure in every runner, then
    # an IndexError in the driver
    (["--env-kwargs", "{obs_mode: dict}"], ["obs_mode: 'dict' has no encoder", "'vector'"]),
    (["--env-kwargs", "{obs_mode: pixels, obs_size: [224, 96]}"],
     ["obs_mode: 'pixels' (obs_size [224, 96], uint8)", "42x42, 64x64, 84x84 or 96x96"]),
    # the CLI's evaluation and video set their own render_mode
    (["--env-kwargs", "{render_mode: rgb_array}"], ["env_kwargs: render_mode is not an env"]),
    # the SB3 backend's options: were accepted and ignored
    (["--device", "auto"], ["--device: the SB3 backend's", "'auto'"]),
    (["--torch-threads", "7"], ["--torch-threads: the SB3 backend's", "7"]),
], ids=["minibatch", "minibatch-over-runners", "obs-dict", "obs-pixels", "render-mode",
        "device", "torch-threads"])
def test_cli_backend_rllib_refuses_before_ray_starts(tmp_path, args, words):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", STRIKE, "--timesteps", "500", "--no-video", "--out", str(out), *args]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert done.returncode == 2 and len(errors) == 1, done.stderr[-3000:]
    for word in words:
        assert word in errors[0], errors[0]
    assert "Traceback" not in done.stderr and "Started a local Ray" not in done.stderr
    assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_cli_backend_rllib_says_it_compiles_the_kernels_before_ray_starts(tmp_path):
    """On a cold kernel cache the driver builds the env first: its one-line compile notice
    reaches the user before Ray starts, and the runners load the kernels from the cache (was:
    the runners compiled silently, their output being off, and the first iteration stalled).
    No runner process here (the notice's place is the point): 30-50 s on 2 busy cores."""
    out = tmp_path / "run"
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg",
               SPINSTRIKE_CACHE_DIR=str(tmp_path / "empty-cache"))
    env.pop("SPINSTRIKE_QUIET", None)
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", STRIKE, "--num-env-runners", "0", "--timesteps", "64", "--n-envs", "4",
           "--no-eval", "--no-video", "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    notice = "spinstrike: compiling the physics kernels for this machine"
    assert done.stderr.count(notice) == 1, done.stderr[-3000:]
    assert done.stderr.index(notice) < done.stderr.index("Started a local Ray")
    assert any((tmp_path / "empty-cache").rglob("*.nbi"))


def test_configure_compiles_every_kernel_the_runners_use_in_the_driver(tmp_path):
    """``configure`` builds the env once to check it; it only reset it, so on a cold kernel
    cache the step's kernels were left to each runner, which compiled them silently (its
    output is the runner's): a first iteration ~45 s longer (RLlib walk W10). It steps it too:
    the one compile notice is the driver's, and a runner's log shows none."""
    script = tmp_path / "configure_cold.py"
    script.write_text(textwrap.dedent(f"""
        import ray
        from ray.rllib.algorithms.ppo import PPOConfig
        from spinstrike.envs.rllib import configure
        ray.init(num_cpus=2, include_dashboard=False, log_to_driver=True)
        config = configure(PPOConfig(), {CONTROL!r}, num_envs_per_env_runner=2)
        print("CONFIGURED", flush=True)
        algo = config.env_runners(num_env_runners=1).training(
            train_batch_size_per_learner=64, minibatch_size=32, num_epochs=1).build_algo()
        algo.train()
        algo.stop()
        ray.shutdown()
        print("TRAINED", flush=True)
    """))
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg",
               SPINSTRIKE_CACHE_DIR=str(tmp_path / "empty-cache"))
    env.pop("SPINSTRIKE_QUIET", None)
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          env=env, timeout=900, cwd=tmp_path)
    both = done.stdout + done.stderr
    assert done.returncode == 0 and "TRAINED" in done.stdout, both[-3000:]
    notice = "spinstrike: compiling the physics kernels for this machine"
    assert both.count(notice) == 1, both[-3000:]
    assert not [line for line in both.splitlines() if notice in line and "pid=" in line]


def test_runners_import_the_drivers_spinstrike_from_a_checkouts_root(local_ray, tmp_path,
                                                                       monkeypatch):
    """Ray puts the driver's working directory first on the runners' sys.path. From the root
    of another SpinStrike checkout (here one whose envs package cannot be imported) the
    runners imported that checkout while the driver ran its own package; now the creator
    imports the driver's files."""
    fake = tmp_path / "checkout"
    (fake / "spinstrike").mkdir(parents=True)
    (fake / "spinstrike" / "__init__.py").write_text(Path(spinstrike.__file__).read_text())
    (fake / "envs").mkdir()
    (fake / "envs" / "__init__.py").write_text("raise ImportError('the checkout in the cwd')\n")
    (fake / "pyproject.toml").write_text("[project]\nname = 'spinstrike'\n")
    monkeypatch.chdir(fake)
    ray.shutdown()  # the fixture's Ray was started elsewhere: start it from the checkout
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    algo = tiny(configure(PPOConfig(), STRIKE), runners=1, envs=2).build_algo()
    try:
        assert _sampled(algo.train()) > 0
        (where,) = algo.env_runner_group.foreach_env_runner(
            lambda r: (sys.path[0], sys.modules["spinstrike.envs"].__file__),
            local_env_runner=False)
    finally:
        algo.stop()
    assert where == (str(fake), sys.modules["spinstrike.envs"].__file__)


LAB = "spinstrike_rllib_lab"
LAB_SOURCE = """
import gymnasium as gym
from spinstrike.envs.strike import RodSpinEnv, RodSpinVectorEnv

class LoudRod(RodSpinEnv):
    pass

class LoudRodVector(RodSpinVectorEnv):
    pass

gym.register("RLlibLab/BouncyRod-v0", entry_point="spinstrike.envs.strike:RodSpinEnv",
             kwargs={"restitution": 0.95}, max_episode_steps=3)
gym.register("RLlibLab/LoudRod-v0", entry_point=LoudRod, vector_entry_point=LoudRodVector)
gym.register("RLlibLab/NestedRod-v0", entry_point="spinstrike.envs.strike:RodSpinEnv",
             kwargs={"config": {"restitution": 0.95, "scene": "table.yaml"}},
             max_episode_steps=3)
gym.register("RLlibLab/NoLimit-v0", entry_point="spinstrike.envs.control:RodSpinControlEnv",
             vector_entry_point="spinstrike.envs.control:RodSpinControlVectorEnv",
             kwargs={"max_force": 6.0})
"""


@pytest.fixture
def rllib_lab(user_module):
    """A user's module registering a variant (the shipped class, other arguments) and a
    subclass, in the working directory (``user_module``)."""
    return user_module(LAB, LAB_SOURCE)


def test_a_registered_variant_trains_on_rllib_runners_with_its_arguments(local_ray, rllib_lab):
    """``configure`` refused every id but the shipped ones. A variant registered with
    ``gym.register`` (a shipped env class, other arguments), given as
    ``"module:Namespace/Name-vN"``, runs on the runners as the shipped id with the variant's
    arguments (an env_config key wins over them, as a ``gym.make`` argument does), so the
    runner processes need nothing from the user's module. A subclass is refused, saying why."""
    variant = f"{LAB}:RLlibLab/BouncyRod-v0"
    config = tiny(configure(PPOConfig(), variant, {"striker_mass": 0.25}), envs=2, fragment=8)
    assert config.env == STRIKE
    assert config.env_config == {"restitution": 0.95, "max_episode_steps": 3,
                                 "striker_mass": 0.25}
    assert resolve(variant, {"restitution": 0.5}) == (STRIKE, {"restitution": 0.5,
                                                               "max_episode_steps": 3})
    algo = config.build_algo()
    try:
        algo.train()
        seen = algo.env_runner_group.foreach_env_runner(
            lambda r: (r.env.unwrapped.world.restitution("rod", "striker").tolist(),
                       LAB in sys.modules), local_env_runner=False)
    finally:
        algo.stop()
    assert seen == [([0.95, 0.95], False)] * 2
    with pytest.raises(ConfigError, match=r"RLlibLab/LoudRod-v0.*subclass.*runners"):
        configure(PPOConfig(), f"{LAB}:RLlibLab/LoudRod-v0")
    with pytest.raises(ConfigError, match=r"unknown id 'RLlibLab/Nothing-v0'"):
        configure(PPOConfig(), "RLlibLab/Nothing-v0")


def test_cli_backend_rllib_refuses_a_control_variant_without_a_step_limit(rllib_lab):
    """W17: a control variant registered without ``max_episode_steps`` trained on the runners
    (their vector env stops at 250 steps), then hung for ever in the driver's first
    learning-curve evaluation (``gym.make`` adds no limit), both cores busy and nothing said.
    The SB3 backend refused it in one line; so does this one, before Ray starts."""
    out = rllib_lab / "run"
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", f"{LAB}:RLlibLab/NoLimit-v0", "--num-env-runners", "1", "--timesteps",
           "64", "--n-envs", "2", "--no-video", "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=rllib_lab)
    errors = [line for line in done.stderr.splitlines() if line.startswith("error: ")]
    assert done.returncode == 2 and len(errors) == 1, done.stderr[-3000:]
    assert "episodes never end" in errors[0] and "max_episode_steps" in errors[0], errors[0]
    assert "Started a local Ray" not in done.stderr
    assert not out.exists() and not Path(str(out) + ".partial").exists()


def test_cli_backend_rllib_trains_and_evaluates_a_variant(rllib_lab):
    """``spinstrike train --backend rllib --env module:Namespace/Name-vN`` (``spinstrike
    train`` took variants with SB3 only): the run's record names the variant, and
    ``spinstrike evaluate RUN`` finds it again through its module. The variant registers its
    arguments in the env's ``config`` form with a scene file, which the CLI refused
    (``config: unknown argument``; ``configure`` took it, RLlib walk W10): the run records
    them flat, the scene as read, so the run evaluates after the file is gone."""
    from spinstrike.envs.config import load_packaged_scene

    (rllib_lab / "table.yaml").write_text(yaml.safe_dump(load_packaged_scene("rod_spin")))
    out = rllib_lab / "run"
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    variant = f"{LAB}:RLlibLab/NestedRod-v0"
    cmd = [sys.executable, "-m", "spinstrike.agents.cli", "train", "--backend", "rllib",
           "--env", variant, "--num-env-runners", "1", "--timesteps", "64", "--n-envs", "4",
           "--eval-episodes", "3", "--no-video", "--out", str(out)]
    done = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900,
                          cwd=rllib_lab)
    assert done.returncode == 0, done.stderr[-3000:]
    record = yaml.safe_load((out / "config.yml").read_text())
    assert record["env"] == variant
    kwargs = record["hyperparameters"][record["env"]]["env_kwargs"]
    assert kwargs["restitution"] == 0.95 and kwargs["scene"] == load_packaged_scene("rod_spin")
    assert "RLlibLab/NestedRod-v0" in (out / "summary.md").read_text()
    (rllib_lab / "table.yaml").unlink()
    evaluated = subprocess.run([sys.executable, "-m", "spinstrike.agents.cli", "evaluate",
                                str(out), "--episodes", "3", "--no-save"],
                               capture_output=True, text=True, env=env, timeout=300,
                               cwd=rllib_lab)
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    assert "agent" in evaluated.stdout


def test_a_users_saved_sac_checkpoint_is_scored_with_the_actions_its_policy_takes(
        local_ray, tmp_path, capsys):
    """Walk W22a: ``evaluate``/``record`` took a SAC policy's deterministic action as RLlib's
    ``to_deterministic`` gives it, the squashed Gaussian's mean before the squash, clipped (a
    mean of 1.5 acted 1.0 where the policy acts tanh(1.5) = 0.91); and a user's own
    ``algo.save()`` folder was "not a run". Both through the CLI, on the env its config holds."""
    import torch
    from ray.rllib.algorithms.sac import SACConfig
    from ray.rllib.core.rl_module.rl_module import RLModule

    from spinstrike.agents.cli import main
    from spinstrike.agents.evaluate import evaluate
    from spinstrike.agents.rllib_train import load_algorithm_policy

    config = configure(SACConfig(), STRIKE, {"striker_mass": 0.3}).env_runners(
        num_env_runners=0).rl_module(model_config={"fcnet_hiddens": [16]})
    algo = config.build_algo()
    saved = tmp_path / "mine"
    algo.save(str(saved))
    algo.stop()
    # the policy's mean made constant, beyond the bounds for two actions
    where = saved / "learner_group" / "learner" / "rl_module" / "default_policy"
    module = RLModule.from_checkpoint(str(where))
    head = dict(module.named_parameters())
    loc = torch.tensor([1.5, -2.5, 0.3])
    with torch.no_grad():
        head["pi.net.mlp.0.weight"][:3] = 0.0
        head["pi.net.mlp.0.bias"][:3] = loc
    module.save_to_path(str(where))
    policy, env_id, env_config = load_algorithm_policy(saved)
    assert (env_id, env_config) == (STRIKE, {"striker_mass": 0.3})
    env = gym.make(STRIKE, **env_config)
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(policy(env, obs), np.tanh(loc.numpy()), atol=1e-6)
    capsys.readouterr()
    assert main(["evaluate", str(saved), "--episodes", "3", "--json", "--no-save"]) == 0
    scores = json.loads(capsys.readouterr().out)
    mine = evaluate(STRIKE, lambda env, obs: np.tanh(loc.numpy()), 3, 1000, env_config,
                    baselines=False)[0].mean
    assert scores["agent"]["mean"] == pytest.approx(mine, abs=1e-12)


def test_check_config_refuses_what_the_default_model_cannot_encode(local_ray):
    """Walk W22a: ``check_config`` let ``obs_mode: dict`` through on a plain
    ``config.environment(...)``; ``build_algo()`` then died with ``IndexError``. It refuses it
    as ``configure`` does, unless the config has its own connector (or it is told)."""
    from ray.rllib.connectors.env_to_module import FlattenObservations

    config = PPOConfig().environment(f"spinstrike:{STRIKE}",
                                     env_config={"obs_mode": "dict", "goal": "target"})
    with pytest.raises(ConfigError, match=r"env_config: obs_mode: 'dict' has no encoder.*"
                                          r"default_encoders=False"):
        check_config(config)
    check_config(config, default_encoders=False)
    check_config(config.env_runners(env_to_module_connector=lambda env, spaces=None,
                                    device=None: FlattenObservations()))
