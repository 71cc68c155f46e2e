"""The pymunk backend: parity with the exact solver where pymunk is exact, and the World contract
(state, contacts and their sign convention, walls, parameters, effects, determinism)."""

import math
import pickle

import numpy as np
import pytest

import spinstrike.physics.pymunk_backend as backend
from spinstrike import physics
from spinstrike.physics import SceneError
from spinstrike.physics.analytic import rod_strike
from tests.physics.scenes import seed_strike

PYMUNK = {"mode": "pymunk", "substeps": 100, "iterations": 10}


def _pair(va=(1.0, 0.0), vb=(0.0, 0.0), yb=0.0, e=1.0, mu=0.0, ma=0.1, mb=0.3):
    effects = ["rotation"] + (["contact_friction"] if mu else [])
    return {
        "effects": effects,
        "materials": {"restitution": e, "friction": mu},
        "bodies": [
            {"name": "a", "shape": "disk", "radius": 0.03, "mass": ma, "position": [-0.1, 0.0],
             "velocity": list(va)},
            {"name": "b", "shape": "disk", "radius": 0.02, "mass": mb, "position": [0.1, yb],
             "velocity": list(vb)},
        ],
    }


def _pymunk_body(world, i, b=0):
    """Body i of element b as pymunk has it (its shape's collision type is the body's index)."""
    return next(s.body for s in world.backend.space(b).shapes if s.collision_type == i)


# ---------------------------------------------------------------------------------------------
# (a) parity where pymunk is exact
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("ratio", [1e-3, 1.0, 1e3])
def test_seed_head_on_pymunk_agrees_with_exact_and_closed_form(ratio):
    scene = seed_strike(0.0, ratio, 1.0)
    results = []
    for solver in ({"mode": "exact", "tolerance": 1e-9}, PYMUNK):
        world = physics.World(scene, solver=solver)
        contacts = world.step(0.06)
        assert len(contacts) == 1
        results.append((world.state.velocities[0].copy(), world.state.omegas[0].copy()))
    (v_exact, w_exact), (v_pm, w_pm) = results
    assert np.abs(v_pm - v_exact).max() <= 1e-9
    assert np.abs(w_pm - w_exact).max() * 0.2 <= 1e-9
    V1, V2, W1 = rod_strike(ratio, 1.0, 0.2, 0.0, 1.0)
    assert v_pm[0, 0] == pytest.approx(V1, abs=1e-9)
    assert v_pm[1, 0] == pytest.approx(V2, abs=1e-9)
    assert w_pm[0] == pytest.approx(W1, abs=1e-9 / 0.2)


def test_thin_rod_inertia_override_reaches_pymunk():
    """The seed's I = m r^2/3 ('thin_rod') is what pymunk uses: oblique seed case, theta = 60."""
    theta = math.radians(60)
    world = physics.World(seed_strike(theta, 1.0, 2.0), solver=PYMUNK)
    world.step(0.06)
    V1, V2, W1 = rod_strike(1.0, 2.0, 0.2, theta, 1.0)
    assert world.state.velocities[0, 1, 0] == pytest.approx(V2, abs=1e-9)
    assert world.state.omegas[0, 0] == pytest.approx(W1, abs=1e-9)


# ---------------------------------------------------------------------------------------------
# (d) backend basics
# ---------------------------------------------------------------------------------------------


def test_unsupported_effect_raises_scene_error_naming_it(monkeypatch):
    monkeypatch.setattr(backend, "SUPPORTED_EFFECTS", frozenset({"rotation", "walls"}))
    scene = {"effects": ["rotation", "table_friction"], "table": {"friction": 0.1},
             "bodies": [{"name": "p", "shape": "disk", "radius": 0.02, "mass": 0.1}]}
    with pytest.raises(SceneError, match="table_friction"):
        physics.World(scene, solver=PYMUNK)
    physics.World(scene)  # the exact solver is unaffected


def test_contact_sign_convention_normal_from_a_to_b():
    """a moving +x hits b: n = +x, j = the momentum b receives; b moving instead: n still a->b."""
    for va, vb, sign in (((1.0, 0.0), (0.0, 0.0), 1.0), ((0.0, 0.0), (-1.0, 0.0), 1.0)):
        world = physics.World(_pair(va, vb), solver=PYMUNK)
        before = world.state.velocities[0, 1].copy()
        contacts = world.step(0.3)
        assert len(contacts) == 1
        assert (contacts.body_a[0], contacts.body_b[0]) == (0, 1)
        np.testing.assert_allclose(contacts.normal[0], [sign, 0.0], atol=1e-12)
        j = contacts.impulse[0]
        assert j > 0
        dv = world.state.velocities[0, 1] - before
        np.testing.assert_allclose(0.3 * dv, j * contacts.normal[0], atol=1e-12)
        # the contact point lies between the two surfaces on the line of centres
        assert abs(contacts.point[0, 1]) < 1e-12
        assert 0.0 < contacts.time[0] < 0.3


