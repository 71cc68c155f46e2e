"""World API: state views, setting state, forces, snapshots, pickling, and closed-form flight."""

import math
import pickle

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.physics import SceneError

TABLE = {
    "table": {"size": [1.2, 0.8], "friction": 0.2},
    "effects": ["rotation", "walls", "table_friction"],
    "bodies": [
        {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05, "position": [-0.3, 0.0]},
        {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1,
         "position": [0.3, 0.0], "angle": 0.5},
        {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.2, "driven": True,
         "position": [0.0, -0.3]},
        {"name": "post", "shape": "disk", "radius": 0.02, "static": True, "position": [0.0, 0.3]},
    ],
}


def test_state_views_are_named_and_read_only():
    world = physics.World(TABLE, batch_size=3)
    s = world.state
    assert s.positions.shape == (3, 4, 2) and s.angles.shape == (3, 4)
    assert s.velocities.shape == (3, 4, 2) and s.omegas.shape == (3, 4)
    with pytest.raises(ValueError):
        s.positions[0, 0, 0] = 1.0
    assert world.index("rod") == 1 and world.index("wall_top") == 7
    with pytest.raises(SceneError, match="unknown body 'nope'"):
        world.index("nope")


def test_set_state_validates():
    world = physics.World(TABLE, batch_size=2)
    with pytest.raises(SceneError, match="positions: must be finite"):
        world.set_state(positions=np.full((2, 4, 2), np.nan))
    with pytest.raises(SceneError, match="static bodies and pivots cannot move"):
        world.set_state(positions=[0.1, 0.1], body="post")
    with pytest.raises(SceneError, match="overlap"):
        world.set_state(positions=[0.3, 0.0], body="puck")  # onto the rod
    with pytest.raises(SceneError, match="shape"):
        world.set_state(velocities=np.zeros((5, 2)), body="puck")
    before = world.get_state()["state"]
    world.set_state(velocities=[[1.0, 0.0]], body="puck", env=[1])
    after = world.get_state()["state"]
    assert np.array_equal(after[0], before[0])
    assert np.array_equal(world.state.velocities[1, 0], [1.0, 0.0])


def test_forces_only_on_driven_bodies():
    world = physics.World(TABLE)
    with pytest.raises(SceneError, match="driven"):
        world.set_force("puck", [1.0, 0.0])
    with pytest.raises(SceneError, match="finite"):
        world.set_force("mallet", [np.nan, 0.0])
    world.set_force("mallet", [0.4, 0.0])
    world.step(0.1)
    # a driven body is exempt from table friction: x = x0 + F t^2 / (2 m)
    assert world.state.positions[0, 2, 0] == pytest.approx(0.5 * 0.4 / 0.2 * 0.1**2, rel=1e-12)
    assert world.state.velocities[0, 2, 0] == pytest.approx(0.4 / 0.2 * 0.1, rel=1e-12)


def test_table_friction_closed_form():
    """A puck slides v^2 / (2 mu g) and stops; a spinning rod stops after |w| k / (mu g)."""
    world = physics.World(TABLE)
    v0, w0 = 0.6, 3.0
    world.set_state(velocities=[[v0, 0.0]], body="puck")
    world.set_state(omegas=[[w0]], body="rod")
    world.step(1.0)
    mu_g = 0.2 * 9.81
    assert world.state.positions[0, 0, 0] == pytest.approx(-0.3 + v0**2 / (2 * mu_g), rel=1e-12)
    assert np.all(world.state.velocities[0, 0] == 0.0)
    k = math.sqrt(world.inertia[0, 1] / world.mass[0, 1])
    decel = mu_g / k
    assert world.state.angles[0, 1] == pytest.approx(0.5 + w0**2 / (2 * decel), rel=1e-12)
    assert world.state.omegas[0, 1] == 0.0


def test_contacts_report_wall_and_static_bodies_with_sign_convention():
    world = physics.World(TABLE)
    world.set_state(velocities=[[-2.0, 0.0]], body="puck")
    contacts = world.step(0.2)
    assert len(contacts) == 1
    assert contacts.body_a[0] == 0 and contacts.body_b[0] == world.index("wall_left")
    np.testing.assert_allclose(contacts.normal[0], [-1.0, 0.0])  # from the puck to the cushion
    assert contacts.point[0, 0] == pytest.approx(-0.6, abs=1e-8)
    assert contacts.impulse[0] > 0
    # time of impact: the puck slid 0.27 m against friction
    mu_g = 0.2 * 9.81
    t = (2.0 - math.sqrt(4.0 - 2 * mu_g * 0.27)) / mu_g
    assert contacts.time[0] == pytest.approx(t, abs=1e-7)
    world.set_state(positions=[[0.0, 0.2]], velocities=[[0.0, 1.0]], body="puck")
    contacts = world.step(0.2)
    assert contacts.body_b[0] == world.index("post")


