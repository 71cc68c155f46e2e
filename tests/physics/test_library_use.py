"""The physics as a library in a user's own loop (walk W24a): what a researcher porting from
pymunk did with ``physics.World`` and what it did silently wrong."""

import warnings

import numpy as np
import pytest

from spinstrike import physics

SCENE = {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
         "bodies": [{"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02,
                     "mass": 0.1},
                    {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
                     "position": [-0.3, 0.1], "velocity": [1.0, -0.2]}]}


def test_the_public_arrays_cannot_be_made_writeable():
    """F7: numpy let ``flags.writeable = True`` back on a read-only view, and a write then
    reached the world unchecked (an overlap; a mass out of step with the impulses')."""
    world = physics.World(SCENE, batch_size=2)
    for a in (world.state.positions, world.state.omegas, world.mass, world.inertia,
              world.radius, world.time, world.params, world.forces, world.state.positions[0]):
        with pytest.raises(ValueError):
            a.flags.writeable = True
    with pytest.raises(ValueError):
        world.mass[0, 0] = 100.0


def test_an_edit_never_written_warns():
    """F4: ``world.edit(env).set_body(...)`` without ``with`` dropped the change silently."""
    world = physics.World(SCENE, batch_size=4)
    with pytest.warns(RuntimeWarning, match=r"never written.*with world.edit"):
        world.edit(env=[3]).set_body("rod", mass=2.0)
    assert (world.mass[:, 0] == 0.1).all()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with world.edit(env=[3]) as e:  # the documented forms: written, no warning
            e.set_body("rod", mass=2.0)
        e = world.edit(env=[2])
        e.set_body("rod", mass=3.0)
        e.commit()
        with pytest.raises(KeyError), world.edit(env=[1]) as e:  # a block that raises
            e.set_body("rod", mass=4.0)
            raise KeyError("the user's own error: nothing written, nothing to warn of")
        del e
    np.testing.assert_array_equal(world.mass[:, 0], [0.1, 0.1, 3.0, 2.0])


def test_a_step_takes_a_0d_array():
    """F8: ``world.step(np.clip(dt, ...))`` (a 0-d array) was refused as "not one number"."""
    a, b = physics.World(SCENE), physics.World(SCENE)
    for _ in range(20):
        a.step(np.array(0.01))
        b.step(0.01)
    np.testing.assert_array_equal(a.get_state()["state"], b.get_state()["state"])
    assert a.dt == 0.01 and type(a.dt) is float
    with pytest.raises(physics.SceneError, match="one number"):
        a.step(np.array([0.01, 0.02]))


def test_a_one_element_snapshot_restores_into_a_chosen_element():
    """F9: ``restore(snapshot, env=[i])`` wanted a whole batch's snapshot."""
    one = physics.World(SCENE)
    for _ in range(10):
        one.step(0.01)
    snap = one.get_state(parameters=True)
    many = physics.World(SCENE, batch_size=4)
    many.restore(snap, env=[2])
    np.testing.assert_array_equal(many.get_state()["state"][2], snap["state"][0])
    for _ in range(15):
        one.step(0.01)
        many.step(0.01)
    np.testing.assert_array_equal(many.get_state()["state"][2], one.get_state()["state"][0])
    with pytest.raises(physics.SceneError, match=r"neither the whole batch's .* nor the selected"):
        many.restore(snap, env=[0, 1])


def test_kinetic_energy_reads_inf_without_a_warning():
    """F10: a puck at 1e300 m/s: ``kinetic_energy()`` is inf, as the README says, with no bare
    numpy overflow warning."""
    world = physics.World({"bodies": [{"name": "puck", "shape": "disk", "radius": 0.03,
                                       "mass": 0.05, "velocity": [1e300, 0.0]}]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert world.kinetic_energy()[0] == np.inf


def test_recording_the_live_state_needs_a_copy():
    """F3, as documented (``State``): the views follow the world; copies keep each step."""
    world = physics.World(SCENE)
    views, copies = [], []
    for _ in range(3):
        world.step(0.05)
        views.append(world.state.positions)
        copies.append(world.state.positions.copy())
    assert all(np.array_equal(v, copies[-1]) for v in views)
    assert not np.array_equal(copies[0], copies[-1])


def test_the_fixed_solver_says_when_it_cannot_keep_a_body_on_the_table():
    """F2: a force beyond what the fixed solver's substeps resolve put a mallet far off a
    walled table (1e60 N: 1.7e41 m) and said nothing; a step that would take a body that far
    is now refused, naming it (``test_extreme_inputs``: up to that bound the fixed solver
    keeps it on the table). (The off-table warning stays, shared with the pymunk backend.)
    The exact solver keeps it on the table at a force it resolves."""
    scene = {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
             "bodies": [{"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3,
                         "driven": True, "position": [-0.4, 0.0]}]}
    fixed = physics.World(scene, solver={"mode": "fixed", "substeps": 1})
    fixed.set_force("mallet", [1e60, 3e59])
    with pytest.raises(physics.SimulationError, match="not stepped: body 'mallet'"):
        fixed.step(0.02)
    assert fixed.state.positions[0, 0].tolist() == [-0.4, 0.0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        exact = physics.World(scene)
        exact.set_force("mallet", [1e7, 3e6])
        for _ in range(5):
            exact.step(0.02)
    assert (np.abs(exact.state.positions[0, 0]) <= [0.6 - 0.04 + 1e-9, 0.4 - 0.04 + 1e-9]).all()


def test_an_edit_opened_before_a_step_is_refused_not_rewinding():
    """Walk W25 F5: an edit kept open while the world stepped, then committed, wrote its old
    copies back: bodies it did not name were rewound (a rod from x 0.0475 back to 0). Its
    commit is refused, naming why, and nothing is written; an edit opened after the steps
    works."""
    world = physics.World(SCENE)
    e = world.edit()
    e.set_body("puck", mass=0.07)  # copies the parameters now
    e.set_state(body="puck", velocities=[1.0, -0.2])  # and the state
    for _ in range(40):
        world.step(0.01)
    moved = world.get_state()["state"]
    with pytest.raises(physics.SceneError, match="before the world stepped or changed since"):
        e.commit()
    np.testing.assert_array_equal(world.get_state()["state"], moved)
    assert world.mass[0, 1] == 0.05
    with world.edit() as e:
        e.set_body("puck", mass=0.07)
    assert world.mass[0, 1] == 0.07
    np.testing.assert_array_equal(world.get_state()["state"], moved)


def test_a_shallow_copy_of_a_world_is_its_own():
    """Walk W25 F8: ``copy.copy(world)`` shared the state, so stepping the copy moved the
    original."""
    import copy

    world = physics.World(SCENE)
    before = world.get_state()["state"]
    twin = copy.copy(world)
    for _ in range(10):
        twin.step(0.01)
    np.testing.assert_array_equal(world.get_state()["state"], before)
    for _ in range(10):
        world.step(0.01)
    np.testing.assert_array_equal(world.get_state()["state"], twin.get_state()["state"])