def test_oblique_contact_and_friction_sign_match_exact():
    """Off-line impact with friction: the normal, impulse and tangential impulse agree in sign
    and to the size of pymunk's overlap error with the exact solver."""
    scene = _pair(yb=0.03, mu=0.3, mb=0.1)
    ce = physics.World(scene).step(0.3)
    fine = {"mode": "pymunk", "substeps": 3000, "iterations": 10}
    cp = physics.World(scene, solver=fine).step(0.3)
    assert len(ce) == len(cp) == 1
    np.testing.assert_allclose(cp.normal[0], ce.normal[0], atol=1e-3)
    assert cp.impulse[0] == pytest.approx(ce.impulse[0], rel=1e-3)
    assert np.sign(cp.tangent_impulse[0]) == np.sign(ce.tangent_impulse[0]) != 0
    assert cp.tangent_impulse[0] == pytest.approx(ce.tangent_impulse[0], rel=2e-2)


@pytest.mark.parametrize("wall, velocity, normal", [
    ("wall_left", (-2.0, 0.0), (-1.0, 0.0)), ("wall_right", (2.0, 0.0), (1.0, 0.0)),
    ("wall_bottom", (0.0, -2.0), (0.0, -1.0)), ("wall_top", (0.0, 2.0), (0.0, 1.0)),
])
def test_walls_reflect_with_cushion_as_body_b(wall, velocity, normal):
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.2, 0.8]},
             "bodies": [{"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
                         "velocity": list(velocity)}]}
    world = physics.World(scene, solver=PYMUNK)
    contacts = world.step(0.3)  # reaches the cushion (0.57 or 0.37 m away) once
    assert len(contacts) == 1
    assert contacts.body_a[0] == 0 and contacts.body_b[0] == world.index(wall)
    np.testing.assert_allclose(contacts.normal[0], normal, atol=1e-12)
    np.testing.assert_allclose(world.state.velocities[0, 0], -np.asarray(velocity), atol=1e-12)
    assert contacts.impulse[0] == pytest.approx(2 * 0.05 * 2.0, rel=1e-12)
    # the cushion's surface is the table edge: the contact point lies on it
    edge = np.array(normal) * np.array([0.6, 0.4])
    assert np.abs(contacts.point[0] - edge)[np.nonzero(normal)[0][0]] < 0.02


def test_set_table_moves_the_cushions():
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.2, 0.8]},
             "bodies": [{"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
                         "velocity": [1.0, 0.0]}]}
    world = physics.World(scene, batch_size=2, solver=PYMUNK)
    world.set_table(size=[0.4, 0.8], env=[1])  # right cushion at x = 0.2 in element 1 only
    contacts = world.step(0.3)
    assert list(contacts.batch) == [1]
    v = world.state.velocities[:, 0, 0]
    assert v[0] == pytest.approx(1.0) and v[1] == pytest.approx(-1.0)


def test_set_state_then_step_equals_fresh_world():
    """A teleport right after an impact (the pair's contact still cached by Chipmunk) into a
    state that collides at once steps exactly like a fresh world built in that state."""
    moved = _pair()
    moved["bodies"][0]["position"] = [0.0499, 0.0]  # 0.1 mm from b, closing at 1 m/s
    fresh = physics.World(moved, solver=PYMUNK)
    c_fresh = fresh.step(0.1)
    world = physics.World(_pair(), solver=PYMUNK)
    world.step(0.1502)  # the impact happens at t = 0.15
    world.set_state(positions=[[0.0499, 0.0], [0.1, 0.0]], velocities=[[1.0, 0.0], [0.0, 0.0]])
    c = world.step(0.1)
    assert len(c) == len(c_fresh) == 1
    assert np.array_equal(c.impulse, c_fresh.impulse)
    assert np.array_equal(world.get_state()["state"], fresh.get_state()["state"])


def test_velocity_only_set_state_continues_in_place():
    world = physics.World(_pair(), solver=PYMUNK)
    world.step(0.05)
    world.set_state(velocities=[[2.0, 0.0], [0.0, 0.0]])
    world.step(0.1)
    scene = _pair(va=(2.0, 0.0))
    scene["bodies"][0]["position"] = [-0.1 + 0.05, 0.0]
    fresh = physics.World(scene, solver=PYMUNK)
    fresh.step(0.1)
    np.testing.assert_allclose(world.state.velocities, fresh.state.velocities, rtol=0, atol=1e-12)


