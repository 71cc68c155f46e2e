"""Inputs too large for a step get a clear error or a warning, never a silent NaN or tunnel.

A speed of 1e160 m/s overflows float64 within a step (its square is infinite): the step raises
``SimulationError`` naming the elements and bodies. A force so large that the exact solver's
settling would need more than its cap of substeps loses the bound that keeps bodies from passing
through each other: the step warns and ``last_step.capped`` says which elements.
"""

import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from spinstrike import physics
from spinstrike.physics import contacts
from spinstrike.physics.world import PARALLEL_BATCH
from tests.physics.test_conservation import _scales


def _walled(restitution, bodies):
    """A scene of ``bodies`` on the fuzz test's walled 1.2 m x 0.8 m table, frictionless."""
    return {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
            "materials": {"restitution": restitution, "friction": 0.0}, "bodies": bodies}


def _unbounded(scene="rod_control"):
    """A shipped scene without its cushions (the ``walls`` effect): an unbounded table."""
    spec = physics.load_scene(scene).model_dump()
    spec["effects"] = [e for e in spec["effects"] if e != "walls"]
    spec["table"].pop("size")
    spec["materials"]["pairs"] = [p for p in spec["materials"].get("pairs", [])
                                  if "walls" not in p["bodies"]]
    return spec


@pytest.mark.parametrize("batch", [4, PARALLEL_BATCH])  # the serial and the parallel kernel
@pytest.mark.parametrize("solver", [None, {"mode": "fixed", "substeps": 4}])
def test_a_state_that_overflows_raises_naming_element_and_body(batch, solver):
    """(On an unbounded table: on a walled one the travel bound refuses the step first.)"""
    world = physics.World(_unbounded(), batch_size=batch, solver=solver)
    velocities = np.zeros((batch, 2, 2))
    velocities[2, 0] = [1e160, 0.0]  # element 2's rod
    world.set_state(velocities=velocities)
    with pytest.raises(physics.SimulationError,
                       match=r"element\(s\) \[2\] is no longer finite \(bodies \['rod'\]\)") as err:
        world.step(0.02)
    assert err.value.elements.tolist() == [2]
    assert isinstance(err.value, physics.SceneError)  # the physics' one error type
    # the other elements stepped normally
    assert np.isfinite(np.delete(world.state.positions, 2, axis=0)).all()


def test_a_large_but_finite_speed_steps_without_error_on_an_unbounded_table():
    """1e100 m/s squares to 1e200: finite, so the step runs and the rod flies 2e98 m."""
    world = physics.World(_unbounded())
    world.set_state(velocities=[[[1e100, 0.0], [0.0, 0.0]]])
    for _ in range(3):
        world.step(0.02)
    assert np.isfinite(world.state.velocities).all()
    assert world.state.positions[0, 0, 0] == pytest.approx(6e98)


def _mallet_alone(solver=None, batch=1):
    scene = {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
             "bodies": [{"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3,
                         "driven": True, "position": [-0.4, 0.0]}]}
    return physics.World(scene, solver=solver, batch_size=batch)


