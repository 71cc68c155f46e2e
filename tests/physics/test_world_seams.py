"""Parameters that reach the kernel: what a user reads from a world is what it simulates.

Every array a world exposes is read-only (or, for the packed buffers a compiled kernel takes,
a write the kernel sees); attributes cannot be rebound; every change goes through a validated
edit that refuses bad values (NaN, strings, booleans) and changes that leave a body overlapping
another or outside the table — naming the body — and leaves the world unchanged when it refuses.
"""

from __future__ import annotations

import dataclasses
import math
import re

import gymnasium as gym
import numpy as np
import pytest

import spinstrike  # noqa: F401
from spinstrike import physics
from spinstrike.envs import ConfigError
from spinstrike.physics import SceneError

HEAD_ON = {
    "effects": ["rotation", "walls"], "table": {"size": [2.0, 1.0]},
    "materials": {"restitution": 1.0},
    "bodies": [
        {"name": "a", "shape": "disk", "radius": 0.05, "mass": 1.0, "position": [-0.3, 0.0],
         "velocity": [1.0, 0.0]},
        {"name": "b", "shape": "disk", "radius": 0.05, "mass": 1.0, "position": [0.0, 0.0]},
        {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.2,
         "position": [0.0, 0.3]},
    ],
}


def _outcome(world: physics.World) -> np.ndarray:
    world.step(0.5)
    return np.concatenate([world.state.velocities.ravel(), world.state.positions.ravel(),
                           world.state.omegas.ravel()])


def _exposed_arrays(world: physics.World):
    """Every numpy array reachable from a public attribute or property of a world, including
    the fields of the dataclasses it returns (state, last_step, last_contacts, buffers)."""
    for name in dir(world):
        if name.startswith("_"):
            continue
        value = getattr(world, name)
        if isinstance(value, np.ndarray):
            yield name, value
        elif dataclasses.is_dataclass(value) and not isinstance(value, type):
            for f in dataclasses.fields(value):
                v = getattr(value, f.name)
                if isinstance(v, np.ndarray):
                    yield f"{name}.{f.name}", v


def test_every_exposed_array_is_read_only_or_seen_by_the_kernel():
    base = _outcome(physics.World(HEAD_ON))
    world = physics.World(HEAD_ON)
    world.step(0.0)  # so last_step / last_contacts exist
    names = []
    for name, arr in _exposed_arrays(world):
        names.append(name)
        if arr.size == 0:
            assert not arr.flags.writeable, name
            continue
        try:
            arr.flat[0] = arr.flat[0]
        except ValueError:
            continue  # read-only
        # writable: only the kernels' own buffers, whose writes the kernel sees
        assert name.startswith("buffers."), f"world.{name} is writable"
    assert {"mass", "inertia", "radius", "half_length", "table_mu", "pair_a", "pair_b",
            "static", "time", "forces", "params", "state.positions", "state.omegas",
            "last_step.contacts", "last_contacts.impulse", "buffers.fbuf"} <= set(names)
    # a write into the float buffer's state slot is what the next step starts from
    probe = physics.World(HEAD_ON)
    slot = np.flatnonzero(probe.buffers.fbuf == 1.0)  # a's vx is the first 1.0 (its velocity)
    probe.buffers.fbuf[slot[0]] = 0.0
    assert not np.array_equal(_outcome(probe), base)


@pytest.mark.parametrize("name", ["mass", "radius", "half_length", "inertia", "table_mu"])
def test_parameter_arrays_refuse_writes_that_the_kernel_would_not_see(name):
    world = physics.World(HEAD_ON)
    with pytest.raises(ValueError, match="read-only"):
        getattr(world, name)[0, 1] = 3.0 if name != "table_mu" else 0.1