def test_determinism_same_input_same_output():
    scene = {"effects": ["rotation", "walls", "contact_friction"], "table": {"size": [1.2, 0.8]},
             "materials": {"restitution": 0.9, "friction": 0.2},
             "bodies": [
                 {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1,
                  "angle": 0.3, "omega": 3.0, "velocity": [0.5, -0.2]},
                 {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
                  "position": [-0.4, -0.2], "velocity": [1.5, 0.8]}]}

    def run(world):
        out = []
        for _ in range(60):
            c = world.step(0.02)
            out.append((world.get_state()["state"].copy(), c.impulse.copy(), c.point.copy()))
        return out

    w1 = physics.World(scene, solver=PYMUNK)
    w2 = physics.World(scene, solver=PYMUNK)
    a, b = run(w1), run(w2)
    w1.reset()
    c = run(w1)
    assert sum(len(x[1]) for x in a) >= 3  # the run has contacts
    for x, y, z in zip(a, b, c, strict=True):
        for p, q, r in zip(x, y, z, strict=True):
            assert np.array_equal(p, q) and np.array_equal(p, r)


@pytest.mark.parametrize("cloth", [0.0, 0.3])
def test_restore_and_pickle_resume_identically(cloth):
    """Also with cloth friction (Chipmunk joints whose cached impulses a rebuilt space has
    not): the same state steps bit for bit the same."""
    scene = _pair(yb=0.02)
    if cloth:
        scene["effects"].append("table_friction")
        scene["table"] = {"friction": cloth}
    world = physics.World(scene, solver=PYMUNK)
    world.step(0.1)
    snap = world.get_state()
    clone = pickle.loads(pickle.dumps(world))
    world.step(0.3)
    expected = world.get_state()["state"].copy()
    world.restore(snap)
    world.step(0.3)
    assert np.array_equal(world.get_state()["state"], expected)
    clone.step(0.3)
    assert np.array_equal(clone.get_state()["state"], expected)


def test_parameters_reach_the_spaces():
    """set_body / set_material per element act like scenes built with those values."""
    world = physics.World(_pair(), batch_size=3, solver=PYMUNK)
    world.set_body("b", mass=[0.3, 0.1, 0.3])
    world.set_material("a", "b", restitution=[1.0, 1.0, 0.5])
    world.step(0.3)
    for k, (mb, e) in enumerate(((0.3, 1.0), (0.1, 1.0), (0.3, 0.5))):
        ref = physics.World(_pair(mb=mb, e=e), solver=PYMUNK)
        ref.step(0.3)
        np.testing.assert_array_equal(world.state.velocities[k], ref.state.velocities[0])
        j = (1 + e) * 1.0 / (1 / 0.1 + 1 / mb)  # head-on, b at rest
        assert world.state.velocities[k, 1, 0] == pytest.approx(j / mb, rel=1e-12)


def test_per_pair_restitution_override():
    scene = _pair()
    scene["bodies"].append({"name": "c", "shape": "disk", "radius": 0.02, "mass": 0.1,
                            "position": [-0.5, 0.0], "velocity": [-1.0, 0.0]})
    scene["effects"].append("walls")
    scene["table"] = {"size": [1.2, 0.8]}
    scene["materials"]["pairs"] = [{"bodies": ["c", "walls"], "restitution": 0.25}]
    world = physics.World(scene, solver=PYMUNK)
    world.step(0.2)
    assert world.state.velocities[0, 2, 0] == pytest.approx(0.25, rel=1e-12)  # c off the wall
    assert world.state.velocities[0, 1, 0] == pytest.approx(2 * 0.1 / 0.4, rel=1e-12)  # a-b: e=1


def test_without_rotation_nothing_spins():
    scene = {"effects": [], "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.01, "mass": 0.2,
         "angle": math.pi / 2},
        {"name": "disk", "shape": "disk", "radius": 0.02, "mass": 0.05, "position": [-0.2, 0.15],
         "velocity": [2.0, 0.0]}]}
    exact = physics.World(scene)
    exact.step(0.2)
    world = physics.World(scene, solver=PYMUNK)
    world.step(0.2)
    assert np.all(world.state.omegas == 0.0) and np.all(world.state.angles[0, 0] == math.pi / 2)
    np.testing.assert_allclose(world.state.velocities, exact.state.velocities, atol=1e-12)


