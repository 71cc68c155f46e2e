"""Many bodies: the exact solver's broadphase and event calendar (``physics.calendar``).

From ``layout.CALENDAR_BODIES`` bodies an exact world steps on the calendar instead of scanning
every pair at every event. It must find the very same events: worlds stepped both ways stay bit
for bit equal (pucks, rods, posts, a pivot, a driven mallet, cloth and contact friction, a
cradle of simultaneous contacts). And it keeps the physics exact on a crowded table: 64 pucks at
e = 1 over 500 steps keep their energy to 1e-12, never overlap and never leave the table.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.benchmarks.speed import _many_pucks_scene
from spinstrike.physics import layout
from spinstrike.physics import world as world_module


def _scan_world(scene: dict, **kwargs) -> physics.World:
    """The same world on the plain event loop (every pair scanned), whatever its size."""
    saved = world_module.CALENDAR_BODIES
    world_module.CALENDAR_BODIES = 10**9
    try:
        return physics.World(scene, **kwargs)
    finally:
        world_module.CALENDAR_BODIES = saved


def _mixed(n_pucks: int) -> dict:
    """Pucks around a rod, a static post, a pivoted arm and a driven mallet, with cloth and
    contact friction: every kind of body and flight the calendar must bound."""
    rng = np.random.default_rng(5)
    bodies = [
        {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1,
         "position": [0.0, 0.25], "velocity": [0.3, -0.4], "omega": 6.0},
        {"name": "post", "shape": "disk", "radius": 0.03, "static": True, "position": [0.3, -0.2]},
        {"name": "arm", "shape": "rod", "length": 0.2, "thickness": 0.01, "mass": 0.2,
         "pivot": True, "position": [-0.35, 0.2], "omega": 4.0},
        {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3, "driven": True,
         "position": [-0.4, -0.25]},
    ]
    side = int(np.ceil(np.sqrt(n_pucks)))
    for k in range(n_pucks):
        i, j = divmod(k, side)
        bodies.append({"name": f"p{k}", "shape": "disk", "radius": 0.025, "mass": 0.05,
                       "position": [-0.2 + 0.1 * i, -0.25 + 0.08 * j],
                       "velocity": rng.uniform(-2, 2, 2).tolist()})
    return {"table": {"size": [1.2, 0.8], "friction": 0.05},
            "effects": ["rotation", "walls", "contact_friction", "table_friction"],
            "materials": {"restitution": 0.9, "friction": 0.2}, "bodies": bodies}


def _cradle(n: int) -> dict:
    bodies = [{"name": f"d{k}", "shape": "disk", "radius": 0.03, "mass": 0.05,
               "position": [0.06 * k, 0.0]} for k in range(n)]
    bodies[0]["position"] = [-0.3, 0.0]
    bodies[0]["velocity"] = [2.0, 0.0]
    bodies[-1]["velocity"] = [-1.0, 0.0]
    return {"effects": ["rotation"], "bodies": bodies}


SCENES = {
    "pucks_16": (_many_pucks_scene(16), 40, False),
    "pucks_64": (_many_pucks_scene(64), 25, False),
    "mixed": (_mixed(12), 40, True),
    "cradle": (_cradle(9), 20, False),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_the_calendar_finds_the_same_events_bit_for_bit(name):
    scene, steps, push = SCENES[name]
    batch = 2
    fast = physics.World(scene, batch_size=batch)
    plain = _scan_world(scene, batch_size=batch)
    assert fast.flags.jam == layout.LEVEL_MANY_BODIES
    assert plain.flags.jam == layout.LEVEL_CAN_JAM
    rng = np.random.default_rng(11)
    vel = rng.uniform(-1.5, 1.5, (batch, fast.n_bodies, 2))
    vel *= ~(fast.static | fast.pivot | fast.driven)[None, :, None]
    vel[0] = fast.get_state()["state"][0, :, layout.VX:layout.VY + 1]  # the scene's own
    for w in (fast, plain):
        w.set_state(velocities=vel)
    contacts = 0
    for _ in range(steps):
        if push:
            force = rng.uniform(-4, 4, (batch, 2))
            for w in (fast, plain):
                w.set_force("mallet", force)
        cf = fast.step(0.02)
        cp = plain.step(0.02)
        np.testing.assert_array_equal(fast.get_state()["state"], plain.get_state()["state"])
        np.testing.assert_array_equal(cf.impulse, cp.impulse)
        np.testing.assert_array_equal(fast.last_step.events, plain.last_step.events)
        contacts += int(fast.last_step.contacts.sum())
    assert contacts > steps // 4  # the scene is crowded enough to test something


def test_64_elastic_pucks_keep_energy_and_the_table():
    scene = _many_pucks_scene(64)
    scene["materials"] = {"restitution": 1.0}
    world = physics.load_scene(scene)
    world = physics.World(world)
    assert world.flags.jam == layout.LEVEL_MANY_BODIES
    e0 = world.kinetic_energy()[0]
    reach = world.radius[0]
    half = world.table_half_size[0]
    tol = world.tolerance
    contacts = 0
    for _ in range(500):
        world.step(0.02)
        s = world.last_step
        assert not s.fallback.any()
        contacts += int(s.contacts.sum())
        assert world.gaps().min() >= -tol
        pos = world.state.positions[0]
        assert (np.abs(pos) <= half - reach[:, None] + tol).all()
    assert contacts > 1000
    assert abs(world.kinetic_energy()[0] - e0) <= 1e-12 * e0


def test_bodies_moved_by_the_user_are_re_sorted_bit_for_bit():
    """The sweep and prune keeps the bodies' order from step to step (an insertion sort from
    the last order): a user's edit that reverses it (every puck mirrored across the table)
    must still give the scan's events, bit for bit."""
    scene = _many_pucks_scene(64)
    fast = physics.World(scene)
    plain = _scan_world(scene)
    contacts = 0
    for k in range(30):
        if k == 10:
            for w in (fast, plain):
                pos = w.state.positions.copy()
                w.set_state(positions=pos * [-1.0, 1.0], velocities=-w.state.velocities)
        fast.step(0.02)
        plain.step(0.02)
        np.testing.assert_array_equal(fast.get_state()["state"], plain.get_state()["state"])
        contacts += int(fast.last_step.contacts.sum())
    assert contacts > 30


