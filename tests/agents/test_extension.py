"""A researcher extends a shipped env (walk W21b): what their subclass, registration or edit
changes must be what every path runs, or be refused naming why. Each test goes through
``gym.make`` / ``gym.make_vec`` or the CLI, as the user's own code does."""

import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from spinstrike.agents.cli import main

MODULE = "spinstrike_test_extension_lab"
LAB = textwrap.dedent("""
    import gymnasium as gym
    import numpy as np
    from gymnasium.envs.registration import WrapperSpec
    from spinstrike.envs.control import PuckSpeedControlEnv, PuckSpeedControlVectorEnv
    from spinstrike.envs.strike import RodSpinEnv, RodSpinVectorEnv


    class SpeedRod(RodSpinEnv):  # pays for the rod's speed too
        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + 0.5 * info["speed"], terminated, truncated, info


    class OtherTaskVec(RodSpinVectorEnv):
        TASK = type("OtherTask", (RodSpinVectorEnv.TASK,), {})


    class SpeedBonus(gym.RewardWrapper):
        def reward(self, reward):
            return reward + 1.0


    class SignOnly(RodSpinEnv):  # dict mode: pays 1 for a spin of the target's sign
        def compute_reward(self, achieved_goal, desired_goal, info):
            return (np.sign(achieved_goal[..., 0]) == np.sign(desired_goal[..., 0])).astype(
                np.float64)

        def step(self, action):
            obs, _, terminated, truncated, info = super().step(action)
            reward = float(self.compute_reward(obs["achieved_goal"], obs["desired_goal"], info))
            return obs, reward, terminated, truncated, info


    class Weighted(RodSpinEnv):  # an argument of its own
        def __init__(self, speed_weight=0.5, **kwargs):
            self.speed_weight = speed_weight
            super().__init__(**kwargs)
            self.strikes = 0
            self.table = self.world  # its own world, not a copy

        def reset(self, *, seed=None, options=None):
            self.strikes += 1
            return super().reset(seed=seed, options=options)

        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + self.speed_weight * info["speed"], terminated, truncated, info


    class Bouncy(Weighted):  # an __init__ of other parameters than the env's
        def __init__(self, render_mode=None):
            super().__init__(speed_weight=3.0, render_mode=render_mode, restitution=0.5)


    class SpeedTask(RodSpinEnv.TASK):  # the change made once, for both envs
        def step(self, actions, batch_info=True):
            reward, terminated, info = super().step(actions, batch_info)
            return reward + 5.0 * np.asarray(info["speed"]), terminated, info


    class SpeedTaskRod(RodSpinEnv):
        TASK = SpeedTask


    class PaidControl(PuckSpeedControlEnv):  # a control env paying 1 more a step
        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + 1.0, terminated, truncated, info


    class PaidMore(PaidControl):  # and its subclass, 2 more
        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + 1.0, terminated, truncated, info


    class Repeat(PuckSpeedControlEnv):  # an action repeat: 4 steps of the env a step
        def step(self, action):
            total = 0.0
            for _ in range(4):
                obs, reward, terminated, truncated, info = super().step(action)
                total += reward
            return obs, total + 1.0, terminated, truncated, info


    class RepeatVec(PuckSpeedControlVectorEnv):
        def step(self, actions):
            total = 0.0
            for _ in range(4):
                obs, reward, terminated, truncated, info = super().step(actions)
                total = total + reward
            return obs, total + 1.0, terminated, truncated, info


    class KeepsClips(RodSpinEnv):  # renders within its step: each strike's clip in its info
        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            info["clip"] = self.render()
            return obs, reward + 1.0, terminated, truncated, info


    class Bonus:  # a reward-shaping mixin, before the env's class
        def step(self, action):
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + 1.0, terminated, truncated, info


    class MixRod(Bonus, RodSpinEnv):
        pass


    class ResetsFirst(PuckSpeedControlEnv):  # starts a new episode every 3 steps, itself
        def step(self, action):
            self.count = getattr(self, "count", 0) + 1
            if self.count % 3 == 1:
                self.reset()
            obs, reward, terminated, truncated, info = super().step(action)
            return obs, reward + 1.0, terminated, truncated, info


    class Odd(PuckSpeedControlEnv):  # rewards of odd types; a step that makes no base step
        kind = "float"

        def step(self, action):
            if self.kind == "skip":
                return self.task.observations()[0], 5.0, False, False, {}
            obs, reward, terminated, truncated, info = super().step(action)
            paid = reward + 1.0
            if self.kind == "tensor":
                import torch
                paid = torch.tensor(paid, requires_grad=True) * 1.0
            elif self.kind == "array":
                paid = np.array([paid])
            elif self.kind == "none":
                paid = None
            elif self.kind == "copy":
                import copy
                self.copied = copy.deepcopy(self)
            return obs, paid, terminated, truncated, info


    class Static(RodSpinEnv):  # a staticmethod step (odd, but Python allows it)
        @staticmethod
        def step(action):
            return "static", action


    class PaidControlVec(PuckSpeedControlVectorEnv):
        def step(self, actions):
            obs, reward, terminated, truncated, info = super().step(actions)
            return obs, reward + 1.0, terminated, truncated, info


    class SpeedTaskRodVec(RodSpinVectorEnv):
        TASK = SpeedTask


    # the README's template with the entry point swapped for a subclass, its vector line kept
    gym.register("ExtLab/SpeedRod-v0", entry_point=SpeedRod,
                 vector_entry_point="spinstrike.envs.strike:RodSpinVectorEnv")
    gym.register("ExtLab/OtherTask-v0", entry_point=RodSpinEnv, vector_entry_point=OtherTaskVec)
    gym.register("ExtLab/Wrapped-v0", entry_point="spinstrike.envs.strike:RodSpinEnv",
                 vector_entry_point="spinstrike.envs.strike:RodSpinVectorEnv",
                 additional_wrappers=(WrapperSpec("SpeedBonus", f"{__name__}:SpeedBonus", {}),))
    gym.register("ExtLab/Weighted-v0", entry_point=Weighted, kwargs={"speed_weight": 2.0})
    gym.register("ExtLab/Bouncy-v0", entry_point=Bouncy)
    gym.register("ExtLab/SpeedTask-v0", entry_point=SpeedTaskRod,
                 vector_entry_point=SpeedTaskRodVec)
    gym.register("ExtLab/PaidControl-v0", entry_point=PaidControl,
                 vector_entry_point=PaidControlVec, max_episode_steps=50)
    gym.register("ExtLab/PaidMore-v0", entry_point=PaidMore, max_episode_steps=50)
    gym.register("ExtLab/Repeat-v0", entry_point=Repeat, vector_entry_point=RepeatVec,
                 max_episode_steps=50)
    gym.register("ExtLab/KeepsClips-v0", entry_point=KeepsClips)
    gym.register("ExtLab/MixRod-v0", entry_point=MixRod)
    gym.register("ExtLab/SignOnly-v0", entry_point=SignOnly,
                 kwargs={"obs_mode": "dict", "goal": "target"})
""")


