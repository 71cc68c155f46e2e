"""Scenes a researcher writes, through ``gym.make``, ``physics.World`` and the CLI: the same
scene means the same physics in each, numbers are read as written, and a scene the task cannot
use is refused naming what it needs (found by an adversarial walk of scene authoring)."""

import gymnasium as gym
import numpy as np
import pytest
import yaml

import spinstrike  # noqa: F401  (registers the ids)
from spinstrike import physics
from spinstrike.agents.cli import main
from spinstrike.envs import ConfigError
from spinstrike.physics.scene import packaged_scene


def _packaged(name: str, drop: tuple[str, ...] = ()) -> dict:
    data = packaged_scene(name)
    return {k: v for k, v in data.items() if k not in drop}


def _strikes(env, seeds=range(40)) -> np.ndarray:
    rewards = []
    for s in seeds:
        env.reset(seed=s)
        rewards.append(env.step(np.array([0.6, 0.2, 0.9], np.float32))[1])
    return np.array(rewards)


def test_a_scene_without_effects_has_rotation_in_gym_make_as_in_world():
    """``effects`` left out is ``[rotation]`` (the schema's default, and ``World``'s); the envs
    read it as no effect at all: PuckSpeed with contact friction then ran without rotation,
    with other rewards and no message, and RodSpin refused the scene for lacking rotation."""
    bare = _packaged("puck_speed", drop=("effects",))
    assert physics.World(bare).effects == {"rotation"}
    given = dict(bare, effects=["rotation"])
    envs = [gym.make("SpinStrike/PuckSpeed-v1", scene=s, friction=0.4) for s in (bare, given)]
    assert [sorted(e.unwrapped.task.world.effects) for e in envs] == \
        [["contact_friction", "rotation"]] * 2
    a, b = (_strikes(e) for e in envs)
    assert np.array_equal(a, b)
    rod = gym.make("SpinStrike/RodSpin-v0", scene=_packaged("rod_spin", drop=("effects",)))
    same = gym.make("SpinStrike/RodSpin-v0")
    assert np.array_equal(_strikes(rod, range(10)), _strikes(same, range(10)))


def test_yaml_numbers_with_an_exponent_and_no_dot_are_floats(tmp_path, capsys):
    """PyYAML (YAML 1.1) reads ``1e-9`` as a string: a scene file with ``tolerance: 1e-9`` was
    refused as "not a number (got '1e-9')", and so was ``--env-kwargs '{restitution: 5e-1}'``,
    where hyperparameter files took the same spelling."""
    text = yaml.safe_dump(_packaged("rod_spin"), sort_keys=False)
    text = text.replace("tolerance: 1.0e-09", "tolerance: 1e-9").replace("mass: 0.1", "mass: 1e-1")
    assert "1e-9" in text and "1e-1" in text
    path = tmp_path / "rod.yaml"
    path.write_text(text)
    world = physics.World(path)
    assert world.tolerance == 1e-9 and np.all(world.mass[:, 0] == 0.1)
    env = gym.make("SpinStrike/RodSpin-v0", scene=str(path))
    assert np.array_equal(_strikes(env, range(5)), _strikes(gym.make("SpinStrike/RodSpin-v0"),
                                                            range(5)))
    assert main(["evaluate", "--random", "--env", "SpinStrike/RodSpin-v0", "--env-kwargs",
                 "{restitution: 5e-1}", "--episodes", "2", "--no-save"]) == 0
    capsys.readouterr()
    # what is not a number stays a string, and is refused naming the field
    assert main(["evaluate", "--random", "--env", "SpinStrike/RodSpin-v0", "--env-kwargs",
                 "{restitution: 5e}", "--episodes", "2", "--no-save"]) == 2
    assert "restitution" in capsys.readouterr().err


