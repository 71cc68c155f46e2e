"""Bad input at every door: scene files, the World API, env keyword arguments, ``config`` dicts
and actions. Each gets one clear error of a documented type (``physics.SceneError``,
``envs.ConfigError``, ``ValueError`` for actions) whose message names what is wrong."""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
import yaml

from spinstrike import envs, physics
from spinstrike.envs import ConfigError
from spinstrike.physics import SceneError

DISK = {"name": "p", "shape": "disk", "radius": 0.05, "mass": 0.1}

# ---------------------------------------------------------------------------------------------
# scene files and scene data
# ---------------------------------------------------------------------------------------------

BAD_SCENE_FILES = [
    ("bodies: [ {name: p, shape: disk", "not valid YAML"),
    ("", "must be a mapping"),
    ("- 1\n- 2\n", "must be a mapping"),
    ("bodies:\n  - {name: p, shape: disk, radius: 0.05, mass: heavy}\n", "bodies[0].mass"),
    ("bodies:\n  - {name: p, shape: disk, radius: .nan, mass: 1}\n", "bodies[0].radius"),
    ("bodies:\n  - {name: p, shape: disk, radius: -1, mass: 1}\n", "bodies[0].radius"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1, mass: 1, colour: red}\n",
     "bodies[0].colour"),
    ("bodies:\n  - {name: p, shape: square, radius: 1, mass: 1}\n", "bodies[0].shape"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1}\n", "bodies[0].mass"),
    ("bodies:\n  - {name: p, shape: rod, radius: 1, mass: 1}\n", "bodies[0].length"),
    ("bodies: []\n", "bodies"),
    ("bodies: {p: 1}\n", "bodies"),
    ("effects: [gravity]\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "effects"),
    ("effects: [rotation, walls]\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "table.size"),
    ("solver: {mode: magic}\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "solver"),
    ("solver: {mode: exact, tolerance: 0}\nbodies:\n  - {name: p, shape: disk, radius: 1, "
     "mass: 1}\n", "solver.tolerance"),
    ("materials: {restitution: 1.5}\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "materials.restitution"),
    ("materials: {friction: 0.3}\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "materials.friction"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n"
     "  - {name: p, shape: disk, radius: 1, mass: 1, position: [5, 0]}\n", "used twice"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n"
     "  - {name: q, shape: disk, radius: 1, mass: 1, position: [1, 0]}\n", "'p' and 'q' overlap"),
    ("table: {size: [1, 1]}\neffects: [walls]\nbodies:\n"
     "  - {name: p, shape: disk, radius: 0.1, mass: 1, position: [0.45, 0]}\n",
     "bodies[0].position"),
    # accepted by load_scene before, then refused by World() without the field, or never
    ("materials: {pairs: [{bodies: [p, walls], restitution: 0.5}]}\nbodies:\n"
     "  - {name: p, shape: disk, radius: 1, mass: 1}\n", "materials.pairs[0].bodies"),
    ("materials: {pairs: [{bodies: [p, p], restitution: 0.5}]}\nbodies:\n"
     "  - {name: p, shape: disk, radius: 1, mass: 1}\n", "materials.pairs[0].bodies"),
    ("materials: {pairs: [{bodies: [s, t], restitution: 0.5}]}\nbodies:\n"
     "  - {name: s, shape: disk, radius: 1, static: true}\n"
     "  - {name: t, shape: disk, radius: 1, static: true, position: [5, 0]}\n",
     "materials.pairs[0].bodies"),
    ("table: {gravity: 100}\nbodies:\n  - {name: p, shape: disk, radius: 1, mass: 1}\n",
     "table.gravity"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1, mass: 1.0e-310}\n", "bodies[0].mass"),
    ("bodies:\n  - {name: p, shape: disk, radius: 1.0e+300, mass: 1}\n", "bodies[0].radius"),
]


@pytest.mark.parametrize(("text", "names"), BAD_SCENE_FILES,
                         ids=[n for _, n in BAD_SCENE_FILES])
def test_bad_scene_file_is_one_error_naming_the_field(tmp_path, text, names):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        physics.World(str(path))
    assert names in str(info.value)
    assert "\n" not in str(info.value).strip() or "YAML" in str(info.value)


def test_missing_scene_file_and_directory(tmp_path):
    with pytest.raises(SceneError, match="does not exist"):
        physics.load_scene(str(tmp_path / "nope.yaml"))
    with pytest.raises(SceneError, match="is not a file"):
        physics.load_scene(tmp_path)


@pytest.mark.parametrize("source", ["myscene.txt", "scenes/rod.YAML", "rod_spin ",
                                    "nope"])
def test_a_mistyped_scene_path_or_name_says_so(tmp_path, monkeypatch, source):
    """One line that is no file, no packaged scene and no YAML mapping was read as YAML text
    and reported as 'scene must be a mapping of fields, got str'."""
    monkeypatch.chdir(tmp_path)
    for given in (source, tmp_path / source):
        with pytest.raises(SceneError, match="does not exist|is neither a file") as info:
            physics.load_scene(given)
        assert "rod_spin" in str(info.value)  # the packaged scenes are listed


def test_a_one_line_yaml_scene_longer_than_a_file_name_loads():
    """Read as a possible path first, a one-line YAML scene over 255 bytes raised
    ``OSError: File name too long`` (in ``load_scene`` and in an env's ``scene=``)."""
    bodies = ", ".join(f"{{name: p{i}, shape: disk, radius: 0.01, mass: 1, position: [{i}, 0]}}"
                       for i in range(6))
    text = f"{{effects: [rotation], bodies: [{bodies}]}}"
    assert len(text) > 300 and "\n" not in text
    assert len(physics.load_scene(text).bodies) == 6
    scene = envs.config.load_packaged_scene("rod_spin")
    yaml_text = yaml.safe_dump(scene, default_flow_style=True, width=10**6).strip()
    yaml_text = yaml_text.replace(", ", ",    ")  # the same YAML, over 255 bytes
    assert "\n" not in yaml_text and len(yaml_text) > 255
    env = gym.make("SpinStrike/RodSpin-v0", scene=yaml_text)
    env.reset(seed=0)


def test_a_scene_names_its_solver_by_mode_as_world_does():
    scene = {"solver": "fixed", "bodies": [DISK]}
    assert physics.World(scene).solver == physics.World({"bodies": [DISK]},
                                                        solver="fixed").solver


def test_packaged_scene_files_load():
    for name in ("rod_spin", "puck_speed", "rod_control", "puck_control"):
        scene = physics.load_scene(envs.config.load_packaged_scene(name))
        assert scene.bodies


# ---------------------------------------------------------------------------------------------
# the World API
# ---------------------------------------------------------------------------------------------


def _world(**kw):
    scene = {"effects": ["rotation"],
             "bodies": [DISK, {"name": "m", "shape": "disk", "radius": 0.05, "mass": 0.2,
                               "driven": True, "position": [0.5, 0.0]}]}
    return physics.World(scene, **kw)


@pytest.mark.parametrize(("call", "names"), [
    (lambda w: w.step(math.nan), "dt"),
    (lambda w: w.step(-1.0), "dt"),
    (lambda w: w.step(math.inf), "dt"),
    (lambda w: w.set_state(positions=np.full((1, 2, 2), np.nan)), "positions"),
    (lambda w: w.set_state(velocities=np.ones((3, 3))), "shape"),
    (lambda w: w.set_state(omegas=[[math.inf, 0.0]]), "omegas"),
    (lambda w: w.set_state(positions=[[0.05, 0.0]], body="m"), "overlap"),
    (lambda w: w.set_force("p", [1.0, 0.0]), "driven"),
    (lambda w: w.set_force("m", [math.nan, 0.0]), "m.force"),
    (lambda w: w.set_force("nope", [1.0, 0.0]), "unknown body 'nope'"),
    (lambda w: w.set_body("p", mass=-1.0), "p.mass"),
    (lambda w: w.set_body("p", mass=math.nan), "p.mass"),
    (lambda w: w.set_body("p", length=1.0), "disk"),
    (lambda w: w.set_material("p", "m", restitution=2.0), "restitution"),
    (lambda w: w.set_material("p", "m", friction=0.5), "contact_friction"),
    (lambda w: w.set_state(velocities=[[1.0, 0.0]], body="p", env=[3]), "env"),
    # accepted before: a string, a boolean (a 1 s step), None (the last dt again), an array
    (lambda w: w.step("0.1"), "dt: must be one number of seconds"),
    (lambda w: w.step(True), "dt: must be one number of seconds"),
    (lambda w: w.step(None), "dt: must be one number of seconds"),
    (lambda w: w.step(np.array([0.01])), "one number of seconds, the same for all elements"),
    (lambda w: w.set_body("p", mass=1e-320), "p.mass: too small or large for float64"),
    (lambda w: w.set_body("p", radius=1e300), "p.inertia (of this mass and size)"),
], ids=lambda x: x if isinstance(x, str) else "")
def test_world_api_rejects_bad_values(call, names):
    world = _world()
    world.step(1.0)  # a last dt equal to True's
    before = world.get_state()["state"].copy()
    with pytest.raises(SceneError) as info:
        call(world)
    assert names in str(info.value)
    assert np.array_equal(world.get_state()["state"], before)  # the world is unchanged


@pytest.mark.parametrize(("kw", "names"), [
    ({"batch_size": 0}, "batch_size"),
    ({"batch_size": "2"}, "batch_size"),
    ({"solver": {"mode": "fixed", "substeps": 0}}, "solver.substeps"),
    ({"solver": "magic"}, "solver"),
    ({"solver": {"mode": "exact", "bogus": 1}}, "solver.bogus"),
])
def test_world_constructor_rejects_bad_arguments(kw, names):
    with pytest.raises(SceneError) as info:
        _world(**kw)
    assert names in str(info.value)


# ---------------------------------------------------------------------------------------------
# env keyword arguments, config dicts and actions
# ---------------------------------------------------------------------------------------------


def _make(env_id, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make(env_id, **kw)
        env.reset(seed=0)
        if env.step(env.action_space.sample())[2]:  # a used env, in an episode
            env.reset()
        return env


BAD_KWARGS = [
    ("SpinStrike/RodSpin-v0", {"bogus": 1}, "bogus: unknown argument"),
    ("SpinStrike/RodSpin-v0", {"restitution": 1.5}, "restitution"),
    ("SpinStrike/RodSpin-v0", {"restitution": "high"}, "restitution"),
    ("SpinStrike/RodSpin-v0", {"striker_mass": 0.0}, "striker_mass"),
    ("SpinStrike/RodSpin-v0", {"speed_range": [2.0, 1.0]}, "speed_range"),
    ("SpinStrike/RodSpin-v0", {"rod_inertia": "heavy"},
     "rod_inertia: Input should be 'capsule' or 'thin_rod', or a valid number (got 'heavy')"),
    ("SpinStrike/RodSpin-v0", {"solver": "rk4"},
     "solver: unknown mode 'rk4'; allowed: 'exact', 'fixed', 'pymunk'"),
    ("SpinStrike/RodSpin-v0", {"rod_inertia": 0},
     "rod_inertia: Input should be 'capsule' or 'thin_rod', or greater than 0 (got 0)"),
    ("SpinStrike/RodSpinControl-v0", {"obs_mode": "dict"}, "obs_mode: 'dict' needs a goal"),
    ("SpinStrike/RodSpin-v0", {"render_mode": "hologram"}, "render_mode: must be one of"),
    ("SpinStrike/RodSpin-v0", {"effects": ["gravity"]}, "effects"),
    ("SpinStrike/RodSpin-v0", {"randomize": {"colour": [0, 1]}}, "colour"),
    ("SpinStrike/RodSpin-v0", {"randomize": {"target_mass": [-1, 1]}}, "target_mass"),
    ("SpinStrike/RodSpin-v0", {"obs_mode": "telepathy"}, "obs_mode"),
    ("SpinStrike/RodSpin-v0", {"solver": {"mode": "fixed", "substeps": -3}}, "substeps"),
    ("SpinStrike/RodSpin-v0", {"scene": "missing.yaml"}, "scene: 'missing.yaml' does not"),
    ("SpinStrike/RodSpin-v0", {"scene": "rod_spn"}, "scene: 'rod_spn' is neither a file"),
    ("SpinStrike/RodSpin-v0", {"scene": "bodies: [\n {name: x"}, "scene: not valid YAML"),
    ("SpinStrike/RodSpin-v0", {"scene": {"bodies": "rod"}}, "scene.bodies"),
    ("SpinStrike/RodSpin-v0", {"scene": {"bodies": [DISK]}}, "needs a body named"),
    ("SpinStrike/RodSpin-v0", {"config": {"time_cap": -1}}, "time_cap"),
    ("SpinStrike/PuckSpeed-v0", {"friction": -0.1}, "friction"),
    ("SpinStrike/PuckSpeed-v0", {"target_speed": [0, 1]}, "target_speed"),
    ("SpinStrike/RodSpinControl-v0", {"dt": 0.0}, "dt"),
    ("SpinStrike/RodSpinControl-v0", {"max_force": -1.0}, "max_force"),
    # named effects (was "scene: a control env needs the 'walls' effect", no scene given)
    ("SpinStrike/PuckSpeedControl-v0", {"effects": ["rotation"]},
     "effects: this env needs 'walls'"),
    ("SpinStrike/PuckSpeedControl-v0", {"config": {"mallet_mass": math.nan}}, "mallet_mass"),
    ("SpinStrike/RodSpin-v0", {"config": [1]}, "config: must be a mapping"),  # was a TypeError
    # a rod env without rotation paid 0 for every action (best_reward said 1); thin_rod's
    # inertia was then blamed on a scene field the user never wrote
    ("SpinStrike/RodSpin-v0", {"effects": []}, "effects: this env needs 'rotation'"),
    ("SpinStrike/RodSpin-v0", {"rod_inertia": "thin_rod", "effects": []},
     "effects: this env needs 'rotation'"),
    ("SpinStrike/RodSpinControl-v0", {"effects": ["walls"]}, "effects: this env needs 'rotation'"),
    ("SpinStrike/RodSpinControl-v0",
     {"scene": "table: {size: [1.2, 0.8]}\neffects: [walls]\nbodies:\n"
               "  - {name: rod, shape: rod, length: 0.3, thickness: 0.02, mass: 0.1}\n"
               "  - {name: mallet, shape: disk, radius: 0.04, mass: 0.3, driven: true,"
               " position: [-0.4, 0]}\n"},
     "scene.effects: this env needs 'rotation'"),
]


@pytest.mark.parametrize(("env_id", "kw", "names"), BAD_KWARGS,
                         ids=[f"{i.split('/')[1]}-{n}" for i, _, n in BAD_KWARGS])
def test_bad_env_arguments_are_one_config_error(env_id, kw, names):
    with pytest.raises(ConfigError) as info:
        _make(env_id, **kw)
    assert names in str(info.value)


@pytest.mark.parametrize(("solver", "message"), [
    ({"mode": "rk4"}, "solver: unknown mode 'rk4'; allowed: 'exact', 'fixed', 'pymunk'"),
    ("rk4", "solver: unknown mode 'rk4'"),
    ({"mode": "exact", "tolerence": 1e-10},
     "solver.tolerence: unknown field; allowed: ['mode', 'tolerance'"),
    ({"mode": "fixed", "substeps": 0}, "solver.substeps: Input should be greater than or equal"),
])
def test_a_bad_solver_argument_is_named_as_given(solver, message):
    """``solver=`` went into the scene first, so its error read ``scene: solver: ...``, as if
    the scene were wrong; it names the argument."""
    for env_id in ("SpinStrike/RodSpin-v0", "SpinStrike/RodSpinControl-v0"):
        with pytest.raises(ConfigError) as info:
            _make(env_id, solver=solver)
        assert str(info.value).startswith(message), str(info.value)


def test_bad_vector_env_arguments_are_config_errors():
    for kw, names in (({"num_envs": 0}, "num_envs: must be an int >= 1"),
                      ({"num_envs": 2, "render_mode": "hologram"}, "render_mode"),
                      ({"num_envs": 2, "autoreset_mode": "sometimes"},
                       "autoreset_mode")):
        with pytest.raises(ConfigError, match=names):
            gym.make_vec("SpinStrike/RodSpinControl-v0", **kw)


@pytest.mark.parametrize("env_id", list(envs.ENV_IDS))
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_actions_raise_and_leave_the_env_usable(env_id, bad):
    env = _make(env_id)
    action = env.action_space.sample()
    action[0] = bad
    with pytest.raises(ValueError, match="action"):
        env.step(action)
    obs, reward, *_ = env.step(env.action_space.sample())  # still usable
    assert np.all(np.isfinite(obs)) and math.isfinite(reward)


@pytest.mark.parametrize("env_id", list(envs.ENV_IDS))
def test_wrong_action_shape_raises(env_id):
    env = _make(env_id)
    with pytest.raises(ValueError, match="action"):
        env.step(np.zeros(7, dtype=np.float32))


def test_vector_env_rejects_nan_actions():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        vec = gym.make_vec("SpinStrike/PuckSpeedControl-v0", num_envs=3)
    vec.reset(seed=0)
    actions = np.zeros((3, 2), dtype=np.float32)
    actions[1, 1] = np.nan
    with pytest.raises(ValueError, match="action"):
        vec.step(actions)
    vec.close()


def test_the_cushions_materials_read_as_one_only_where_they_agree():
    """``world.restitution(body, "walls")`` returned the left cushion's value alone, whatever
    the other three had; a cushion's name as a body said 'body index 4 out of range'."""
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.0, 1.0]},
             "materials": {"restitution": 0.7}, "bodies": [DISK]}
    world = physics.World(scene)
    assert world.restitution("p", "walls").tolist() == [0.7]
    world.set_material("p", "wall_left", restitution=0.1)
    assert world.restitution("p", "wall_left").tolist() == [0.1]
    with pytest.raises(SceneError, match="differ.*name one cushion"):
        world.restitution("p", "walls")
    with pytest.raises(SceneError, match="'wall_top' is a cushion, not a body"):
        world.set_body("wall_top", mass=1.0)