def test_train_refuses_a_variant_its_vector_env_would_not_be(user_module, capsys):
    """Training steps the batched vector env. A subclass registered with the shipped vector
    env itself (the README's line kept) trained its whole budget on the shipped reward, and
    only the final evaluation ran the subclass; Gymnasium's ``additional_wrappers`` were
    dropped the same way. Both are refused before anything is written, as a subclass with
    no vector env was."""
    where = user_module(MODULE, LAB)
    for env_id, words in (("ExtLab/SpeedRod-v0", "its vector_entry_point is the shipped "
                                                 "RodSpinVectorEnv itself"),
                          ("ExtLab/Wrapped-v0", "additional_wrappers ['SpeedBonus']"),
                          ("ExtLab/OtherTask-v0", "TASK (RodSpinTask) and its vector env's "
                                                  "(OtherTask) differ")):
        out = where / env_id.replace("/", "-")
        assert main(["train", "--env", f"{MODULE}:{env_id}", "--timesteps", "256",
                     "--out", str(out), "--no-progress"]) == 2, env_id
        err = capsys.readouterr().err
        assert words in " ".join(err.split()), (env_id, err)
        assert not out.exists() and not out.with_name(out.name + ".partial").exists()


def test_rllib_refuses_a_variant_its_runners_would_not_wrap(user_module):
    """Walk W26a F6: a variant registered with ``additional_wrappers`` trained under RLlib on
    the unwrapped env (the runners build the shipped id with the variant's arguments) and was
    scored wrapped (a reward clipped at 0.5: oracle 0.5000, exit 0, no wrapper in the record).
    ``configure`` (so the CLI's ``--backend rllib``) refuses it, naming the wrappers, before
    Ray is imported."""
    from spinstrike.envs import ConfigError
    from spinstrike.envs.rllib import configure

    user_module(MODULE, LAB)
    for env_id in (f"{MODULE}:ExtLab/Wrapped-v0", "ExtLab/Wrapped-v0"):
        with pytest.raises(ConfigError, match=r"registered with additional_wrappers "
                                              r"\['SpeedBonus'\], which gym.make applies and "
                                              r"RLlib's runners"):
            configure(object(), env_id)