def test_a_mallet_driven_into_a_cushion_rests_there_the_same_way_on_both_loops():
    """The rest on a cushion (``solvers._rest_on_cushions``): the calendar finds the changed
    bodies' cushion pairs from its pair index, the scan from its pair list; the same rests, bit
    for bit, and the mallet does end up resting (so both paths ran it)."""
    scene = _many_pucks_scene(10)
    scene["materials"] = {"restitution": 0.5}
    scene["bodies"].append({"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3,
                            "driven": True, "position": [0.0, 0.0]})
    batch = 3
    fast = physics.World(scene, batch_size=batch)
    plain = _scan_world(scene, batch_size=batch)
    assert fast.flags.jam == layout.LEVEL_MANY_BODIES
    assert plain.flags.jam < layout.LEVEL_MANY_BODIES
    pushes = np.array([[5.0, 0.5], [-4.0, 3.0], [0.5, -5.0]])
    for w in (fast, plain):
        w.set_force("mallet", pushes)
    for _ in range(60):
        fast.step(0.02)
        plain.step(0.02)
        np.testing.assert_array_equal(fast.get_state()["state"], plain.get_state()["state"])
    np.testing.assert_array_equal(fast.forces, plain.forces)
    m = fast.names.index("mallet")
    rests = 0
    for b in range(batch):
        x, y = fast.state.positions[b, m]
        vx, vy = fast.state.velocities[b, m]
        on_side = abs(abs(x) - (fast.table_half_size[b, 0] - 0.04)) < 1e-9 and vx == 0.0
        on_end = abs(abs(y) - (fast.table_half_size[b, 1] - 0.04)) < 1e-9 and vy == 0.0
        rests += on_side or on_end
    assert rests >= 2


def _puck_gas(n_side: int, max_events=None) -> dict:
    """``n_side``^2 pucks at ~1 m/s in a walled box, 10 % free spacing, e = 1."""
    r, sp = 0.02, 2.1
    width = sp * r * n_side + sp * r
    height = math.sqrt(3) * sp / 2 * r * (n_side - 1) + sp * r
    rng = np.random.default_rng(2)
    bodies = [{"name": f"d{j}_{i}", "shape": "disk", "radius": r, "mass": 0.1,
               "position": [-width / 2 + sp * r * (i + 0.5 + 0.5 * (j % 2)),
                            -height / 2 + sp * r / 2 + math.sqrt(3) * sp / 2 * r * j],
               "velocity": rng.normal(size=2).tolist()}
              for j in range(n_side) for i in range(n_side)]
    solver = {"mode": "exact"} | ({} if max_events is None else {"max_events": max_events})
    return {"effects": ["rotation", "walls"], "table": {"size": [width, height]},
            "materials": {"restitution": 1.0}, "bodies": bodies, "solver": solver}