@pytest.mark.parametrize("batch", [3, PARALLEL_BATCH])  # the serial and the parallel kernel
@pytest.mark.parametrize("solver", [None, {"mode": "fixed", "substeps": 10}])
@pytest.mark.parametrize("push", ["speed", "force"])
def test_a_travel_float64_cannot_place_on_a_walled_table_is_refused(solver, push, batch):
    """Walk W24a F2: a step whose travel float64 cannot resolve on a walled table (1e12 m/s or
    1e20 N on a 0.3 kg mallet in 20 ms; ~1e15 table sizes and beyond, the cushions' correction
    cancelled to round-off) put the mallet at meaningless places: the table's centre, or the
    fixed solver's (0.5, 0.3125) at rest, 6 cm from the corner the force pressed it into, and
    nothing said so. Such an element is not stepped, and the step raises, naming it and the
    body; the other elements step."""
    world = _mallet_alone(solver, batch)
    velocities = np.zeros((batch, 1, 2))
    velocities[:, 0] = [1.0, 0.0]  # the others move
    if push == "speed":
        velocities[1, 0] = [1e12, 3e11]
    world.set_state(velocities=velocities)
    if push == "force":
        forces = np.zeros((batch, 1, 2))
        forces[1, 0] = [1e20, 3e19]
        world.set_force("mallet", forces[:, 0])
    positions = world.state.positions.copy()
    with pytest.raises(physics.SimulationError,
                       match=r"element\(s\) \[1\] not stepped: body 'mallet' would travel up to "
                             r"\S+ m in this 0.02 s step .* more than 2\*\*32 \(4.3e\+09\) times "
                             r"the walled table's half size \(0.4 m\)") as err:
        world.step(0.02)
    assert err.value.elements.tolist() == [1]
    assert isinstance(err.value, physics.SceneError)
    assert np.array_equal(world.state.positions[1], positions[1])
    assert np.array_equal(world.state.velocities[1], velocities[1])
    assert world.time[1] == 0.0 and world.time[0] == pytest.approx(0.02)
    assert world.state.positions[0, 0, 0] == pytest.approx(-0.4 + 0.02)
    assert world.last_step.contacts[1] == 0


@pytest.mark.parametrize("solver", [None, {"mode": "fixed", "substeps": 1}])
def test_the_travel_bound_is_where_float64_still_places_a_body_to_1e_6_of_the_table(solver):
    """Just under the bound (2**32 half sizes of travel, 1.7e9 m on a 0.8 m table: 8.5e10 m/s
    in 20 ms) the step is taken and the mallet ends on the table; just over, refused. The
    bound is the travel a step would take from the state and force, not the speed."""
    limit = 2.0 ** 32 * 0.4 / 0.02  # m/s
    for factor, refused in [(0.99, False), (1.01, True)]:
        world = _mallet_alone(solver)
        world.set_state(velocities=[[[limit * factor, 0.0]]])
        if refused:
            with pytest.raises(physics.SimulationError, match="not stepped"):
                world.step(0.02)
            continue
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", "step: element", RuntimeWarning)  # exact: capped
            world.step(0.02)
        x, y = world.state.positions[0, 0]
        assert abs(x) <= 0.56 + 1e-3 and abs(y) <= 0.36 + 1e-3
        assert np.isfinite(world.state.velocities).all()
    world = _mallet_alone(solver)  # a force that adds the travel: 0.5 F/m dt^2
    world.set_force("mallet", [2.0 * 1.01 * 2.0 ** 32 * 0.4 * 0.3 / 0.02 ** 2, 0.0])
    with pytest.raises(physics.SimulationError, match=r"speed 0 m/s.*force 2\.6e\+12 N"):
        world.step(0.02)


def test_a_restored_snapshot_recovers_from_the_error():
    world = physics.World("rod_control")
    snapshot = world.get_state()
    world.set_state(velocities=[[[1e160, 0.0], [0.0, 0.0]]])
    with pytest.raises(physics.SimulationError):
        world.step(0.02)
    world.restore(snapshot)
    world.step(0.02)
    assert np.isfinite(world.state.positions).all()


def test_a_force_beyond_what_the_step_resolves_warns_and_flags_the_element():
    """1e12 N on the 0.3 kg mallet, the rod between it and the cushion (1e15 N before the
    travel bound refused it): the settling needs ~5e7 substeps and takes 1e6; the mallet ends
    up past the rod (a tunnel), and the step says
    so. An ordinary step leaves the flag off."""
    world = physics.World("rod_control", batch_size=2)
    world.step(0.02)
    assert not world.last_step.capped.any()
    world.set_force("mallet", [[1e12, 0.0], [1.0, 0.0]])
    with pytest.warns(RuntimeWarning, match=r"element\(s\) \[0\]: .* cap of 1,000,000 "
                      r"substeps") as warned:
        world.step(0.02)
    # it names the caller's line (the warnings of world.step named lines inside it)
    assert [w.filename for w in warned] == [__file__]
    assert world.last_step.capped.tolist() == [True, False]
    assert world.last_step.fallback[0] and world.last_step.substeps[0] == 1_000_000
    assert not world.last_step.capped.flags.writeable