def test_a_subclass_s_own_compute_reward_is_the_one_her_calls(user_module):
    """In dict mode the env bound the base reward to the instance as ``compute_reward``,
    which hid a subclass's own method: HER relabelled with the base reward and the checkers
    passed, the two sides agreeing on the wrong reward."""
    user_module(MODULE, LAB)
    __import__(MODULE)
    env = gym.make("ExtLab/SignOnly-v0")
    obs, _ = env.reset(seed=3)
    _, reward, *_ = env.step(env.action_space.sample())
    assert env.unwrapped.compute_reward.__func__ is type(env.unwrapped).compute_reward
    # SB3's HER calls it on batches: its own formula, 0 or 1
    goals = np.array([[1.0], [-1.0]], dtype=np.float32)
    assert list(env.unwrapped.compute_reward(goals, np.ones_like(goals), [{}, {}])) == [1, 0]
    assert reward in (0.0, 1.0)


def test_a_control_env_observes_its_world_after_an_edit_or_a_state_put_back():
    """A control env's observation was a buffer the reset wrote: after ``world.edit()`` (a
    subclass's reset placing the rod) or ``set_physics_state`` it still showed the old pose
    until the next step, and nothing public refreshed it."""
    env = gym.make("SpinStrike/RodSpinControl-v0")
    first, _ = env.reset(seed=0)
    snap = env.unwrapped.get_physics_state()
    for _ in range(5):
        moved, *_ = env.step(np.array([1.0, 0.3], dtype=np.float32))
    assert not np.array_equal(moved, first)
    # a state put back: its observation, returned, and the one the next step starts from
    put_back = env.unwrapped.set_physics_state(snap)
    np.testing.assert_array_equal(put_back, first)
    # an edit: the rod moved and spun, as a subclass's reset would place it
    env.reset(seed=1)
    with env.unwrapped.world.edit() as edit:
        edit.set_state(body="rod", positions=[0.3, 0.1], omegas=10.0)
    fields = env.unwrapped.task.LAYOUT
    obs = dict(zip([f.name for f in fields], env.unwrapped.task.observations()[0], strict=True))
    fresh = gym.make("SpinStrike/RodSpinControl-v0")
    fresh.reset(seed=1)
    fresh.unwrapped.world.restore(env.unwrapped.world.get_state(parameters=True))
    assert obs == dict(zip([f.name for f in fields], fresh.unwrapped.task.observations()[0],
                           strict=True))
    assert obs[[f.name for f in fields if "spin" in f.name][0]] > 0
    # the vector env alike: one element edited, the others' observations as they were
    vec = gym.make_vec("SpinStrike/RodSpinControl-v0", 3, vectorization_mode="vector_entry_point")
    before, _ = vec.reset(seed=2)
    with vec.unwrapped.world.edit(1) as edit:
        edit.set_state(body="rod", omegas=10.0)
    after = vec.unwrapped.task.observations()
    np.testing.assert_array_equal(after[[0, 2]], before[[0, 2]])
    assert not np.array_equal(after[1], before[1])