def test_pivot_pinned_rod_matches_exact_with_enough_iterations():
    scene = {"effects": ["rotation"], "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.01, "mass": 0.2,
         "pivot": True, "angle": math.pi / 2},
        {"name": "disk", "shape": "disk", "radius": 0.02, "mass": 0.05, "position": [-0.2, 0.1],
         "velocity": [2.0, 0.0]}]}
    exact = physics.World(scene)
    exact.step(0.1)
    errors = {}
    for its in (1, 100):
        world = physics.World(scene, solver={"mode": "pymunk", "substeps": 200, "iterations": its})
        world.step(0.1)
        give = np.array(_pymunk_body(world, 0).position)  # the joint's, in pymunk
        assert np.abs(give).max() < 1e-12  # the pin holds
        np.testing.assert_array_equal(world.state.positions[0, 0], [0.0, 0.0])  # as reported
        errors[its] = abs(world.state.omegas[0, 0] - exact.state.omegas[0, 0])
    assert errors[100] < 1e-6 * abs(exact.state.omegas[0, 0])
    assert errors[1] > 100 * errors[100]  # the pin is as rigid as the iterations make it


def test_a_pivot_that_gives_in_pymunk_is_reported_at_its_pin_and_the_world_resets():
    """pymunk pins a pivot with a finite-mass joint that gives a little; the world's rule is
    that pivots do not move, so it reports the pin (at rest) and its own checks keep working:
    reset, writing the current state back, a snapshot."""
    scene = {"effects": ["rotation"], "materials": {"restitution": 1.0}, "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 1.0,
         "angle": math.pi / 2, "pivot": True},
        {"name": "s", "shape": "disk", "radius": 0.02, "mass": 0.5, "position": [-0.2, 0.15],
         "velocity": [1.0, 0.0]}]}
    world = physics.World(scene, solver="pymunk")
    world.step(0.3)
    give = np.hypot(*_pymunk_body(world, 0).position)
    assert give > 1e-5  # the joint gave (2e-4 m at the default iterations), inside pymunk
    assert world.state.omegas[0, 0] != 0.0  # the rod was struck and turns
    np.testing.assert_array_equal(world.state.positions[0, 0], [0.0, 0.0])
    np.testing.assert_array_equal(world.state.velocities[0, 0], [0.0, 0.0])
    s = world.state
    world.set_state(positions=s.positions.copy(), angles=s.angles.copy(),
                    velocities=s.velocities.copy(), omegas=s.omegas.copy())
    snap = world.get_state()
    world.step(0.1)
    after = world.state.omegas.copy()
    world.restore(snap)
    world.step(0.1)
    np.testing.assert_array_equal(world.state.omegas, after)
    world.reset()
    fresh = physics.World(scene, solver="pymunk")
    world.step(0.3)
    fresh.step(0.3)
    np.testing.assert_array_equal(world.state.omegas, fresh.state.omegas)


def test_the_state_read_after_an_impact_that_left_an_overlap_can_be_written_back():
    """pymunk leaves bodies slightly inside each other after an impact; writing the state just
    read back (every body placed, as a user's replay does) keeps that overlap, while a
    placement that moves one of the pair must separate them."""
    world = physics.World(_pair(), solver=PYMUNK)
    world.step(0.1503)
    assert world.gaps().min() < -1e-4
    s = world.state
    world.set_state(positions=s.positions.copy(), angles=s.angles.copy(),
                    velocities=s.velocities.copy(), omegas=s.omegas.copy())
    p = world.state.positions.copy()
    p[0, 1, 0] += 1e-4  # b a little away from a, still inside it
    with pytest.raises(SceneError, match="overlapped by 0.0003 m already"):
        world.set_state(positions=p)
    world.set_state(positions=p[:, 1], body="b")  # one body alone: the overlap may stay
    assert world.gaps().min() == pytest.approx(-2e-4, rel=1e-6)


@pytest.mark.parametrize("walls", [False, True])
def test_a_static_body_resized_by_set_body_collides_at_its_new_size(walls):
    """A static body's shape is in Chipmunk's static index, which keeps the old bounding box
    until reindexed: a post grown in a scene without walls let a puck through."""
    scene = {"effects": ["rotation"] + (["walls"] if walls else []),
             "materials": {"restitution": 1.0}, "bodies": [
                 {"name": "post", "shape": "disk", "radius": 0.05, "static": True},
                 {"name": "a", "shape": "disk", "radius": 0.03, "mass": 1.0,
                  "position": [-0.5, 0.06], "velocity": [1.0, 0.0]}]}
    if walls:
        scene["table"] = {"size": [3.0, 3.0]}
    grown = physics.World(scene, solver=PYMUNK)
    grown.set_body("post", radius=0.1)
    grown.step(1.0)
    scene["bodies"][0]["radius"] = 0.1
    built = physics.World(scene, solver=PYMUNK)
    built.step(1.0)
    np.testing.assert_allclose(grown.state.velocities, built.state.velocities, atol=1e-12)
    assert grown.state.velocities[0, 1, 1] > 0.5  # deflected by the bigger post