def test_yaml_scalars_are_read_as_yaml_1_2_reads_them(tmp_path, capsys):
    """Beyond the exponent, PyYAML's YAML 1.1 read ``substeps: 010`` as 8 (octal), ``1:30`` as
    90 (base 60), ``1_0`` as 10 and ``static: on`` as true, silently, where the README says
    YAML 1.2. Now ``010`` is ten (``0o10`` eight, ``0x10`` sixteen), and the others are strings,
    refused naming the field, in a scene file and on the command line."""
    scene = {k: v for k, v in _packaged("puck_speed").items() if k != "solver"}
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(scene, sort_keys=False)
                    + "solver: {mode: fixed, substeps: 010}\n")
    assert physics.World(path).solver.substeps == 10
    for value, got in (("0o10", 8), ("0x10", 16)):
        assert physics.World(path.read_text().replace("010", value)).solver.substeps == got
    bodies = scene["bodies"]
    for value in ("1:30", "1_0"):
        with pytest.raises(physics.SceneError, match=f"solver.substeps: .*got '{value}'"):
            physics.World(path.read_text().replace("010", value))
    flagged = yaml.safe_dump({**scene, "bodies": [bodies[0], {**bodies[1], "static": True}]},
                             sort_keys=False)
    for word in ("on", "yes", "off"):
        with pytest.raises(physics.SceneError, match=rf"bodies\[1\]\.static: .*got '{word}'"):
            physics.World(flagged.replace("static: true", f"static: {word}"))
    assert main(["evaluate", "--random", "--env", "SpinStrike/RodSpin-v0", "--env-kwargs",
                 "{solver: {mode: fixed, substeps: 1:30}}", "--episodes", "2",
                 "--no-save"]) == 2
    assert "substeps" in capsys.readouterr().err


@pytest.mark.parametrize(("env_id", "scene", "body", "changes", "shape"), [
    ("SpinStrike/RodSpin-v0", "rod_spin", "rod", {"shape": "disk", "radius": 0.1}, "rod"),
    ("SpinStrike/RodSpin-v0", "rod_spin", "striker",
     {"shape": "rod", "length": 0.1, "thickness": 0.02}, "disk"),
    ("SpinStrike/PuckSpeed-v1", "puck_speed", "puck",
     {"shape": "rod", "length": 0.1, "thickness": 0.02}, "disk"),
    ("SpinStrike/RodSpinControl-v0", "rod_control", "rod", {"shape": "disk", "radius": 0.1}, "rod"),
    ("SpinStrike/PuckSpeedControl-v0", "puck_control", "mallet",
     {"shape": "rod", "length": 0.1, "thickness": 0.02}, "disk"),
])
def test_a_task_body_of_another_shape_is_refused(env_id, scene, body, changes, shape):
    """RodSpin took a disk as its "rod": every strike paid ~1e-22, with nothing said (the scene
    without rotation, which pays 0 as surely, was refused)."""
    data = _packaged(scene)
    for b in data["bodies"]:
        if b["name"] == body:
            for key in ("radius", "length", "thickness"):
                b.pop(key, None)
            b.update(changes)
    with pytest.raises(ConfigError, match=rf"bodies\[\d\]\.shape: this env's '{body}' must be a "
                                          rf"{shape}: .*\(got '{changes['shape']}'\)"):
        gym.make(env_id, scene=data)


def test_a_control_envs_puck_may_be_a_rod():
    """Not refused: the control env observes its target's angle and spin and rewards speed."""
    data = _packaged("puck_control")
    data["bodies"][0] = {"name": "puck", "shape": "rod", "length": 0.1, "thickness": 0.02,
                         "mass": 0.05}
    env = gym.make("SpinStrike/PuckSpeedControl-v0", scene=data)
    env.reset(seed=0)
    assert np.isfinite(env.step(env.action_space.sample())[1])


@pytest.mark.parametrize(("where", "key", "message"), [
    ((), "gravity", "gravity: unknown field; allowed: ['table', 'effects', 'solver', 'materials', "
                    "'bodies'] ('gravity' is a field of table) (got 9.81)"),
    (("bodies", 0), "positon", "bodies[0].positon: unknown field; allowed: ['name', 'shape', "),
    (("solver",), "substeps", "'substeps' is a field of solver (mode fixed) and solver (mode "
                              "pymunk)"),
    (("table",), "sise", "table.sise: unknown field; allowed: ['size', 'friction', 'gravity'] "
                         "(did you mean 'size'?)"),
])
def test_an_unknown_scene_key_names_what_is_allowed(where, key, message):
    """"Extra inputs are not permitted" named neither the keys allowed there nor the section a
    misplaced key belongs to; through ``gym.make`` and ``physics.World`` alike."""
    data = _packaged("rod_spin")
    target = data
    for part in where:
        target = target.setdefault(part, {}) if isinstance(part, str) else target[part]
    target[key] = 9.81 if key == "gravity" else 4 if key == "substeps" else [0.0, 0.0]
    with pytest.raises(ConfigError) as info:
        gym.make("SpinStrike/RodSpin-v0", scene=data)
    assert message in str(info.value)
    with pytest.raises(physics.SceneError) as info:
        physics.World(data)
    assert message in str(info.value)


def test_effects_given_as_one_word_asks_for_a_list():
    data = dict(_packaged("rod_spin"), effects="rotation")
    with pytest.raises(physics.SceneError, match=r"effects: Input should be a list \(got "
                                                 r"'rotation'\)"):
        physics.World(data)