def test_copies_of_a_subclass_keep_its_arguments_and_attributes(user_module):
    """Pickle and deepcopy rebuilt an env from its config with this package's ``__init__``: a
    subclass's own argument went back to its default (speed_weight 2.0 -> 0.5, the reward
    with it), an attribute set since was gone, and a subclass whose ``__init__`` takes other
    parameters failed (TypeError: unexpected keyword argument 'config')."""
    import copy
    import pickle

    user_module(MODULE, LAB)
    __import__(MODULE)
    for env_id in ("ExtLab/Weighted-v0", "ExtLab/Bouncy-v0"):
        env = gym.make(env_id)
        env.reset(seed=5)
        env.unwrapped.curriculum_level = 3
        action = np.array([0.2, -0.4, 0.9], dtype=np.float32)
        for copied in (copy.deepcopy(env.unwrapped),
                       pickle.loads(pickle.dumps(env.unwrapped))):
            assert type(copied) is type(env.unwrapped)
            assert copied.speed_weight == env.unwrapped.speed_weight
            assert copied.curriculum_level == 3
            assert copied.strikes == 1  # the resets counted when it was copied
            assert copied.table is copied.world is not env.unwrapped.world
            assert copied.cfg == env.unwrapped.cfg
            theirs, ours = copied.step(action), env.unwrapped.step(action)
            np.testing.assert_array_equal(theirs[0], ours[0])
            assert theirs[1:4] == ours[1:4] and ours[1] > 1.0  # the speed paid too
            env.reset(seed=5)


def test_the_rod_oracle_strikes_for_a_task_subclass_s_reward(user_module):
    """The rod oracle tried its what-if strikes on the shipped task, so on a variant whose
    task pays for the rod's speed too its 'oracle' row scored 6.73 where an agent scored
    11.68; it tries them on the env's own task class now."""
    from spinstrike.agents.oracle import RodSpinOracle

    user_module(MODULE, LAB)
    lab = __import__(MODULE)
    env = gym.make("ExtLab/SpeedTask-v0")
    base = gym.make("SpinStrike/RodSpin-v0")
    paid = []
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        base.reset(seed=seed)
        ours = RodSpinOracle()(env, obs)
        shipped = RodSpinOracle()(base, obs)  # the shipped task's best strike
        copy_of = __import__("copy").deepcopy(env.unwrapped)
        paid.append((env.step(ours)[1], copy_of.step(shipped)[1]))
    assert isinstance(env.unwrapped.task, lab.SpeedTask)
    assert all(ours >= shipped for ours, shipped in paid), paid
    assert any(ours > shipped + 0.1 for ours, shipped in paid), paid