@pytest.mark.parametrize("solver", ["exact", "fixed", "pymunk"])
def test_a_static_body_is_b_wherever_the_scene_lists_it(solver):
    """README: "in a contact with a static body, the static body is b". A static body listed
    before the moving one was a (pairs ran in listing order), its normal pointing from the post
    to the puck. Now it is b either way, and the listing order changes nothing else."""
    post = {"name": "post", "shape": "disk", "radius": 0.1, "static": True, "position": [0.5, 0.0]}
    puck = {"name": "puck", "shape": "disk", "radius": 0.1, "mass": 1.0, "velocity": [1.0, 0.1]}
    runs = []
    for bodies in ([post, puck], [puck, post]):
        world = physics.World({"effects": ["rotation"], "bodies": bodies,
                               "solver": {"mode": solver, **({"substeps": 50} if solver == "fixed"
                                                              else {})}})
        contacts = world.step(1.0)
        assert len(contacts) == 1
        assert contacts.body_a[0] == world.index("puck")
        assert contacts.body_b[0] == world.index("post")
        assert contacts.normal[0, 0] > 0.9  # from the puck to the post (+x)
        runs.append(world.state.velocities[0, world.index("puck")])
    np.testing.assert_allclose(runs[0], runs[1], rtol=0, atol=1e-12)
    assert runs[0][0] < 0  # bounced back


def test_snapshot_restore_reset_and_pickle_reproduce_trajectories():
    world = physics.World(TABLE, batch_size=2)
    world.set_state(velocities=[[1.5, 0.3]], body="puck")
    world.set_force("mallet", [0.2, 0.5])
    snap = world.get_state()
    clone = pickle.loads(pickle.dumps(world))
    for _ in range(20):
        world.step(0.02)
        clone.step(0.02)
    assert np.array_equal(world.get_state()["state"], clone.get_state()["state"])
    end = world.get_state()["state"]
    world.restore(snap)
    for _ in range(20):
        world.step(0.02)
    assert np.array_equal(world.get_state()["state"], end)
    world.reset()
    assert np.array_equal(world.state.positions[0, 0], [-0.3, 0.0])
    assert np.all(world.forces == 0) and np.all(world.time == 0)


def test_set_body_rederives_inertia_and_validates():
    world = physics.World(TABLE, batch_size=2)
    i0 = world.inertia[0, 1]
    world.set_body("rod", mass=[0.2, 0.1])
    assert world.inertia[0, 1] == pytest.approx(2 * i0)
    assert world.inertia[1, 1] == pytest.approx(i0)
    with pytest.raises(SceneError, match="rod.mass: must be > 0"):
        world.set_body("rod", mass=-1.0)
    with pytest.raises(SceneError, match="rod.radius"):
        world.set_body("rod", radius=0.1)
    with pytest.raises(SceneError, match="restitution: must lie in"):
        world.set_material("rod", "puck", restitution=1.2)
    with pytest.raises(SceneError, match="no contact pair"):
        world.set_material("post", "post", restitution=0.5)


def test_fixed_solver_converges_to_exact_with_substeps():
    scene = {
        "effects": ["rotation"],
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1},
            {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
             "position": [0.05, 0.25], "velocity": [0.5, -2.0]},
        ],
    }
    exact = physics.World(scene)
    exact.step(0.2)
    errors = []
    for n in (4, 32, 256):
        world = physics.World(scene, solver={"mode": "fixed", "substeps": n})
        world.step(0.2)
        errors.append(np.abs(world.state.velocities - exact.state.velocities).max())
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.05 * 2.0


def test_zero_dt_and_bad_dt():
    world = physics.World(TABLE)
    before = world.get_state()["state"]
    world.step(0.0)
    assert np.array_equal(world.get_state()["state"], before)
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(SceneError, match="dt"):
            world.step(bad)


def test_set_state_accepts_overlap_left_by_a_stepping_solver():
    """pymunk (and fixed) leave bodies overlapping right after an impact; setting velocities
    then must work, while moving a body deeper into another is still refused."""
    scene = {"effects": ["rotation"], "bodies": [
        {"name": "a", "shape": "disk", "radius": 0.03, "mass": 0.1, "position": [-0.1, 0],
         "velocity": [1, 0]},
        {"name": "b", "shape": "disk", "radius": 0.02, "mass": 0.3, "position": [0.1, 0]}]}
    world = physics.World(scene, solver={"mode": "pymunk", "substeps": 100, "iterations": 10})
    world.step(0.1503)  # just after the impact
    assert world.gaps().min() < -1e-9
    world.set_state(velocities=[[0, 0], [0, 0]])
    pos = world.state.positions[0].copy()
    pos[0, 0] += 0.01
    with pytest.raises(SceneError, match="overlap"):
        world.set_state(positions=pos)