def test_a_large_world_gets_events_enough_to_stay_exact():
    """``max_events`` was 1000 a step whatever the number of bodies: 256 pucks in a box at
    e = 1 make ~1200 events a 0.01 s step, so every step ran out and was settled by fixed
    substeps (not exact, and 4x slower), with nothing to tell but ``last_step.fallback``. The
    default is now 10,000 (1000 until 2026-11-28) or 20 per body, whichever is more; a value
    given is kept as given."""
    world = physics.World(_puck_gas(16))
    assert world.n_bodies == 256 and world.solver.max_events is None
    e0 = world.kinetic_energy()[0]
    events = []
    for _ in range(4):
        world.step(0.01)
        assert not world.last_step.fallback[0]
        events.append(int(world.last_step.events[0]))
    assert max(events) > 1000  # (what the old default ran out at)
    assert world.kinetic_energy()[0] == pytest.approx(e0, rel=1e-12)
    capped = physics.World(_puck_gas(16, max_events=1000))
    capped.step(0.01)
    assert capped.last_step.fallback[0] and capped.last_step.events[0] == 1000


def _inelastic_pile(n: int) -> dict:
    """n pucks (2 mm and 1 cm) and bare rods, masses 1e-3 to 1e3 kg, thrown at the centre of a
    walled box at e = 0: a collapse whose steps are mostly settled, with corrections deep
    enough to move a body by more than the pair list's margin (a quarter of the 2 mm puck's
    reach)."""
    rng = np.random.default_rng(3)
    side = math.ceil(math.sqrt(n))
    bodies = []
    for k in range(n):
        x, y = (k % side - (side - 1) / 2) * 0.03, (k // side - (side - 1) / 2) * 0.03
        body = {"name": f"b{k}", "mass": float(10 ** rng.uniform(-3, 3)), "position": [x, y],
                "velocity": [-20 * x, -20 * y]}
        if k % 3 == 2:
            body.update(shape="rod", length=0.02, thickness=0.0, angle=float(rng.uniform(0, 3)))
        else:
            body.update(shape="disk", radius=float(rng.choice([0.002, 0.01])))
        bodies.append(body)
    size = 0.03 * side + 0.05
    return {"effects": ["rotation", "walls"], "table": {"size": [size, size]},
            "materials": {"restitution": 0.0}, "bodies": bodies}


@pytest.mark.parametrize("solver", [None, {"mode": "fixed", "substeps": 4}],
                         ids=["exact settle", "fixed"])
@pytest.mark.parametrize("n", [12, 80])
def test_settles_and_fixed_substeps_visit_close_pairs_only_bit_for_bit(solver, n):
    """From ``layout.CALENDAR_BODIES`` bodies the exact solver's settling and the fixed solver
    sweep only the pairs close enough to touch (``calendar.close_pairs``, made after each
    substep's drift and again whenever the positional correction may have moved a body by the
    list's margin, also within a correction sweep), not all N^2 pairs: 30x faster settled
    steps at 400 bodies, 100x faster fixed steps. Stepped with every pair visited, the same
    world must give the same states bit for bit. (With ``NUMBA_DISABLE_JIT`` the 12-body pile
    was seen to remake the list within a correction: 9 times in its first 114 settling
    substeps, and 15 times in 40 fixed ones; the 80-body fixed pile failed while the list was
    remade only between sweeps, its single sweep moving bodies farther than the margin.)"""
    scene = _inelastic_pile(n)
    if solver is not None:
        scene["solver"] = solver
    batch = 2
    fast = physics.World(scene, batch_size=batch)
    plain = _scan_world(scene, batch_size=batch)
    assert fast.flags.jam == layout.LEVEL_MANY_BODIES
    assert plain.flags.jam == layout.LEVEL_CAN_JAM
    vel = fast.state.velocities.copy()
    vel[1] *= -0.5  # the second element flies apart first, then back against the cushions
    for w in (fast, plain):
        w.set_state(velocities=vel)
    settled = 0
    for _ in range(30):
        fast.step(0.01)
        plain.step(0.01)
        np.testing.assert_array_equal(fast.get_state()["state"], plain.get_state()["state"])
        np.testing.assert_array_equal(fast.last_step.contacts, plain.last_step.contacts)
        settled += int(np.count_nonzero(fast.last_step.fallback))
    if solver is None:
        assert settled >= 20  # the settle ran