def test_a_mass_changed_through_the_setter_reaches_the_kernel():
    """1:3 elastic head-on: a bounces back at -0.5 m/s, b leaves at 0.5 m/s."""
    world = physics.World(HEAD_ON)
    world.set_body("b", mass=3.0)
    world.step(0.5)
    np.testing.assert_allclose(world.state.velocities[0, 0], [-0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(world.state.velocities[0, 1], [0.5, 0.0], atol=1e-12)
    assert world.mass[0, 1] == 3.0 and world.params[0, 1, 0] == pytest.approx(1 / 3)


@pytest.mark.parametrize("attr", ["mass", "solver", "batch_size", "rotation", "names", "state",
                                  "gravity"])
def test_public_attributes_cannot_be_rebound(attr):
    world = physics.World(HEAD_ON)
    with pytest.raises(AttributeError, match="read-only"):
        setattr(world, attr, getattr(world, attr))


def test_a_smaller_table_that_leaves_a_body_outside_raises_naming_it():
    world = physics.World(HEAD_ON)
    before = world.table_half_size.copy()
    with pytest.raises(SceneError, match="'a' would lie outside the table"):
        world.set_table(size=[0.2, 0.2])
    np.testing.assert_array_equal(world.table_half_size, before)
    world.set_table(size=[1.0, 1.0])  # still holds every body
    np.testing.assert_array_equal(world.table_half_size, [[0.5, 0.5]])


def test_a_longer_rod_that_would_overlap_raises_naming_both():
    world = physics.World(HEAD_ON)
    with pytest.raises(SceneError, match="'a' and 'rod' overlap by"):
        world.set_body("rod", thickness=0.6)
    assert world.radius[0, 2] == 0.01


def test_a_refused_edit_changes_nothing():
    world = physics.World(HEAD_ON, batch_size=2)
    state = world.get_state()
    mass = world.mass.copy()
    with pytest.raises(SceneError, match="overlap"):
        with world.edit(env=[1]) as e:
            e.set_body("a", mass=5.0)
            e.set_state(positions=[[-0.3, 0.0], [-0.25, 0.0], [0.0, 0.3]])  # a into b
    np.testing.assert_array_equal(world.mass, mass)
    np.testing.assert_array_equal(world.get_state()["state"], state["state"])


def test_an_edit_sets_parameters_and_placement_at_once():
    """The placement may depend on the new parameters (an env's reset): one edit reads them."""
    world = physics.World(HEAD_ON, batch_size=3)
    with world.edit(env=[0, 2]) as e:
        e.set_body("rod", length=[1.0, 0.6])
        reach = e.half_length[:, 2] + e.radius[:, 2]
        np.testing.assert_allclose(reach, [0.51, 0.31])
        pos = np.array([[-0.9, 0.0], [0.0, 0.0], [0.0, 0.4]])
        e.set_state(positions=np.stack([pos, pos]), velocities=0.0, omegas=0.0)
        assert world.half_length[0, 2] == 0.15  # not written before the edit ends
    np.testing.assert_array_equal(world.half_length[:, 2], [0.5, 0.15, 0.3])
    np.testing.assert_array_equal(world.state.positions[1, 0], [-0.3, 0.0])


def test_an_element_named_twice_is_refused_not_the_last_value_taken():
    """``set_body("rod", mass=[5.0, 6.0], env=[0, 0])`` gave element 0 the mass 6 silently
    (found by a new-user walk). Two values for one element are ambiguous: refused, naming
    ``env``, and nothing changes; indices in any order, or a mask, still work."""
    world = physics.World("rod_control", batch_size=3)
    mass = world.mass.copy()
    for setter in (lambda: world.set_body("rod", mass=[5.0, 6.0], env=[0, 0]),
                   lambda: world.set_state(velocities=0.5, env=[2, 0, 2]),
                   lambda: world.edit(env=np.array([1, 1]))):
        with pytest.raises(SceneError, match=r"env: element indices must not repeat"):
            setter()
    np.testing.assert_array_equal(world.mass, mass)
    world.set_body("rod", mass=[5.0, 6.0], env=[2, 0])
    rod = world.index("rod")
    np.testing.assert_array_equal(world.mass[:, rod], [6.0, mass[1, rod], 5.0])
    world.set_body("rod", mass=7.0, env=np.array([False, True, False]))
    assert world.mass[1, rod] == 7.0


@pytest.mark.parametrize("value", ["0.5", True, None, [0.5, "x"], np.nan])
def test_setters_refuse_non_numbers(value):
    world = physics.World(HEAD_ON)
    if value is None:
        world.set_material("a", "b", restitution=None)  # None: unchanged
        return
    with pytest.raises(SceneError, match="restitution"):
        world.set_material("a", "b", restitution=value)
    with pytest.raises(SceneError, match="a.mass"):
        world.set_body("a", mass=value)


def test_an_inertia_without_the_rotation_effect_is_refused():
    """effects.py lists inertia as a rotation parameter: set where nothing rotates, it is
    refused as the scene refuses it (it used to be accepted and ignored)."""
    world = physics.World(dict(HEAD_ON, effects=["walls"]))
    with pytest.raises(SceneError, match="a.inertia: is set but the scene does not list the "
                                         "'rotation' effect"):
        world.set_body("a", inertia=1.0)
    physics.World(HEAD_ON).set_body("a", inertia=1.0)  # with rotation: accepted


def test_scene_numbers_are_strict():
    with pytest.raises(SceneError, match=r"bodies\[0\]\.mass"):
        physics.World({"bodies": [{"name": "a", "shape": "disk", "radius": 0.1, "mass": "1"}]})
    with pytest.raises(SceneError, match="materials.restitution"):
        physics.World({"materials": {"restitution": True},
                       "bodies": [{"name": "a", "shape": "disk", "radius": 0.1, "mass": 1}]})
    with pytest.raises(SceneError, match="solver.substeps"):
        physics.World({"solver": {"mode": "fixed", "substeps": 2.5},
                       "bodies": [{"name": "a", "shape": "disk", "radius": 0.1, "mass": 1}]})
    world = physics.World({"solver": {"mode": "fixed", "substeps": np.int64(3)},
                           "bodies": [{"name": "a", "shape": "disk", "radius": np.float64(0.1),
                                       "mass": 1}]})
    assert world.solver.substeps == 3


@pytest.mark.parametrize("kwargs,field", [({"restitution": "0.5"}, "restitution"),
                                          ({"restitution": True}, "restitution"),
                                          ({"striker_mass": "1"}, "striker_mass"),
                                          ({"speed_range": [0.5, True]}, "speed_range"),
                                          ({"render_size": [480.5, 320]}, "render_size")])
def test_env_arguments_refuse_strings_and_booleans(kwargs, field):
    with pytest.raises(ConfigError, match=field):
        gym.make("SpinStrike/RodSpin-v0", **kwargs)


@pytest.mark.parametrize("env_id,good", [("SpinStrike/RodSpinControl-v0", 2),
                                         ("SpinStrike/RodSpin-v0", 3)])
def test_actions_must_have_the_exact_shape(env_id, good):
    env = gym.make(env_id)
    env.reset(seed=0)
    for bad in (np.zeros(1, np.float32), np.zeros((1, good), np.float32),
                np.zeros(good + 1, np.float32)):
        with pytest.raises(ValueError, match="expected shape"):
            env.unwrapped.step(bad)
    with pytest.raises(ValueError, match="must be numbers"):
        env.unwrapped.step(np.array(["1"] * good))
    with pytest.raises(ValueError, match="must be numbers"):
        env.unwrapped.step(np.ones(good, bool))
    vec = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    for bad in (np.zeros(good, np.float32), np.zeros((3, 1), np.float32),
                np.zeros((1, good), np.float32)):
        with pytest.raises(ValueError, match="expected shape"):
            vec.step(bad)
    vec.step(np.zeros((3, good), np.float32))  # the right shape steps


def test_a_strike_launch_that_would_overlap_is_refused_naming_the_pair():
    """The compiled strike places the striker itself; a launch inside the target raises."""
    env = gym.make("SpinStrike/RodSpin-v0")
    env.reset(seed=0)
    task = env.unwrapped.task
    rod = task.world.state.positions[:, task.it]
    task._put_striker(rod + [0.01, 0.0], np.zeros((1, 2)))
    with pytest.raises(SceneError, match="'rod' and 'striker' overlap by"):
        task._simulate()
    task._put_striker(np.full((1, 2), np.nan), np.zeros((1, 2)))
    with pytest.raises(SceneError, match="not finite"):
        task._simulate()


@pytest.mark.parametrize("solver", ["exact", "pymunk"])
def test_a_snapshot_with_parameters_undoes_an_edit(solver):
    """``get_state(parameters=True)`` then ``restore``: the masses, sizes and materials of the
    snapshot are what the next step simulates (a plain snapshot keeps the edit)."""
    world = physics.World(dict(HEAD_ON, solver={"mode": solver}), batch_size=2)
    reference = physics.World(dict(HEAD_ON, solver={"mode": solver}), batch_size=2)
    snap, plain = world.get_state(parameters=True), world.get_state()
    with world.edit(env=[1]) as e:
        e.set_body("a", mass=7.0)
        e.set_body("rod", length=0.2)
        e.set_material("a", "b", restitution=0.3)
    world.restore(plain)
    assert world.mass[1, 0] == 7.0
    world.restore(snap)
    for name in ("mass", "inertia", "radius", "half_length"):
        np.testing.assert_array_equal(getattr(world, name), getattr(reference, name))
    for _ in range(40):
        world.step(0.01)
        reference.step(0.01)
    np.testing.assert_array_equal(world.get_state()["state"], reference.get_state()["state"])


def _env_snapshot_edited(env_id, edit):
    env = gym.make(env_id)
    env.reset(seed=0)
    snap = env.unwrapped.get_physics_state()
    edit(snap["world"])
    return env, snap


_IM = 1  # the mallet's index in both control scenes (checked below)


@pytest.mark.parametrize(("env_id", "edit", "names"), [
    ("SpinStrike/RodSpinControl-v0",
     lambda w: w["materials"].__setitem__((..., 0), 3.0), "restitution must lie in [0, 1]"),
    ("SpinStrike/RodSpinControl-v0", lambda w: w["mass"].__setitem__((..., _IM), -1.0),
     "snapshot.mass (['mallet'])"),
    ("SpinStrike/PuckSpeedControl-v0", lambda w: w["mass"].__setitem__((..., _IM), math.inf),
     "snapshot.mass (['mallet'])"),
    ("SpinStrike/PuckSpeedControl-v0", lambda w: w["state"].__setitem__((..., _IM, 0), 5.0),
     "'mallet' and 'wall_right' overlap"),
    ("SpinStrike/RodSpinControl-v0", lambda w: w["forces"].__setitem__((..., 0, 0), 1.0),
     "only bodies marked 'driven: true'"),
    ("SpinStrike/RodSpinControl-v0", lambda w: w.pop("inertia"), "missing ['inertia']"),
    # cushions gone from a walled table (the mallet then left it); a clock before the start
    ("SpinStrike/PuckSpeedControl-v0",
     lambda w: w["table_half_size"].__setitem__(..., math.inf),
     "snapshot.table_half_size: must be finite and > 0 m"),
    ("SpinStrike/RodSpinControl-v0", lambda w: w["time"].__setitem__(..., -5.0),
     "snapshot.time: must be >= 0 s"),
])
def test_a_snapshot_no_edit_could_make_is_refused_naming_the_field(env_id, edit, names):
    """``set_physics_state`` (``World.restore``) took any numbers of the right shape: e = 3
    (energy gained 5x), negative or infinite masses, a mallet 4 m off the table, forces on
    bodies that are not driven; a snapshot missing one parameter silently restored none."""
    env, snap = _env_snapshot_edited(env_id, edit)
    assert env.unwrapped.world.names[_IM] == "mallet"
    before = env.unwrapped.get_physics_state()
    with pytest.raises(SceneError, match=re.escape(names)):
        env.unwrapped.set_physics_state(snap)
    after = env.unwrapped.get_physics_state()  # refused: nothing was written
    for key, value in before["world"].items():
        np.testing.assert_array_equal(after["world"][key], value)


def test_another_scenes_snapshot_is_refused():
    rod, puck = gym.make("SpinStrike/RodSpinControl-v0"), gym.make("SpinStrike/PuckSpeedControl-v0")
    rod.reset(seed=0)
    puck.reset(seed=0)
    for a, b in ((rod, puck), (puck, rod)):
        with pytest.raises(SceneError, match=re.escape(
                f"snapshot: another scene's (its bodies are {list(a.unwrapped.world.names)}; "
                f"this world's are {list(b.unwrapped.world.names)})")):
            b.unwrapped.set_physics_state(a.unwrapped.get_physics_state())
    # a plain World.get_state() (no parameters) of two bodies into another scene of two bodies
    # was restored silently; a snapshot saved before the names were recorded is still checked by
    # its parameters
    with pytest.raises(SceneError, match="another scene's"):
        puck.unwrapped.world.restore(rod.unwrapped.world.get_state())
    old = rod.unwrapped.get_physics_state()
    del old["world"]["bodies"]
    with pytest.raises(SceneError, match="a disk has no length.*another scene's snapshot"):
        puck.unwrapped.set_physics_state(old)
    # the other way round it read as a bad value only ("a rod's half length must be > 0 m")
    old = puck.unwrapped.get_physics_state()
    del old["world"]["bodies"]
    with pytest.raises(SceneError, match="half length must be > 0 m.*another scene's snapshot"):
        rod.unwrapped.set_physics_state(old)


def test_a_pymunk_snapshot_keeps_its_overlap_and_an_exact_world_refuses_it():
    scene = {"effects": ["rotation"], "bodies": [
        {"name": "a", "shape": "disk", "radius": 0.03, "mass": 0.1, "position": [-0.1, 0.0],
         "velocity": [1.0, 0.0]},
        {"name": "b", "shape": "disk", "radius": 0.02, "mass": 0.3, "position": [0.1, 0.0]}]}
    pm = physics.World(scene, solver={"mode": "pymunk", "substeps": 100})
    pm.step(0.1503)
    snap = pm.get_state(parameters=True)
    assert pm.gaps().min() < -1e-4
    pm.step(0.1)
    pm.restore(snap)  # its own solver left that overlap: it comes back as it was
    assert pm.gaps().min() < -1e-4
    with pytest.raises(SceneError, match="exact solver's states never overlap"):
        physics.World(scene).restore(snap)


def test_a_solver_argument_of_the_scenes_mode_keeps_the_scenes_other_values():
    """``World(scene, solver=...)`` replaced the scene's whole block, where the envs' ``solver=``
    keeps the scene's values it leaves out: the packaged RodSpin scene's ``settle_substep`` of
    1e-5 s went back to 1 ms when only the tolerance was asked for. Now both merge a block of
    the scene's mode, and a block of another mode (or a solver model) replaces it."""
    from spinstrike.physics.scene import ExactSolver, FixedSolver

    scene = physics.World("rod_spin").solver
    assert scene.settle_substep == 1e-5
    tighter = physics.World("rod_spin", solver={"mode": "exact", "tolerance": 1e-10}).solver
    assert tighter == scene.model_copy(update={"tolerance": 1e-10})
    env = gym.make("SpinStrike/RodSpin-v0", solver={"mode": "exact", "tolerance": 1e-10})
    assert env.unwrapped.world.solver == tighter  # the env's and World's argument agree
    assert physics.World("rod_spin", solver="exact").solver == scene
    assert physics.World("rod_spin", solver={"mode": "fixed", "substeps": 3}).solver == \
        FixedSolver(substeps=3)
    assert physics.World("rod_spin", solver=ExactSolver(tolerance=1e-8)).solver == \
        ExactSolver(tolerance=1e-8)
    with pytest.raises(SceneError, match="tolerence"):
        physics.World("rod_spin", solver={"mode": "exact", "tolerence": 1e-10})