def test_the_cap_warning_names_the_fastest_body_counting_its_spin():
    """A pivoted rod spun at 1e6 rad/s against a post within its reach: its centre is at rest,
    its tips move at 2e5 m/s, and settling them would need ~5e6 substeps. The warning gave the
    fastest centre's speed ("now up to 0 m/s" here, 39 m/s in the fuzz case that showed it); it
    now gives the fastest point of a body's core, as the no-tunnelling bound sees it, and names
    the body."""
    scene = _walled(1.0, [
        {"name": "rotor", "shape": "rod", "length": 0.4, "thickness": 0.01,
         "mass": 0.1, "pivot": True, "angle": 1.0, "omega": 1e6},
        {"name": "post", "shape": "disk", "radius": 0.02, "static": True,
         "position": [0.1, 0.0]}])
    world = physics.World(scene)
    with pytest.warns(RuntimeWarning, match=r"now up to 2e\+05 m/s, body 'rotor'"):
        world.step(0.1)
    assert world.last_step.capped[0] and world.last_step.substeps[0] == 1_000_000


def test_a_force_the_settling_can_resolve_does_not_warn():
    """1e6 N on the mallet squeezing the rod against the cushion: ~5e4 settling substeps, within
    the cap; no warning, and no tunnel."""
    world = physics.World("rod_control")
    world.set_force("mallet", [1e6, 0.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.step(0.02)
    assert world.last_step.fallback[0] and not world.last_step.capped[0]
    rod, mallet = world.state.positions[0, :, 0]
    assert mallet < rod


def test_thin_rods_settle_without_the_cap():
    """A rod 50 um thick against a bare one, both fast, in 1 s steps (a case the fuzz test
    found): the settling's substeps keep the pair from closing by more than half the depth at
    which an overlap is still seen, which for two rods includes crossing cores (the shorter
    half-length), not only the thicknesses (50 um: 1e6 substeps, the cap, and a warning). No
    warning now, a few thousand substeps, no overlap and no energy gained."""
    scene = _walled(0.25, [
        {"name": "bare", "shape": "rod", "position": [0.15, 0.2], "angle": -0.65,
         "length": 0.08, "thickness": 0.0, "mass": 64.0, "omega": 15.0,
         "velocity": [18.9, -18.6]},
        {"name": "thin", "shape": "rod", "position": [0.45, -0.2], "angle": 0.18,
         "length": 0.2, "thickness": 5e-05, "mass": 2.75e-05, "omega": 62.4,
         "velocity": [15.3, 0.0]}])
    world = physics.World(scene)
    energy = world.kinetic_energy()[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        world.step(1.0)
    assert world.last_step.fallback[0] and not world.last_step.capped[0]
    assert world.last_step.substeps[0] < 10_000
    assert world.gaps().min() >= -1e-9
    assert world.kinetic_energy()[0] <= energy


@pytest.mark.parametrize("loop", ["pairs", "calendar"])
def test_a_settled_pile_is_handed_on_without_overlap(loop):
    """Four plastic disks driven into the top-right corner (a case the big fuzz test found): the
    rest of the step is settled, and in the pile (one disk pushing three along a cushion, the
    last sliding down the side cushion) a positional-correction sweep removes only ~1/6 of the
    overlap, so the 64 sweeps of a substep left 8.8e-9 m in the pose the step handed on, where
    the tolerance is 1e-9 m. The last substep now sweeps until the overlap is within the
    tolerance, on both of the exact solver's loops (every pair, and the event calendar of
    worlds with many bodies: four more disks at rest far away)."""
    disks = [((-0.45, 0.2), 0.09375, 0.1, (9.75, 2.0)), ((-0.15, -0.2), 0.0546875, 1.0, (7.0, 8.0)),
             ((0.15, 0.2), 0.0625, 0.1, (-2.0, 3.0)), ((0.45, -0.2), 0.0625, 1.0, (0.0, 8.0))]
    if loop == "calendar":
        disks += [((-0.5 + 0.1 * i, -0.35), 0.02, 1.0, (0.0, 0.0)) for i in range(4)]
    scene = _walled(0.0, [{"name": f"d{i}", "shape": "disk", "position": list(p), "radius": r,
                           "mass": m, "velocity": list(v)}
                          for i, (p, r, m, v) in enumerate(disks)])
    world = physics.World(scene)
    assert world.tolerance == 1e-9
    energy = world.kinetic_energy()[0]
    world.step(0.1)
    assert world.last_step.fallback[0] and not world.last_step.capped[0]
    assert world.gaps().min() >= -world.tolerance
    assert world.kinetic_energy()[0] <= energy
    world.step(0.1)  # and the next step starts from a legal pose
    assert np.isfinite(world.get_state()["state"]).all()
    assert world.gaps().min() >= -world.tolerance


@pytest.mark.parametrize("loop", ["pairs", "calendar"])
def test_a_light_disk_squeezed_by_a_heavy_one_never_passes_through_it(loop):
    """A 1e4 kg disk at 2 m/s drives a 1e-5 kg one into a cushion (mass ratio 1e9) in 0.1 s
    steps. The light disk shuttles between them ever faster; a step in which the gap closes runs
    out of events and is settled, and the light disk gets ~100 times faster within it. The
    settle planned its substeps once, from the speeds it started with, and in the third step
    the light disk passed through the heavy one, unflagged (in the envs' 20 ms steps: the 14th).
    The plan is now checked after every substep: the light disk stays between the heavy disk
    and the cushion, the heavy disk turns back, with no overlap, no energy gained and no
    warning, on both of the exact solver's loops (every pair, and the event calendar of worlds
    with many bodies: six more disks at rest, out of the way)."""
    bodies = [{"name": "heavy", "shape": "disk", "position": [0.0, 0.0], "radius": 0.05,
               "mass": 1e4, "velocity": [2.0, 0.0]},
              {"name": "light", "shape": "disk", "position": [0.4, 0.0], "radius": 0.01,
               "mass": 1e-5}]
    if loop == "calendar":
        bodies += [{"name": f"rest{i}", "shape": "disk", "position": [-0.5 + 0.1 * i, -0.3],
                    "radius": 0.02, "mass": 1.0} for i in range(6)]
    scene = _walled(1.0, bodies)
    world = physics.World(scene)
    energy = world.kinetic_energy()[0]
    contacts = settled = 0
    turned = False
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(30):
            world.step(0.1)
            contacts += int(world.last_step.contacts[0])
            settled += int(world.last_step.fallback[0])
            x = world.state.positions[0, :2, 0]
            assert x[1] > x[0], "the light disk passed through the heavy one"
            assert world.gaps().min() >= -world.tolerance
            assert world.kinetic_energy()[0] <= energy * (1 + 1e-12 * max(contacts, 1))
            turned |= world.state.velocities[0, 0, 0] < 0.0
    assert settled >= 1 and turned


def test_a_fast_puck_left_to_the_settle_keeps_bouncing_and_is_not_pinned_in_a_corner():
    """A puck at 1e5 m/s in a 1 m box runs out of ``max_events`` (1000 cushion bounces) within
    a 0.01 s step, and the rest of the step is settled. The settle's substeps ignored cushions
    (a half-plane is seen at any depth): 4 substeps of 60 m each, and the positional correction
    left the puck pinned in the corner (0.45, 0.45) step after step, at full speed. Now a body
    moves at most half its reach a substep against a cushion: it bounces on (fixed-step accuracy,
    flagged as settled) and keeps its speed (e = 1)."""
    v = np.array([1e5, 3e4])
    scene = {"table": {"size": [1.0, 1.0]}, "effects": ["rotation", "walls"],
             "solver": {"mode": "exact", "max_events": 1000},
             "bodies": [{"name": "a", "shape": "disk", "radius": 0.05, "mass": 1.0,
                         "velocity": v.tolist()}]}
    world = physics.World(scene)
    corner = 0.5 - 0.05
    seen = []
    for _ in range(3):
        world.step(0.01)
        assert world.last_step.fallback[0] and not world.last_step.capped[0]
        p = world.state.positions[0, 0].copy()
        assert not np.all(np.abs(p) > corner - 1e-6), p  # not pinned against two cushions
        assert np.hypot(*world.state.velocities[0, 0]) == pytest.approx(np.hypot(*v), rel=1e-12)
        assert all(np.hypot(*(p - q)) > 0.05 for q in seen)  # it moved on
        seen.append(p)


def _cores_crossed(world) -> bool:
    """The two rods' core segments cross (their capsules overlap by the whole thickness)."""
    segs = []
    for i in range(2):
        x, y = world.state.positions[0, i]
        a, h = world.state.angles[0, i], world.half_length[0, i]
        segs.append(((x - h * math.cos(a), y - h * math.sin(a)),
                     (x + h * math.cos(a), y + h * math.sin(a))))

    def side(p, q, r):
        return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])

    (p0, p1), (q0, q1) = segs
    return side(q0, q1, p0) * side(q0, q1, p1) < 0 and side(p0, p1, q0) * side(p0, p1, q1) < 0


def _rod(name, length, thickness, mass, position, angle, velocity, omega):
    return {"name": name, "shape": "rod", "length": length, "thickness": thickness, "mass": mass,
            "position": position, "angle": angle, "velocity": velocity, "omega": omega}


#: found by an adversarial walk (2026-11-26): plastic (e = 0) rods, one spinning fast. The
#: exact solver's settle crossed their cores (1 mm: after step 1; bare: after step 13): a crossed
#: pair read as a gap of -(r1 + r2) (0 for bare rods) with the line of centres for a normal, so
#: neither the impulses nor the positional correction could uncross it
CROSSING_RODS = {
    "1 mm rods": [
        _rod("A", 0.8205262186711123, 0.001, 1.0, [0, 0], 2.2205407365844625,
             [0.6940502169188439, -1.0018267766478062], -1.4993579919152804),
        _rod("B", 0.9210078027646625, 0.001, 8.099143076277485,
             [0.0037238675822159895, -0.2652091158436083], -0.32848853623386187,
             [1.8171009566239644, -0.3305654388931757], 113.29042627542499)],
    "zero-thickness rods": [
        _rod("A", 0.8969252603424266, 0.0, 1.0, [0, 0], -2.2069385043030216,
             [-0.8841350052967787, 0.5542878500339838], 23.51048883791098),
        _rod("B", 0.8844184503593422, 0.0, 0.0045949839781477325,
             [-0.38984969478325304, -0.18445088553019806], 1.6351707346116573,
             [-0.024892123415010837, 0.8436720675423006], 1.4943730130741593)],
}


@pytest.mark.parametrize("far", [False, True], ids=["alone", "with a far puck"])
@pytest.mark.parametrize("rods", list(CROSSING_RODS), ids=list(CROSSING_RODS))
def test_thin_rods_cores_never_cross_in_settled_steps(rods, far):
    """Alone, the 1 mm pair's sustained contact is held (``solvers._hold`` takes two rods since
    2026-11-29); a puck far away makes the world's contacts able to jam, and its steps settled,
    as every step that crossed them was."""
    puck = {"name": "far", "shape": "disk", "radius": 0.01, "mass": 0.1, "position": [50, 50]}
    world = physics.World({"effects": ["rotation"], "materials": {"restitution": 0.0},
                           "bodies": CROSSING_RODS[rods] + ([puck] if far else [])})
    settled = 0
    for _ in range(20):
        world.step(0.01)
        settled += int(world.last_step.fallback[0])
        assert not _cores_crossed(world)
    if far:
        assert settled > 0  # the steps that crossed them are still settled


@pytest.mark.parametrize("thickness", [0.0, 1e-6, 0.02])
@pytest.mark.parametrize("end", ["a", "b"])
def test_crossed_cores_get_their_depth_and_the_normal_that_uncrosses_them(thickness, end):
    """Rod a along x (half-length 1), rod b along y crossing it: the shallowest end is a's right
    end 0.1 m past b's line (``end`` a), or b's lower end 0.05 m past a's line (``end`` b). The
    gap is minus that depth less the radii, the normal (a to b) the one that moves that end back,
    the closest points that end and its foot on the other line."""
    r = thickness / 2
    if end == "a":
        got = contacts.capsule_capsule(0.0, 0.0, 0.0, 1.0, r, 0.9, 0.0, math.pi / 2, 1.0, r)
        want = (-0.1 - 2 * r, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, -0.1 - 2 * r)
    else:
        got = contacts.capsule_capsule(0.0, 0.0, 0.0, 1.0, r, 0.0, 0.95, math.pi / 2, 1.0, r)
        want = (-0.05 - 2 * r, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, -0.05 - 2 * r)
    assert got == pytest.approx(want, abs=1e-15)
    # moved by the depth along the normal (b) they touch, their cores no longer crossed
    moved = (0.9 + 0.1, 0.0) if end == "a" else (0.0, 0.95 + 0.05)
    touching = contacts.capsule_capsule(0.0, 0.0, 0.0, 1.0, r, *moved, math.pi / 2, 1.0, r)
    assert touching[0] == pytest.approx(-2 * r, abs=1e-15)


def test_a_scene_of_crossed_bare_rods_is_refused_like_thick_ones():
    """Bare rods placed crossed (an X) read as touching (gap 0) and were accepted; the solver
    then slid one out through the other. Their gap is now minus their depth: refused."""
    bodies = [_rod("A", 0.4, 0.0, 1.0, [0.0, 0.0], 0.0, [0.0, 0.0], 0.0),
              _rod("B", 0.4, 0.0, 1.0, [0.05, 0.0], 1.2, [0.0, 1.0], 3.0)]
    with pytest.raises(physics.SceneError, match="'A' and 'B' overlap by 0.14"):
        physics.World({"effects": ["rotation"], "bodies": bodies})


_thin_rod = st.fixed_dictionaries({
    "length": st.floats(0.05, 0.9),
    "thickness": st.sampled_from([0.0, 1e-6, 1e-3]),
    "angle": st.floats(0, 2 * math.pi),
    "speed": st.floats(0.0, 3.0),
    "aim": st.floats(-0.3, 0.3),
})

_rod_pair = st.fixed_dictionaries({
    "rods": st.tuples(_thin_rod, _thin_rod),
    "log_mass_ratio": st.floats(-3.0, 3.0),
    "spin": st.floats(10.0, 300.0),  # rad/s, the fast rod's
    "other_spin": st.floats(-20.0, 20.0),
    "fast": st.sampled_from([0, 1]),
    "e": st.sampled_from([0.0, 0.1, 1.0]),
    "direction": st.floats(0, 2 * math.pi),
})


@settings(max_examples=60)
@given(_rod_pair)
def test_thin_rods_never_cross_property(s):
    """Random pairs of thin (1 mm, 1 um) and bare rods thrown at each other, one spinning fast,
    masses 1e-3..1e3 apart, e in {0, 0.1, 1}, in 0.01 s steps: their cores never cross, the
    state stays finite, momentum is kept to round-off and kinetic energy never grows."""
    rods = s["rods"]
    reach = sum(r["length"] / 2 + r["thickness"] for r in rods)
    c = reach + 0.02
    phi = s["direction"]
    bodies = []
    for i, r in enumerate(rods):
        side = -1 if i == 0 else 1
        x, y = side * c / 2 * math.cos(phi), side * c / 2 * math.sin(phi)
        heading = phi + (0.0 if i == 0 else math.pi) + r["aim"]
        omega = s["spin"] if i == s["fast"] else s["other_spin"]
        bodies.append(_rod(f"r{i}", r["length"], r["thickness"],
                           10.0 ** s["log_mass_ratio"] if i else 1.0, [x, y], r["angle"],
                           [r["speed"] * math.cos(heading), r["speed"] * math.sin(heading)],
                           omega))
    world = physics.World({"effects": ["rotation"], "materials": {"restitution": s["e"]},
                           "bodies": bodies})
    p0 = world.momentum()[0].copy()
    e0 = world.kinetic_energy()[0]
    ps0, _ = _scales(world)
    n = 0
    for _ in range(30):
        n += len(world.step(0.01))
        assert np.isfinite(world.state.positions).all() and np.isfinite(world.state.omegas).all()
        assert not _cores_crossed(world)
        assert world.gaps().min() >= -max(world.tolerance, 1e-9)
        assert np.abs(world.momentum()[0] - p0).max() <= 1e-12 * max(n, 1) * max(
            ps0, _scales(world)[0])
        assert world.kinetic_energy()[0] <= e0 * (1 + 1e-12 * max(n, 1))


@pytest.mark.parametrize("ratio", [1e9, 1e10])
def test_a_light_rod_jammed_against_a_cushion_keeps_the_heavy_disk_s_energy_at_the_defaults(
        ratio):
    """A 1 g rod standing against a cushion, struck 5 cm off its centre by a disk ``ratio``
    times heavier at 2 m/s (e = 1), needs ~1,100 events in one step at 1e9 (as the square root
    of the ratio). At the old default ``max_events`` (1000) the rest of that step was settled,
    and the settle's sequential impulses pumped the rod: the disk left at 1.84 m/s instead of
    2, the rod at 2.4e4 m/s with 15 % of the energy (1e10: 1.29 m/s, 58 %), total energy right,
    only ``fallback`` telling (found by an engine walk). The default (10,000) keeps it exact."""
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.2, 0.8]},
             "materials": {"restitution": 1.0},
             "bodies": [{"name": "rod", "shape": "rod", "length": 0.2, "thickness": 0.01,
                         "mass": 1e-3, "position": [0.595, 0.0], "angle": math.pi / 2},
                        {"name": "disk", "shape": "disk", "radius": 0.1, "mass": 1e-3 * ratio,
                         "position": [0.3, 0.05], "velocity": [2.0, 0.0]}]}
    world = physics.World(scene)
    e0 = world.kinetic_energy()[0]
    for _ in range(15):
        world.step(0.01)
        assert not world.last_step.fallback[0]
    v = world.state.velocities[0]
    assert v[1] == pytest.approx([-2.0, 0.0], abs=1e-6)  # the disk reflects off the jam
    rod = 0.5 * 1e-3 * v[0] @ v[0] + 0.5 * world.inertia[0, 0] * world.state.omegas[0, 0] ** 2
    assert rod < 1e-6 * e0
    assert world.kinetic_energy()[0] == pytest.approx(e0, rel=1e-9)