def test_static_body_bounces_a_puck():
    scene = {"effects": ["rotation"], "bodies": [
        {"name": "post", "shape": "disk", "radius": 0.05, "static": True},
        {"name": "puck", "shape": "disk", "radius": 0.02, "mass": 0.05, "position": [-0.3, 0.0],
         "velocity": [1.0, 0.0]}]}
    world = physics.World(scene, solver=PYMUNK)
    contacts = world.step(0.5)
    # the static post is b (listed first here), as in the exact solver's contacts
    assert len(contacts) == 1 and contacts.body_a[0] == 1 and contacts.body_b[0] == 0
    np.testing.assert_allclose(world.state.velocities[0, 1], [-1.0, 0.0], atol=1e-12)
    np.testing.assert_array_equal(world.state.positions[0, 0], [0.0, 0.0])


def test_table_friction_decelerates_like_the_model():
    """Speed falls by mu g t and spin by mu g t / k (k = sqrt(I/m)), as in physics.effects."""
    scene = {"effects": ["rotation", "table_friction"], "table": {"friction": 0.2},
             "bodies": [{"name": "rod", "shape": "rod", "length": 0.2, "thickness": 0.02,
                         "mass": 0.1, "velocity": [1.0, 0.5], "omega": 20.0}]}
    world = physics.World(scene, solver=PYMUNK)
    world.step(0.1)
    decel = 0.2 * 9.81
    speed = np.hypot(1.0, 0.5) - decel * 0.1
    v = world.state.velocities[0, 0]
    assert np.hypot(*v) == pytest.approx(speed, rel=1e-12)
    assert v[1] / v[0] == pytest.approx(0.5, rel=1e-12)  # straight path
    k = math.sqrt(world.inertia[0, 0] / 0.1)
    assert world.state.omegas[0, 0] == pytest.approx(20.0 - decel / k * 0.1, rel=1e-12)
    world.set_table(friction=0.0)  # the velocity function goes, motion is free
    world.step(0.1)
    assert np.hypot(*world.state.velocities[0, 0]) == pytest.approx(speed, rel=1e-12)


@pytest.mark.parametrize("seed", range(12))
def test_table_friction_stops_a_body_at_rest_in_the_step_the_model_says(seed):
    """Random rods and pucks sliding and spinning on the cloth, random substeps: speed and spin
    fall by mu g h and mu g h / k per substep along a straight path, never reversed, and are
    exactly 0 from the step the model stops them in, the body at rest where it stopped. (The
    cloth is two Chipmunk joints per body: round-off of their effective mass left a stopped
    body at 1e-17 .. 5e-324 m/s for ever, so it was never at rest.)"""
    rng = np.random.default_rng(seed)
    shape = "rod" if seed % 2 else "disk"
    body = {"name": "b", "shape": shape, "mass": float(rng.uniform(0.05, 2.0)),
            "velocity": rng.uniform(-3.0, 3.0, 2).tolist(), "omega": float(rng.uniform(-40, 40))}
    body.update({"length": 0.3, "thickness": 0.02} if shape == "rod" else {"radius": 0.03})
    mu, n, dt = float(rng.uniform(0.05, 0.5)), int(rng.integers(1, 12)), 0.02
    world = physics.World({"effects": ["rotation", "table_friction"], "table": {"friction": mu},
                           "bodies": [body]}, solver={"mode": "pymunk", "substeps": n})
    decel = mu * 9.81
    spin_decel = decel / math.sqrt(world.inertia[0, 0] / body["mass"])
    v0, w0 = np.array(body["velocity"]), body["omega"]
    speed0 = float(np.hypot(*v0))
    stop_v, stop_w = speed0 / (decel * dt), abs(w0) / (spin_decel * dt)  # in steps
    assert min(abs(stop_v - round(stop_v)), abs(stop_w - round(stop_w))) > 1e-6  # no tie
    rest = None
    for k in range(1, math.ceil(max(stop_v, stop_w)) + 5):
        world.step(dt)
        v, w = world.state.velocities[0, 0], float(world.state.omegas[0, 0])
        speed = float(np.hypot(*v))
        assert speed == pytest.approx(max(speed0 - decel * dt * k, 0.0), rel=1e-9, abs=1e-12)
        assert w == pytest.approx(math.copysign(max(abs(w0) - spin_decel * dt * k, 0.0), w0),
                                  rel=1e-9, abs=1e-12)
        if k < stop_v:
            np.testing.assert_allclose(v / speed, v0 / speed0, rtol=0, atol=1e-12)
        else:
            assert v.tolist() == [0.0, 0.0], (k, v)
            if rest is None:
                rest = world.state.positions[0, 0].copy()
            np.testing.assert_array_equal(world.state.positions[0, 0], rest)
        if k >= stop_w:
            assert w == 0.0, (k, w)