def test_video_frames_show_the_reward_a_variant_pays(user_module):
    """The frames' panel showed the shipped task's reward where a variant paid more (a
    subclass's ``step`` adds after the base step drew its frames; a task subclass's after the
    task kept its score): a video of the user's env read "reward 1.000" where it paid 2."""
    user_module(MODULE, LAB)
    __import__(MODULE)
    action = np.array([0.2, -0.4, 0.9], dtype=np.float32)
    for env_id in ("ExtLab/Weighted-v0", "ExtLab/SpeedTask-v0"):
        for mode in ("rgb_array_list", "rgb_array"):
            env = gym.make(env_id, render_mode=mode)
            env.reset(seed=5)
            _, paid, *_ = env.step(action)
            frames = env.render()
            last = env.unwrapped.task.step_frames()[-1]
            assert last.panel[-1] == f"reward {paid:.3f}" and paid > 1.0, (env_id, last.panel)
            shown = frames[-1] if mode == "rgb_array_list" else frames
            np.testing.assert_array_equal(shown, env.unwrapped.task.draw(last))
    # a mixin's step alike; a step that renders within gets the strike's clip (every frame)
    env = gym.make("ExtLab/MixRod-v0", render_mode="rgb_array")
    env.reset(seed=5)
    _, paid, *_ = env.step(action)
    assert env.unwrapped.task.step_frames()[-1].panel[-1] == f"reward {paid:.3f}"
    env = gym.make("ExtLab/KeepsClips-v0", render_mode="rgb_array_list")
    env.reset(seed=5)
    *_, info = env.step(action)
    assert len(info["clip"]) > 10 and env.render() == []
    # the shipped env with the same strike paid less, and its frame says so
    base = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array")
    base.reset(seed=5)
    _, shipped, *_ = base.step(action)
    assert base.unwrapped.task.step_frames()[-1].panel[-1] == f"reward {shipped:.3f}"
    assert shipped < paid - 0.5
    # a vector env of the task subclass: each element's frame, its own strike's reward
    vec = gym.make_vec("ExtLab/SpeedTask-v0", 2, vectorization_mode="vector_entry_point",
                       render_mode="rgb_array")
    vec.reset(seed=5)
    _, rewards, *_ = vec.step(np.stack([action, action]))
    for b in range(2):
        assert vec.unwrapped.task.frame(b).panel[-1] == f"reward {rewards[b]:.3f}"
    # control envs: the step reward and the return, for a subclass of a subclass too, and
    # for every element of a vector env's subclass
    push = np.array([1.0, 0.2], dtype=np.float32)
    for env_id, extra in (("ExtLab/PaidControl-v0", 1.0), ("ExtLab/PaidMore-v0", 2.0)):
        env = gym.make(env_id, render_mode="rgb_array_list")
        env.reset(seed=1)
        paid = [env.step(push)[1] for _ in range(4)]
        frames = env.render()
        assert len(frames) == 5  # the reset's frame and one a step
        assert min(paid) >= extra
        assert env.unwrapped.task.frame(0).panel[-1] == (
            f"reward {paid[-1]:+.3f} (step)   return {sum(paid):+.3f}"), env_id
    assert min(_vector_returns_shown("ExtLab/PaidControl-v0", 3, 4, push)) >= 4.0


def _vector_returns_shown(env_id, n, steps, action):
    """The returns ``n`` elements of ``env_id``'s native vector env were paid in ``steps``
    steps of ``action``, after checking each element's frame shows its own."""
    vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point",
                       render_mode="rgb_array")
    vec.reset(seed=1)
    total = np.zeros(n)
    for _ in range(steps):
        total += vec.step(np.tile(action, (n, 1)))[1]
    for b in range(n):
        assert vec.unwrapped.task.frame(b).panel[-1].endswith(f"return {total[b]:+.3f}"), b
    return total