def _two_disks(radius: float, tolerance: float, gap: float) -> dict:
    return {"solver": {"mode": "exact", "tolerance": tolerance},
            "bodies": [{"name": "s", "shape": "disk", "radius": radius, "mass": 1.0,
                        "position": [-(2 * radius + gap), 0.0], "velocity": [1.0, 0.0]},
                       {"name": "t", "shape": "disk", "radius": radius, "mass": 1.0}]}


def test_a_tolerance_larger_than_two_bodies_radii_warns_naming_them():
    """The exact solver's tolerance is a length: contacts are resolved up to it apart. Two
    0.1 mm disks at a tolerance of 1 mm collided at once, 8 radii apart (velocities 33 % off),
    without a word. A tolerance larger than a pair's radii together (the length over which
    their normal turns) now warns, naming ``solver.tolerance`` and the bodies, at the World
    and at an edit that shrinks them; through ``gym.make`` too. Below it nothing is said and
    the impulse comes at contact; two rods (a side's normal, flat) are not warned of."""
    import copy

    import gymnasium as gym

    from spinstrike import envs

    with pytest.warns(RuntimeWarning, match=r"solver\.tolerance: 0\.001 m is larger than the "
                      r"radii of bodies 's' and 't' together \(0\.0002 m\)"):
        w = physics.World(_two_disks(1e-4, 1e-3, 8e-4))
    assert len(w.step(1e-6)) == 1  # still resolved at a distance: it is a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w = physics.World(_two_disks(1e-3, 1e-4, 8e-4))  # 20x below the radii: quiet
        c = w.step(2e-3)
        assert len(c) == 1 and c.time[0] == pytest.approx(8e-4, rel=1e-3)
        np.testing.assert_allclose(w.state.velocities[0], [[0, 0], [1, 0]], atol=1e-9)
        rods = {"solver": {"mode": "exact", "tolerance": 1e-3},
                "bodies": [{"name": "a", "shape": "rod", "length": 1e-6, "thickness": 1e-6,
                            "mass": 1.0},
                           {"name": "b", "shape": "rod", "length": 0.1, "thickness": 0.0,
                            "mass": 1.0, "position": [0.0, 0.05]}]}
        physics.World(rods)  # two rods: a side's normal, which does not turn
        physics.World(_two_disks(1e-4, 1e-3, 8e-4), solver={"mode": "fixed"})  # no tolerance
    cap = {"solver": {"mode": "exact", "tolerance": 1e-3},
           "bodies": [{"name": "rod", "shape": "rod", "length": 0.02, "thickness": 2e-4,
                       "mass": 1.0},
                      {"name": "disk", "shape": "disk", "radius": 1e-4, "mass": 1e-3,
                       "position": [0.0, 0.05]}]}
    with pytest.warns(RuntimeWarning, match=r"bodies 'rod' and 'disk' together \(0\.0002 m\)"):
        physics.World(cap)  # a disk on a thin rod's end cap was 0.39 m/s off
    w = physics.World(_two_disks(1e-3, 1e-3, 8e-4))
    with pytest.warns(RuntimeWarning, match=r"bodies 's' and 't' together \(0\.0002 m\)"):
        with w.edit() as e:
            e.set_body("s", radius=1e-4)
            e.set_body("t", radius=1e-4)
    scene = copy.deepcopy(envs.config.load_packaged_scene("puck_speed"))
    for body in scene["bodies"]:
        body["radius"] = 0.002
    with pytest.warns(RuntimeWarning, match=r"solver\.tolerance: 0\.01 m is larger than the "
                      r"radii of bodies '\w+' and '\w+' together \(0\.004 m\)"):
        gym.make("SpinStrike/PuckSpeed-v1", scene=scene,
                 solver={"mode": "exact", "tolerance": 1e-2})