@pytest.mark.parametrize("substeps", [1, 7])
def test_table_friction_over_steps_of_other_lengths_decelerates_at_mu_g(substeps):
    """world.step(0.1), then 0.3, 0.05 and 0.2: the speed falls by mu g per second of them all.
    Chipmunk warm-starts a joint with its last impulse scaled to the new step but clamps with
    the unscaled one: the 0.3 s step took 0.5 s of friction off (0.14 m/s left of 0.53)."""
    scene = {"effects": ["rotation", "table_friction"], "table": {"friction": 0.2},
             "bodies": [{"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.1,
                         "velocity": [1.3, 0.2], "omega": 80.0}]}
    world = physics.World(scene, solver={"mode": "pymunk", "substeps": substeps})
    decel, t = 0.2 * 9.81, 0.0
    k = math.sqrt(world.inertia[0, 0] / 0.1)
    for dt in (0.1, 0.3, 0.05, 0.2):
        world.step(dt)
        t += dt
        assert np.hypot(*world.state.velocities[0, 0]) == pytest.approx(
            np.hypot(1.3, 0.2) - decel * t, rel=1e-12), (dt, t)
        assert world.state.omegas[0, 0] == pytest.approx(80.0 - decel / k * t, rel=1e-12)


def test_table_friction_after_a_change_of_mass_still_decelerates_at_mu_g():
    """The cloth's force is m mu g: a body made 10x heavier by ``set_body`` (as a domain
    randomisation does) still slows at mu g, and its spin at mu g / k."""
    scene = {"effects": ["rotation", "table_friction"], "table": {"friction": 0.2},
             "bodies": [{"name": "rod", "shape": "rod", "length": 0.2, "thickness": 0.02,
                         "mass": 0.1, "velocity": [1.0, 0.0], "omega": 20.0}]}
    world = physics.World(scene, solver=PYMUNK)
    world.set_body("rod", mass=1.0)
    world.step(0.1)
    decel = 0.2 * 9.81
    assert world.state.velocities[0, 0, 0] == pytest.approx(1.0 - decel * 0.1, rel=1e-12)
    k = math.sqrt(world.inertia[0, 0] / 1.0)
    assert world.state.omegas[0, 0] == pytest.approx(20.0 - decel / k * 0.1, rel=1e-12)


def test_driven_body_gets_the_force_each_step():
    scene = {"effects": ["rotation"], "bodies": [
        {"name": "mallet", "shape": "disk", "radius": 0.02, "mass": 0.2, "driven": True}]}
    world = physics.World(scene, batch_size=2, solver=PYMUNK)
    world.set_force("mallet", [[1.0, -2.0], [0.0, 0.0]])
    world.step(0.3)
    np.testing.assert_allclose(world.state.velocities[:, 0], [[1.5, -3.0], [0.0, 0.0]],
                               rtol=1e-12, atol=0)


def test_last_step_counts_pymunk_steps_and_sweeps():
    world = physics.World(_pair(), batch_size=2,
                          solver={"mode": "pymunk", "substeps": 7, "iterations": 3})
    world.step(0.3)
    assert list(world.last_step.substeps) == [7, 7]
    assert list(world.last_step.iterations) == [21, 21]
    assert list(world.last_step.events) == [0, 0]
    assert list(world.last_step.contacts) == [1, 1]


def test_contacts_beyond_max_contacts_are_counted_as_dropped():
    world = physics.World(_pair(), solver=PYMUNK, max_contacts=1)
    world.set_material("a", "b", restitution=0.0)  # plastic: the pair stays in contact...
    world.set_state(velocities=[[1.0, 0.0], [-1.0, 0.0]])  # ...pressed together, many steps
    contacts = world.step(0.3)
    assert len(contacts) == 1
    assert world.last_step.contacts[0] >= 1
    assert contacts.dropped[0] == world.last_step.contacts[0] - 1