def test_an_edit_of_a_subclass_s_code_since_a_run_trained_is_named(user_module):
    """A run records its registered arguments, not a subclass's code: after the user edited
    their task's reward, ``evaluate RUN`` scored the run on the new reward with no word
    (11.68 where it trained on 1.17). The run records a digest of the source of the user's
    modules its classes come from, and ``evaluate`` says when one changed."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    import yaml

    user_module(MODULE, LAB)
    variant = f"{MODULE}:ExtLab/SpeedTask-v0"
    assert main(["train", "--env", variant, "--timesteps", "256", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run"]) == 0
    recorded = yaml.safe_load(Path("run/config.yml").read_text())
    assert list(recorded["code"]) == [MODULE]
    # a variant of the shipped classes records no code of the user's
    assert main(["train", "--env", "SpinStrike/RodSpin-v0", "--timesteps", "256",
                 "--n-envs", "2", "--eval-episodes", "1", "--no-video", "--no-progress",
                 "--out", "shipped"]) == 0
    assert "code" not in yaml.safe_load(Path("shipped/config.yml").read_text())
    script = Path(sys.executable).with_name("spinstrike")
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")

    def evaluate():
        out = subprocess.run([str(script), "evaluate", "run", "--episodes", "2", "--no-save",
                              "--json"], env=env, capture_output=True, text=True, timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]
        return json.loads(out.stdout)["agent"]["mean"], out.stderr

    before, note = evaluate()
    assert "note:" not in note, note
    # a comment, a docstring, another registration's arguments: no change of the code
    user_module(MODULE, LAB.replace("class SpeedTask(RodSpinEnv.TASK):",
                                    "class SpeedTask(RodSpinEnv.TASK):\n    'Pays speed.'"
                                    "  # edited").replace('{"speed_weight": 2.0}',
                                                          '{"speed_weight": 3.0}'))
    assert evaluate() == (before, "")
    user_module(MODULE, LAB.replace("reward + 5.0 * np.asarray", "reward + 50.0 * np.asarray"))
    after, note = evaluate()
    assert after > before  # the code as it is now runs ...
    assert f"the code of {MODULE} ({variant}'s classes and the modules of yours they import) " \
           f"changed since run trained" in " ".join(note.split()), note  # ... and it is said


def test_an_edit_of_a_helper_module_a_subclass_imports_is_named(user_module):
    """The digest covered only the module defining the classes: a reward weight kept in a
    helper module was edited (x10) and ``evaluate`` scored the run at 120.22 instead of 12.02
    with no word (walk W23 H1). The user's modules those import are digested too."""
    import importlib
    import sys

    import yaml

    from spinstrike.envs import code_changes, code_fingerprint

    user_module("spinstrike_ext_weights", "BONUS = 5.0\n")
    user_module("spinstrike_ext_helper", (
        "import gymnasium as gym\n"
        "import numpy as np\n"
        "from spinstrike.envs.strike import RodSpinEnv, RodSpinVectorEnv\n"
        "from spinstrike_ext_weights import BONUS\n"
        "class Task(RodSpinEnv.TASK):\n"
        "    def step(self, actions, batch_info=True):\n"
        "        reward, terminated, info = super().step(actions, batch_info)\n"
        "        return reward + BONUS * np.asarray(info['speed']), terminated, info\n"
        "class Rod(RodSpinEnv):\n"
        "    TASK = Task\n"
        "class RodVec(RodSpinVectorEnv):\n"
        "    TASK = Task\n"
        "gym.register('ExtHelper/Rod-v0', entry_point=Rod, vector_entry_point=RodVec)\n"))
    variant = "spinstrike_ext_helper:ExtHelper/Rod-v0"
    assert main(["train", "--env", variant, "--timesteps", "256", "--n-envs", "2",
                 "--eval-episodes", "1", "--no-video", "--no-progress", "--out", "run"]) == 0
    code = yaml.safe_load(Path("run/config.yml").read_text())["code"]
    assert sorted(code) == ["spinstrike_ext_helper", "spinstrike_ext_weights"]
    assert code == code_fingerprint(variant) and code_changes(variant, code) == []
    user_module("spinstrike_ext_weights", "BONUS = 50.0\n")  # the user edits the helper
    sys.modules.pop("spinstrike_ext_weights")
    importlib.invalidate_caches()
    importlib.import_module("spinstrike_ext_weights")
    assert code_changes(variant, code) == ["spinstrike_ext_weights"]


def test_an_action_repeat_subclass_films_every_step_and_shows_what_it_paid(user_module):
    """A subclass stepping the env 4 times a step: its video kept one frame of 4 (played 4x
    fast, said "real time") and its return counted the first 3 rewards twice (the frames
    of the F8 fix were taken when the subclass's step returned, walk W22b F1)."""
    user_module(MODULE, LAB)
    __import__(MODULE)
    push = np.array([1.0, 0.2], dtype=np.float32)
    env = gym.make("ExtLab/Repeat-v0", render_mode="rgb_array_list")
    env.reset(seed=1)
    paid = [env.step(push)[1] for _ in range(5)]
    assert len(env.render()) == 1 + 4 * 5  # the reset's frame, then every step of the env's
    assert env.unwrapped.task.frame(0).panel[-1] == (
        f"reward {paid[-1]:+.3f} (step)   return {sum(paid):+.3f}")
    _vector_returns_shown("ExtLab/Repeat-v0", 2, 5, push)