def test_a_cloth_deceleration_beyond_the_float_range_is_refused_naming_the_table():
    """``table.friction`` 1e308 (or friction and gravity of 1e300 each) was taken, and their
    product overflowed in the solver: a bare numpy warning and bodies stopped by an infinite
    deceleration. Now refused naming the field, from a scene, an edit and ``gym.make``; a
    large but finite one stops the bodies at once, quietly."""
    import gymnasium as gym

    body = [{"name": "a", "shape": "disk", "radius": 0.1, "mass": 1.0, "velocity": [1, 0],
             "omega": 3.0}]
    scene = {"effects": ["rotation", "table_friction"], "bodies": body}
    for table in ({"friction": 1e308}, {"friction": 1e300, "gravity": 1e300}):
        with pytest.raises(physics.SceneError, match=r"table: friction x gravity, the cloth's "
                           r"deceleration, must be a finite number"):
            physics.World({**scene, "table": table})
    w = physics.World({**scene, "table": {"friction": 0.1}})
    with pytest.raises(physics.SceneError, match=r"table\.friction: times gravity"):
        w.set_table(friction=1e308)
    assert w.table_mu[0] == 0.1
    with pytest.raises(Exception, match=r"table_friction|friction x gravity"):
        gym.make("SpinStrike/RodSpinControl-v0", table_friction=1e308)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        w = physics.World({**scene, "table": {"friction": 0.1, "gravity": 1e308}})
        w.step(0.01)
    assert not w.state.velocities.any() and not w.state.omegas.any()