def test_a_held_contact_records_force_times_dt_when_the_step_length_changes():
    """A driven mallet pushing 2 N holds a puck on the right cushion (e = 0, all at rest): each
    step's records are F dt, also the first step at a new length (walk W29a F1: Chipmunk
    warm-starts a contact with its cached impulse times dt/prev_dt, and the record, the
    accumulator's sum, was off by (dt/prev_dt - 1) J: -6.7 % at 0.01 -> 0.03 s, +50 % at
    0.03 -> 0.005 s)."""
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.2, 0.8]},
             "materials": {"restitution": 0.0},
             "bodies": [{"name": "mallet", "shape": "disk", "radius": 0.03, "mass": 0.2,
                         "position": [0.47, 0.0], "driven": True},
                        {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.1,
                         "position": [0.53, 0.0]}]}
    world = physics.World(scene, solver={"mode": "pymunk", "substeps": 10})
    world.set_force("mallet", [2.0, 0.0])
    for _ in range(100):
        world.step(0.01)
    for dt in (0.01, 0.03, 0.03, 0.005, 0.005, 0.02):
        c = world.step(dt)
        pushes = [j for a, b, j in zip(c.body_a, c.body_b, c.impulse, strict=True) if b == 1]
        cushion = [j for a, b, j in zip(c.body_a, c.body_b, c.impulse, strict=True) if b > 1]
        assert sum(pushes) == pytest.approx(2.0 * dt, rel=1e-6), dt
        assert sum(cushion) == pytest.approx(2.0 * dt, rel=1e-6), dt


@pytest.mark.filterwarnings("ignore")
def test_a_push_below_the_cloth_friction_is_held_on_pymunk_and_creeps_on_exact_and_fixed():
    """README's known failure (walk W29a F3): a driven mallet pressing 0.1 N on a resting puck
    whose cloth friction is 0.196 N. pymunk's cloth joints are static friction and hold it;
    exact and fixed have kinetic cloth friction only, and the push's settled Zeno run moves it
    at zeno_speed (exact) or by the substep (fixed). Above the friction all agree."""
    def run(solver, force):
        scene = {"effects": ["rotation", "table_friction"], "table": {"friction": 0.2},
                 "materials": {"restitution": 0.0},
                 "bodies": [{"name": "mallet", "shape": "disk", "radius": 0.03, "mass": 0.2,
                             "position": [-0.06, 0.0], "driven": True},
                            {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.1}]}
        world = physics.World(scene, solver=solver)
        world.set_force("mallet", [force, 0.0])
        for _ in range(100):
            world.step(0.01)
        return world.state.velocities[0, 1, 0]

    assert run({"mode": "pymunk", "substeps": 10}, 0.1) == 0.0
    assert run({"mode": "exact"}, 0.1) == pytest.approx(1e-3, rel=1e-3)  # zeno_speed
    assert run({"mode": "fixed", "substeps": 10}, 0.1) == pytest.approx(1e-3, rel=0.05)
    closed = (0.3 - 0.1 * 0.2 * 9.81) / 0.3 * 1.0  # the pair moves together from 0.3 N on
    for solver in ({"mode": "pymunk", "substeps": 10}, {"mode": "exact"}):
        assert run(solver, 0.3) == pytest.approx(closed, rel=0.01)


def test_pymunk_contact_records_explain_every_change_of_momentum_in_a_rack():
    """A striker into a rack of 15 touching pucks (e = 1): each body's change of momentum over
    a step is the sum of the impulses its recorded contacts carry, as on the other solvers.
    Chipmunk's cached arbiter of a pair that separated and touched again within
    ``collision_persistence`` steps held an impulse it did not apply, and ``total_impulse``
    counted it: 0.41 N s off one body's change."""
    r, m = 0.028, 0.17
    bodies = [{"name": "striker", "shape": "disk", "radius": r, "mass": m,
               "position": [-0.4, 0.004], "velocity": [6.0, 0.0]}]
    dx = 2 * r * math.sqrt(3) / 2
    for row in range(5):
        for j in range(row + 1):
            bodies.append({"name": f"b{len(bodies)}", "shape": "disk", "radius": r, "mass": m,
                           "position": [row * dx, (j - row / 2) * 2 * r]})
    w = physics.World({"effects": [], "materials": {"restitution": 1.0}, "bodies": bodies},
                      solver={"mode": "pymunk", "substeps": 1, "iterations": 10},
                      max_contacts=4096)
    worst = 0.0
    for _ in range(300):
        before = w.state.velocities[0] * w.mass[0][:, None]
        c = w.step(0.001)
        assert not c.dropped.any()
        p = np.zeros_like(before)
        np.add.at(p, c.body_a, -(c.impulse[:, None] * c.normal))
        np.add.at(p, c.body_b, c.impulse[:, None] * c.normal)
        worst = max(worst, np.abs(w.state.velocities[0] * w.mass[0][:, None] - before - p).max())
    assert worst < 1e-12