def test_odd_user_steps_show_what_they_pay(user_module):
    """Walk W23: a user's step that resets first carried the last episode's return into the
    frames (+4, +5 where the returns were 1, 2); a reward tensor needing its graph raised
    once rendering (RuntimeError); a copy made within a step stuck and never relabelled; a
    step that made no step of the env relabelled the last one's frame; a reward of shape (1,)
    was not shown; a staticmethod step was broken by the wrapping."""
    user_module(MODULE, LAB)
    lab = __import__(MODULE)
    push = np.array([1.0, 0.2], dtype=np.float32)
    env = lab.ResetsFirst(render_mode="rgb_array")
    env.reset(seed=0)
    for k in range(5):
        env.step(push)
        assert env.task.frame(0).panel[-1].endswith(f"return {1.0 + k % 3:+.3f}"), k
    for kind, shown in (("tensor", "+1.000"), ("array", "+1.000"), ("none", "+0.000")):
        env = lab.Odd(render_mode="rgb_array")
        env.kind = kind
        env.reset(seed=0)
        env.step(push)
        assert env.task.frame(0).panel[-1].startswith(f"reward {shown} (step)"), kind
    env.kind = "skip"  # (the last step's frame keeps what that step paid)
    env.step(push)
    assert env.task.frame(0).panel[-1].startswith("reward +0.000 (step)")
    env = lab.Odd(render_mode="rgb_array")
    env.kind = "copy"
    env.reset(seed=0)
    env.step(push)
    copied = env.copied
    copied.kind = "float"
    copied.step(push)
    # (its return is what the frames showed when it was copied, before the relabelling)
    assert copied.task.frame(0).panel[-1].startswith("reward +1.000 (step)   return +1.000")
    assert lab.Static.step(3) == ("static", 3)


def test_a_paying_subclass_in_human_mode_shows_each_frame_once(user_module, monkeypatch):
    """``human`` mode showed a paying subclass's every step twice (the base step's frame, then
    the relabelled one), playing it at half speed under "real time (x1)" (walk W23)."""
    user_module(MODULE, LAB)
    lab = __import__(MODULE)
    push = np.array([1.0, 0.2], dtype=np.float32)
    for cls in (lab.PaidControl, lab.Repeat):
        env = cls(render_mode="human")
        shown: list = []
        monkeypatch.setattr(type(env.task.renderer), "show",
                            lambda self, image, fps, shown=shown: shown.append(image))
        env.reset(seed=0)
        for _ in range(3):
            env.step(push)
        per_step = 4 if cls is lab.Repeat else 1
        assert len(shown) == 1 + 3 * per_step, cls
        assert env.task.frame(0).panel[-1].startswith("reward +1.000")
        env.close()


def test_evaluate_says_the_oracle_aims_at_the_task_where_a_subclass_pays_in_its_step(
        user_module, capsys):
    """An env subclass paying in its own ``step``: the oracle's what-if strikes aim at its
    task's reward, so its row is no upper reference, and the summary presented it as one with
    no word (walk W21b F9). A task subclass, which the oracle aims at, gets no note."""
    user_module(MODULE, LAB)
    for env_id, noted in (("ExtLab/Weighted-v0", True), ("ExtLab/SpeedTask-v0", False)):
        assert main(["evaluate", "--env", f"{MODULE}:{env_id}", "--oracle", "--episodes", "2",
                     "--no-save"]) == 0
        err = " ".join(capsys.readouterr().err.split())
        assert ("Weighted pays in its own step: the oracle aims at its task's reward "
                "(RodSpinTask)" in err) is noted, (env_id, err)