def _two_rods(solver):
    def rod(name, x, v, w):
        return {"name": name, "shape": "rod", "length": 0.08, "thickness": 0.01, "angle": 0.7,
                "mass": 1.0, "position": [x, 0.0], "velocity": v, "omega": w}

    scene = {"table": {"size": [0.4, 0.25]}, "effects": ["rotation", "walls"],
             "materials": {"restitution": 1.0},
             "bodies": [rod("a", -0.1, [13.0, 0.0], 0.0), rod("b", 0.1, [0.0, 0.0], 13.0)]}
    return physics.World(scene, solver=solver)


def test_a_pymunk_step_that_gains_energy_with_no_force_warns_once():
    """Walk W19: Chipmunk's iterative solver gains kinetic energy at e = 1 without friction in
    a sparse scene (two 1 kg rods on a walled table: +2.5 % in one 10 ms step, 1.027x after
    300), silently; the README said pymunk gains only with friction or in crowded inelastic
    scenes. The world now warns once, naming the gain; exact, fixed and pymunk with enough
    substeps keep the energy and say nothing."""
    import warnings

    for solver, gains in (("pymunk", True), ("exact", False),
                          ({"mode": "fixed", "substeps": 100}, False),
                          ({"mode": "pymunk", "substeps": 100, "iterations": 100}, False)):
        world = _two_rods(solver)
        k0 = world.kinetic_energy()[0]
        most = 0.0
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            for _ in range(100):
                world.step(0.01)
                most = max(most, world.kinetic_energy()[0] / k0)
        said = [str(w.message) for w in got if "gained kinetic energy" in str(w.message)]
        assert (most > 1.01) == gains and len(said) == (1 if gains else 0), (solver, most, said)
        if gains:
            assert "no force on any body (up to 2.51 % in this 0.01 s step: " in said[0]


def _spinning_rods(solver, starts=40):
    """README's lone-rod friction case: 40 random starts of a 1 kg, 0.4 m rod spinning at
    28.6 rad/s, moving at up to 3 m/s per axis on a walled 1.2 x 0.8 m table, e = 1, mu = 0.3."""
    scene = {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls", "contact_friction"],
             "materials": {"restitution": 1.0, "friction": 0.3},
             "bodies": [{"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02,
                         "mass": 1.0, "position": [0.0, 0.0], "omega": 28.6}]}
    world = physics.World(scene, batch_size=starts, solver=solver)
    rng = np.random.default_rng(1)
    with world.edit() as edit:
        edit.set_state(positions=np.c_[rng.uniform(-0.2, 0.2, starts),
                                       rng.uniform(-0.1, 0.1, starts)][:, None, :],
                       angles=rng.uniform(-np.pi, np.pi, (starts, 1)),
                       velocities=rng.uniform(-3.0, 3.0, (starts, 1, 2)),
                       omegas=np.full((starts, 1), 28.6))
    return world


def test_a_lone_rod_with_friction_gains_energy_in_pymunk_only():
    """README (Physics, pymunk): with mu > 0 Chipmunk's joint normal-friction solve gains
    energy even for a lone body, and more substeps do not help, where exact and fixed lose it
    as friction must (walk W20a: the README's '33 of 40 random starts' had no setup; this is
    it). Each of 100 steps of 10 ms is compared with the step before it."""
    import warnings

    for solver, gains in (({"mode": "pymunk", "substeps": 20}, True),
                          ({"mode": "pymunk", "substeps": 200}, True), ("exact", False),
                          ({"mode": "fixed", "substeps": 20}, False)):
        world = _spinning_rods(solver)
        before = world.kinetic_energy()
        most = np.zeros(len(before))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # pymunk's gain warning: its own test above
            for _ in range(100):
                world.step(0.01)
                after = world.kinetic_energy()
                most = np.maximum(most, after / before - 1.0)
                before = after
        if gains:  # most starts gain in some step, by tens of per cent at worst
            assert (most > 0.01).sum() >= 30 and most.max() > 0.3, (solver, np.sort(most))
        else:
            assert most.max() <= 1e-12, (solver, most.max())
