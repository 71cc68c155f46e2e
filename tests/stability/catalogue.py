"""The named catalogue of hard cases (issue 7): one entry per case, each a physical law or an exact
expected value, measured by simulation on every solver that claims to support it.

Each :class:`Case` has a ``name``, a one-line ``title``, ``checks`` (the law, in words) and one
:class:`Claim` per solver: the bound the measured worst error must respect (``<=``), or, for a
documented limitation such as the fixed solver's tunnelling, the value it must reach (``>=``).
``case.measure(solver)`` runs the scenes and returns a :class:`Measurement` (the worst error and a
few notes). ``tests/stability/test_catalogue.py`` turns every (case, solver) into a test;
``python -m tests.stability.report`` writes the same measurements into ``docs/stability.md``.

Solvers: ``exact`` is the scene's default (tolerance 1e-9 m); ``fixed`` and ``pymunk`` use the
settings in :data:`SOLVERS` unless a case says otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from spinstrike import physics
from spinstrike.physics import SceneError
from spinstrike.physics.analytic import rod_strike_light_rod, rod_wall

__all__ = ["CASES", "SOLVERS", "Case", "Claim", "Measurement", "by_name"]

#: solver blocks used by the catalogue (None: the scene's exact solver)
SOLVERS: dict[str, dict | None] = {
    "exact": None,
    "fixed": {"mode": "fixed", "substeps": 100},
    "pymunk": {"mode": "pymunk", "substeps": 10, "iterations": 10},
}


@dataclass(frozen=True)
class Measurement:
    """What one (case, solver) measured: the worst error and short notes for the table."""

    worst: float
    notes: str = ""


@dataclass(frozen=True)
class Claim:
    """What a solver promises on a case: ``worst <= bound`` (``at_least``: ``worst >= bound``)."""

    bound: float
    at_least: bool = False
    meaning: str = ""

    def holds(self, worst: float) -> bool:
        if not math.isfinite(worst):
            return False
        return worst >= self.bound if self.at_least else worst <= self.bound


@dataclass(frozen=True)
class Case:
    name: str
    title: str
    checks: str
    unit: str
    run: Callable[[str], Measurement]
    claims: dict[str, Claim] = field(default_factory=dict)
    #: what is checked, in a few words (the README's compact table)
    brief: str = ""

    def measure(self, solver: str) -> Measurement:
        if solver not in self.claims:
            raise KeyError(f"{self.name}: no claim for solver {solver!r}")
        return self.run(solver)


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------


def _world(scene: dict, solver: str, batch_size: int = 1, **override) -> physics.World:
    block = SOLVERS[solver]
    if override:
        block = dict(block or {"mode": "exact"}, **override)
    return physics.World(scene, batch_size=batch_size, solver=block)


def _finite(world: physics.World) -> bool:
    return bool(np.all(np.isfinite(world.get_state()["state"])))


def _seed_scene(theta, m1, m2, r=0.2, V=1.0, gap=0.05, thickness=1e-3, radius=0.005, e=1.0,
                inertia="thin_rod"):
    """Seed §1: a rod (axis (sin theta, cos theta)) slides at V along +x; its upper tip strikes
    a resting disk centred on the velocity line through the tip's end cap, ``gap`` ahead."""
    angle = math.pi / 2 - theta
    tip = (r * math.cos(angle), r * math.sin(angle))
    rod = {"name": "rod", "shape": "rod", "length": 2 * r, "thickness": thickness, "mass": m1,
           "angle": angle, "velocity": [V, 0.0]}
    if inertia is not None:
        rod["inertia"] = inertia
    return {
        "effects": ["rotation"],
        "materials": {"restitution": e},
        "bodies": [rod, {"name": "disk", "shape": "disk", "radius": radius, "mass": m2,
                         "position": [tip[0] + thickness / 2 + radius + gap, tip[1]]}],
    }


def _seed_closed_form(m1, m2, r, theta, V):
    """Seed §1 (e = 1), written out directly from docs/design.md §2 so that no term cancels:
    (V1, V2, omega1 signed CCW for the set-up of :func:`_seed_scene`)."""
    c = math.cos(theta)
    den = m1 + (3 * c * c + 1) * m2
    return ((m1 + (3 * c * c - 1) * m2) / den * V, 2 * m1 / den * V, 6 * m2 * c * V / (den * r))


def _rel(a, b, scale):
    return abs(a - b) / scale


def _conservation(world, p0, e0, scale_p, elastic=True):
    """Relative drift of linear momentum and (elastic) kinetic energy."""
    dp = np.abs(world.momentum()[0] - p0).max() / scale_p
    de = abs(world.kinetic_energy()[0] - e0) / e0 if elastic else 0.0
    return max(dp, de)


# ---------------------------------------------------------------------------------------------
# 1. extreme mass ratios and the seed's light-rod limit
# ---------------------------------------------------------------------------------------------

RATIOS = [10.0**k for k in range(-12, 13, 3)]
THETAS = [0.0, 30.0, 60.0, 89.0]


def _mass_ratios(solver: str) -> Measurement:
    worst = 0.0
    where = ""
    for ratio in RATIOS:
        for th in THETAS:
            theta = math.radians(th)
            m1, m2, r, V = ratio, 1.0, 0.2, 1.0
            world = _world(_seed_scene(theta, m1, m2, r=r, V=V), solver)
            p0 = world.momentum()[0].copy()
            e0 = world.kinetic_energy()[0]
            scale_p = m1 * V + m2 * 2 * V
            world.step(0.06)
            if not _finite(world):
                return Measurement(math.inf, f"NaN at m1/m2 = {ratio:g}, theta = {th} deg")
            v = world.state.velocities[0]
            w = world.state.omegas[0]
            if solver == "exact":
                V1, V2, W1 = _seed_closed_form(m1, m2, r, theta, V)
                err = max(_rel(v[0, 0], V1, V), _rel(v[1, 0], V2, V2),
                          _rel(w[0], W1, abs(W1) if W1 else V / r),
                          abs(v[0, 1]) / V, abs(v[1, 1]) / V, abs(w[1]) * r / V)
            else:
                err = _conservation(world, p0, e0, scale_p)
            if err > worst:
                worst, where = err, f"m1/m2 = {ratio:g}, theta = {th:g} deg"
    return Measurement(worst, f"worst at {where}; ratios 1e-12..1e12, theta 0..89 deg")


def _light_rod_limit(solver: str) -> Measurement:
    worst = 0.0
    for th in (0.0, 40.0, 80.0):
        theta = math.radians(th)
        for ratio in (1e-12, 1e-15):
            world = _world(_seed_scene(theta, ratio, 1.0), solver)
            world.step(0.06)
            V1, V2, W1 = rod_strike_light_rod(theta, 1.0, 0.2)
            v = world.state.velocities[0]
            # the limit differs from the finite ratio by O(m1/m2): that is the bound's floor
            err = max(abs(v[0, 0] - V1), abs(v[1, 0] - V2), abs(abs(world.state.omegas[0, 0])
                                                               - W1) * 0.2)
            worst = max(worst, err)
    return Measurement(worst, "m1/m2 = 1e-12 and 1e-15 vs physics.analytic.rod_strike_light_rod")


# ---------------------------------------------------------------------------------------------
# 2. static walls, static posts and pivots (inverse mass 0)
# ---------------------------------------------------------------------------------------------


def _rod_wall_scene(theta, e, r=0.2, m=0.7, V=2.0):
    angle = math.pi / 2 - theta
    half_w = r * math.cos(angle) + 0.001 + 0.05
    return {"effects": ["rotation", "walls"], "table": {"size": [2 * half_w, 2.0]},
            "materials": {"restitution": e},
            "bodies": [{"name": "rod", "shape": "rod", "length": 2 * r, "thickness": 0.002,
                        "mass": m, "angle": angle, "velocity": [V, 0.0]}]}


def _post_scene(e):
    return {"effects": ["rotation"], "materials": {"restitution": e},
            "bodies": [{"name": "post", "shape": "disk", "radius": 0.05, "static": True},
                       {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.2,
                        "position": [-0.2, 0.0], "velocity": [1.5, 0.0]}]}


def _pivot_scene(e, lever=0.15):
    return {"effects": ["rotation"], "materials": {"restitution": e},
            "bodies": [{"name": "arm", "shape": "rod", "length": 0.4, "thickness": 0.01,
                        "mass": 0.3, "pivot": True},
                       {"name": "puck", "shape": "disk", "radius": 0.02, "mass": 0.1,
                        "position": [lever, -0.1], "velocity": [0.0, 2.0]}]}


def _static_and_pivots(solver: str) -> Measurement:
    worst = 0.0
    notes = []
    for e in (0.0, 0.5, 1.0):
        # a puck head-on into a static post: v' = -e v exactly, the post never moves
        world = _world(_post_scene(e), solver)
        world.step(0.2)
        v = world.state.velocities[0]
        err = max(_rel(v[1, 0], -e * 1.5, 1.5), abs(v[1, 1]) / 1.5,
                  float(np.abs(world.state.positions[0, 0]).max()), abs(v[0]).max())
        worst = max(worst, err)
        if solver == "pymunk":
            continue  # pymunk pins a pivot with a finite-mass joint (documented in its backend)
        # a puck into a pivoted arm at lever l: j = (1+e) v / (1/m + l^2/I), pivot fixed,
        # angular momentum about the pivot conserved
        world = _world(_pivot_scene(e), solver)
        inertia = world.inertia[0, 0]
        l0 = world.angular_momentum()[0]
        c = world.step(0.1)
        j = (1 + e) * 2.0 / (1 / 0.1 + 0.15**2 / inertia)
        w_arm = world.state.omegas[0, 0]
        v_puck = world.state.velocities[0, 1, 1]
        err = max(float(np.abs(world.state.positions[0, 0]).max()),
                  float(np.abs(world.state.velocities[0, 0]).max()))
        if e > 0:
            # e = 0: the turning arm keeps pushing the puck (a sliding contact, settled by
            # fixed substeps whose positional correction moves the puck, so L is not exact)
            err = max(err, abs(world.angular_momentum()[0] - l0) / (0.1 * 2.0 * 0.15))
        if solver == "exact":
            err = max(err, _rel(c.impulse[0], j, j))
            if e > 0:
                err = max(err, _rel(v_puck, 2.0 - j / 0.1, 2.0),
                          _rel(w_arm, j * 0.15 / inertia, 2.0 / 0.15))
        worst = max(worst, err)
    if solver == "exact":
        for th in (0.0, 20.0, 45.0, 70.0):
            for e in (0.3, 1.0):
                theta = math.radians(th)
                world = _world(_rod_wall_scene(theta, e), solver)
                c = world.step(0.05 / 2.0 + 1e-3)
                lever = 0.2 * math.cos(theta) if th > 0 else 0.0
                j, v_after, w_after = rod_wall(0.7, world.inertia[0, 0], lever, 2.0, e=e)
                err = max(_rel(c.impulse[0], j, j), _rel(world.state.velocities[0, 0, 0],
                                                         v_after, 2.0),
                          _rel(abs(world.state.omegas[0, 0]), w_after, 2.0 / 0.2))
                worst = max(worst, err)
        notes.append("rod into cushion vs physics.analytic.rod_wall (theta 0..70 deg)")
    notes.append("puck into static post (v' = -e v), post fixed")
    if solver != "pymunk":
        notes.append("puck into pivoted arm: pivot fixed, L about pivot conserved"
                     + (", j and spin vs closed form" if solver == "exact" else ""))
    return Measurement(worst, "; ".join(notes))


# ---------------------------------------------------------------------------------------------
# 3. grazing contact
# ---------------------------------------------------------------------------------------------


def _grazing(solver: str) -> Measurement:
    worst = 0.0
    # (a) a puck touching the bottom cushion (gap exactly 0) slides along it: nothing happens
    scene = {"effects": ["rotation", "walls"], "table": {"size": [2.0, 1.0]},
             "materials": {"restitution": 0.5},
             "bodies": [{"name": "puck", "shape": "disk", "radius": 0.05, "mass": 0.1,
                         "position": [-0.8, -0.45], "velocity": [1.0, 0.0]}]}
    world = _world(scene, solver)
    c = world.step(1.0)
    s = world.state
    worst = max(worst, float(len(c) and np.abs(c.impulse).max()), abs(s.velocities[0, 0, 0] - 1.0),
                abs(s.velocities[0, 0, 1]), abs(s.positions[0, 0, 0] - 0.2),
                abs(s.positions[0, 0, 1] + 0.45))
    # (b) a puck passes another exactly tangentially (gap 0 at closest approach, v ⟂ n)
    scene = {"effects": ["rotation"], "materials": {"restitution": 1.0},
             "bodies": [{"name": "a", "shape": "disk", "radius": 0.04, "mass": 0.1},
                        {"name": "b", "shape": "disk", "radius": 0.06, "mass": 0.3,
                         "position": [-0.5, 0.1], "velocity": [1.0, 0.0]}]}
    world = _world(scene, solver)
    c = world.step(1.0)
    s = world.state
    worst = max(worst, float(len(c) and np.abs(c.impulse).max()), abs(s.velocities[0, 1, 0] - 1),
                abs(s.velocities[0, 1, 1]), float(np.abs(s.velocities[0, 0]).max()),
                abs(s.positions[0, 1, 0] - 0.5))
    if solver == "exact":
        # (c) approach speed -> 0: a puck meets the cushion at 1e-3..1e-12 rad from tangent;
        # vn' = -e vn, the tangential velocity untouched, no sticking
        # (1e-12 rad is below the engine's round-off floor, events.ROUNDOFF: a normal speed
        # under 1e-12 of the point speeds counts as 0, so that pass is a touching slide)
        for k in (3, 6, 9, 11):
            alpha = 10.0**-k
            for e in (0.0, 1.0):
                vt, vn = math.cos(alpha), math.sin(alpha)
                y0 = -0.45 + 0.5 * vn  # reaches the cushion after 0.5 s
                scene = {"effects": ["rotation", "walls"], "table": {"size": [4.0, 1.0]},
                         "materials": {"restitution": e},
                         "bodies": [{"name": "puck", "shape": "disk", "radius": 0.05,
                                     "mass": 0.1, "position": [-1.5, y0],
                                     "velocity": [vt, -vn]}]}
                world = _world(scene, solver)
                world.step(1.0)
                v = world.state.velocities[0, 0]
                err = max(abs(v[0] - vt), abs(v[1] - e * vn) / vn,
                          abs(world.state.positions[0, 0, 0] - (-1.5 + vt)))
                if not world.gaps().min() >= -1e-9:
                    err = math.inf
                worst = max(worst, err)
        # (d) below that floor, a puck grazing a free rod at 1e-12 rad: plastic and held, no
        # record pulling (walk W28b F3: -2e-21 N s), momentum kept (relative to m v)
        for e in (0.5, 1.0):
            scene = {"effects": ["rotation"], "materials": {"restitution": e},
                     "bodies": [{"name": "rod", "shape": "rod", "length": 0.4,
                                 "thickness": 0.02, "mass": 0.1},
                                {"name": "puck", "shape": "disk", "radius": 0.02, "mass": 0.05,
                                 "position": [-0.15, 0.03 + 0.15e-12],
                                 "velocity": [1.0, -1e-12]}]}
            world = _world(scene, solver)
            p0 = world.momentum()[0]
            c = world.step(0.3)
            err = float(np.abs(world.momentum()[0] - p0).max() / 0.05)
            worst = max(worst, err if len(c) and c.impulse.min() >= 0 else math.inf)
    return Measurement(worst, "touching + sliding along a cushion; exact tangential pass"
                       + ("; approach angle 1e-3..1e-11 rad, e = 0 and 1 (vn' = -e vn, "
                          "relative to vn); a puck grazing a free rod at 1e-12 rad (plastic, "
                          "no impulse < 0, momentum)" if solver == "exact" else ""))


# ---------------------------------------------------------------------------------------------
# 4. theta -> 90 deg, zero-thickness and very long rods
# ---------------------------------------------------------------------------------------------


def _theta_90(solver: str) -> Measurement:
    worst = 0.0
    m1, m2, r, V = 1.0, 0.5, 0.2, 1.0
    for k in list(range(1, 13, 2)) + [None]:
        theta = math.pi / 2 - (10.0**-k if k is not None else 0.0)
        world = _world(_seed_scene(theta, m1, m2, r=r, V=V), solver)
        world.step(0.06)
        V1, V2, W1 = _seed_closed_form(m1, m2, r, theta, V)
        v = world.state.velocities[0]
        w = world.state.omegas[0, 0]
        err = max(_rel(v[0, 0], V1, V), _rel(v[1, 0], V2, V), abs(w - W1) * r / V)
        if k is None and w != 0.0:  # end-on: lever arm exactly 0, so no spin at all
            err = max(err, math.inf)
        worst = max(worst, err)
    return Measurement(worst, "theta = 90 deg - 1e-1..1e-11 rad and exactly 90 deg (omega == 0)")


def _tip_on_side(solver, thickness, tol, e=0.7, v=1.5):
    """Relative velocity and spin error of rod A's lower tip striking the side of rod B (at rest,
    along x) at 1.5 m/s straight down, against the impulse law with n = (0, -1)."""
    ha, hb, ang, xc, ma, mb = 0.15, 0.2, math.pi / 3, 0.05, 0.2, 0.5
    centre = [xc + ha * math.cos(ang), thickness + ha * math.sin(ang) + 0.1]  # A's, 0.1 up
    scene = {"effects": ["rotation"], "materials": {"restitution": e},
             "bodies": [{"name": "A", "shape": "rod", "length": 2 * ha, "thickness": thickness,
                         "mass": ma, "angle": ang, "position": centre, "velocity": [0.0, -v]},
                        {"name": "B", "shape": "rod", "length": 2 * hb, "thickness": thickness,
                         "mass": mb}]}
    world = _world(scene, solver, tolerance=tol)
    ia, ib = world.inertia[0]
    world.step(0.1)
    la, lb = ha * math.cos(ang), -xc  # lever arms r x n of A's tip and of B's struck point
    j = (1 + e) * v / (1 / ma + 1 / mb + la**2 / ia + lb**2 / ib)
    expected = np.array([0.0, -v + j / ma, 0.0, -j / mb, -la * j / ia * ha, lb * j / ib * hb])
    s = world.state
    got = np.array([*s.velocities[0, 0], *s.velocities[0, 1], s.omegas[0, 0] * ha,
                    s.omegas[0, 1] * hb])
    return float(np.abs(got - expected).max() / v)


def _rods_thin_and_long(solver: str) -> Measurement:
    worst = 0.0
    # zero thickness: the capsule's default inertia is the thin rod's, the seed forms hold
    for th in (0.0, 45.0):
        theta = math.radians(th)
        scene = _seed_scene(theta, 1.0, 0.3, thickness=0.0, inertia=None)
        world = _world(scene, solver)
        world.step(0.06)
        V1, V2, W1 = _seed_closed_form(1.0, 0.3, 0.2, theta, 1.0)
        v = world.state.velocities[0]
        worst = max(worst, _rel(v[0, 0], V1, 1.0), _rel(v[1, 0], V2, 1.0),
                    abs(world.state.omegas[0, 0] - W1) * 0.2)
    # very long (1 km) and very short (1 um) rods
    for r, gap in ((500.0, 0.05), (5e-7, 1e-7)):
        theta = math.radians(30.0)
        world = _world(_seed_scene(theta, 1.0, 0.3, r=r, gap=gap, thickness=1e-3 * r,
                                   radius=1e-3 * r + 1e-9), solver)
        world.step(2 * gap + 1e-3 * r)
        V1, V2, W1 = _seed_closed_form(1.0, 0.3, r, theta, 1.0)
        v = world.state.velocities[0]
        worst = max(worst, _rel(v[0, 0], V1, 1.0), _rel(v[1, 0], V2, 1.0),
                    abs(world.state.omegas[0, 0] - W1) * r)
    # the tip of a bare (or 1 um) rod striking the side of another, at tolerances 1e-3..1e-12 m:
    # the impulse law with the struck rod's perpendicular as the normal (the normal was the core
    # offset over the core distance, which for bare rods is the gap: 2.4e-4 off at 1e-12 m)
    for thickness in (0.0, 1e-6):
        for tol in (1e-3, 1e-9, 1e-12):
            worst = max(worst, _tip_on_side(solver, thickness, tol))
    # two zero-thickness rods in a T (tip into the middle), spinning: p, L, E conserved
    scene = {"effects": ["rotation"], "materials": {"restitution": 1.0},
             "bodies": [{"name": "a", "shape": "rod", "length": 0.4, "thickness": 0.0,
                         "mass": 0.2},
                        {"name": "b", "shape": "rod", "length": 0.3, "thickness": 0.0,
                         "mass": 0.1, "angle": math.pi / 2, "position": [0.05, 0.2],
                         "velocity": [0.0, -1.0], "omega": 0.5}]}
    world = _world(scene, solver)
    p0, l0, e0 = world.momentum()[0].copy(), world.angular_momentum()[0], world.kinetic_energy()[0]
    c = world.step(0.2)
    if len(c) == 0:
        return Measurement(math.inf, "the zero-thickness rods passed through each other")
    worst = max(worst, np.abs(world.momentum()[0] - p0).max() / 0.1,
                abs(world.angular_momentum()[0] - l0) / (0.1 * 0.3),
                abs(world.kinetic_energy()[0] - e0) / e0)
    # a zero-thickness rod lying flat against a cushion turns its end into it: no overlap ever
    # (the flat contact's gap is the nearer end's; the middle's hid 1e-6 h of penetration)
    for omega in (1e-3, 1.0):
        scene = {"effects": ["rotation", "walls"], "table": {"size": [1.2, 0.8]},
                 "materials": {"restitution": 0.0},
                 "bodies": [{"name": "r", "shape": "rod", "length": 0.2, "thickness": 0.0,
                             "mass": 0.1, "position": [0.6, 0.0], "angle": math.pi / 2,
                             "omega": omega, "velocity": [1e-3, 0.0]}]}
        world = _world(scene, solver)
        for _ in range(20):
            world.step(0.05)
            if world.gaps().min() < -1e-9:
                worst = math.inf
    return Measurement(worst, "thickness 0 vs seed forms; r = 500 m and 5e-7 m vs seed forms; "
                       "a bare and a 1 um rod's tip onto another's side at tolerance 1e-3, "
                       "1e-9, 1e-12 m vs the impulse law; "
                       "two zero-thickness rods: p, L, E (relative); a zero-thickness rod flat "
                       "on a cushion turning into it never overlaps beyond the tolerance")


# ---------------------------------------------------------------------------------------------
# 5. e = 0 and e = 1 on off-line disk-rod impacts
# ---------------------------------------------------------------------------------------------


def _offline_impacts(n=24, seed=7):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        out.append(dict(angle=rng.uniform(0, math.pi), omega=rng.uniform(-5, 5),
                        aim=rng.uniform(-0.15, 0.15), speed=rng.uniform(0.5, 3.0),
                        heading=rng.uniform(-0.6, 0.6), log_m=rng.uniform(-2, 2)))
    return out


def _restitution_limits(solver: str) -> Measurement:
    worst = 0.0
    for e in (0.0, 1.0):
        for imp in _offline_impacts():
            dx, dy = math.cos(imp["heading"]), math.sin(imp["heading"])
            start = np.array([imp["aim"] * -dy, imp["aim"] * dx]) - 0.35 * np.array([dx, dy])
            scene = {"effects": ["rotation"], "materials": {"restitution": e},
                     "bodies": [{"name": "rod", "shape": "rod", "length": 0.4,
                                 "thickness": 0.02, "mass": 0.1, "angle": imp["angle"],
                                 "omega": imp["omega"]},
                                {"name": "puck", "shape": "disk", "radius": 0.03,
                                 "mass": 0.1 * 10 ** imp["log_m"], "position": start.tolist(),
                                 "velocity": [imp["speed"] * dx, imp["speed"] * dy]}]}
            try:
                world = _world(scene, solver)
            except SceneError:
                continue  # the spinning rod's start pose overlaps the puck: not a case
            s0 = world.get_state()["state"][0].copy()
            e0 = world.kinetic_energy()[0]
            dt = 0.3
            c = world.step(dt)
            if len(c) != 1:
                continue  # no hit, or a second contact: the law is checked on single impacts
            t, p, n = c.time[0], c.point[0], c.normal[0]
            s1 = world.get_state()["state"][0]
            vs = []
            for state, x_at in ((s0, s0[:, :2] + s0[:, 3:5] * t),
                                (s1, s1[:, :2] - s1[:, 3:5] * (dt - t))):
                # point velocities at the contact, with the centres where they were at time t
                r = p - x_at
                vp = state[:, 3:5] + state[:, 5:6] * np.stack([-r[:, 1], r[:, 0]], 1)
                vs.append(float((vp[1] - vp[0]) @ n))
            scale = imp["speed"] + abs(imp["omega"]) * 0.21
            err = abs(vs[1] + e * vs[0]) / scale
            if e == 1.0:
                err = max(err, abs(world.kinetic_energy()[0] - e0) / e0)
            worst = max(worst, err)
    return Measurement(worst, "24 off-line disk-rod impacts (spinning rod, mass ratios 1e-2..1e2)"
                       " x e in {0, 1}: vn' + e vn at the contact point, and E for e = 1")


# ---------------------------------------------------------------------------------------------
# 6. very fast strikes (tunnelling)
# ---------------------------------------------------------------------------------------------


def _fast_scene(speed):
    return {"effects": ["rotation"], "materials": {"restitution": 1.0},
            "bodies": [{"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.001,
                        "mass": 0.1, "angle": math.pi / 2},
                       {"name": "puck", "shape": "disk", "radius": 0.01, "mass": 0.05,
                        "position": [-0.5, 0.05], "velocity": [speed, 0.0]}]}


FAST_FACTORS = [1e2, 1e4, 1e6]  # distance per step of 0.01 s, in puck radii


def _fast_strikes(solver: str) -> Measurement:
    """Exact: worst x-momentum error (all bounce back). Fixed/pymunk: fraction that tunnelled."""
    dt = 0.01
    worst = 0.0
    tunnelled = 0
    for factor in FAST_FACTORS:
        speed = factor * 0.01 / dt
        world = _world(_fast_scene(speed), solver,
                       **({"substeps": 1} if solver == "fixed" else {}))
        world.step(dt)
        if world.state.positions[0, 1, 0] > 0.0 and world.state.velocities[0, 1, 0] > 0.0:
            tunnelled += 1
        if solver == "exact":
            world.step(2 * 0.5 / speed)
            bounced = world.state.positions[0, 1, 0] < 0 and world.state.velocities[0, 1, 0] < 0
            err = abs(world.momentum()[0, 0] - 0.05 * speed) / (0.05 * speed)
            worst = max(worst, err if bounced else math.inf)
    if solver == "exact":
        return Measurement(worst, "puck moving 1e2..1e6 radii per step onto a 1 mm rod: every "
                           "one bounces back; worst relative x-momentum error")
    return Measurement(tunnelled / len(FAST_FACTORS),
                       "fraction of strikes at 1e2..1e6 radii per step that pass through the "
                       "rod (documented: tunnels once speed x substep > sum of radii)")


# ---------------------------------------------------------------------------------------------
# 7. simultaneous contacts
# ---------------------------------------------------------------------------------------------


def _row(n, gap=0.0, r=0.05, V=1.0):
    bodies = [{"name": f"d{i}", "shape": "disk", "radius": r, "mass": 1.0,
               "position": [2 * r * i + gap * i, 0.0]} for i in range(n)]
    bodies.insert(0, {"name": "s", "shape": "disk", "radius": r, "mass": 1.0,
                      "position": [-2 * r - 0.1, 0.0], "velocity": [V, 0.0]})
    return {"effects": ["rotation"], "materials": {"restitution": 1.0}, "bodies": bodies}


def _sequential_reference(x, v, m, r, e=1.0, sweeps=64):
    """Independent re-implementation of the documented rule for equal-radius disks in contact
    at one instant: sequential impulses swept in pair order until no pair approaches."""
    n = len(m)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)
             if np.linalg.norm(x[j] - x[i]) <= 2 * r + 1e-9]
    for _ in range(sweeps):
        hit = False
        for i, j in pairs:
            nrm = (x[j] - x[i]) / np.linalg.norm(x[j] - x[i])
            vn = (v[j] - v[i]) @ nrm
            if vn < 0:
                jj = -(1 + e) * vn / (1 / m[i] + 1 / m[j])
                v[i] -= jj * nrm / m[i]
                v[j] += jj * nrm / m[j]
                hit = True
        if not hit:
            break
    return v


def _simultaneous(solver: str) -> Measurement:
    worst = 0.0
    # (a) Newton's cradle: 4 touching disks struck by a fifth: all stop but the last (V)
    world = _world(_row(4), solver)
    e0 = world.kinetic_energy()[0]
    world.step(0.15)
    v = world.state.velocities[0, :, 0]
    expect = np.array([0.0, 0.0, 0.0, 0.0, 1.0])
    worst = max(worst, float(np.abs(v - expect).max()),
                abs(world.kinetic_energy()[0] - e0) / e0)
    # (b) a puck resting against a cushion is struck by an equal puck: the striker leaves at -V
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.0, 1.0]},
             "materials": {"restitution": 1.0},
             "bodies": [{"name": "a", "shape": "disk", "radius": 0.05, "mass": 1.0,
                         "position": [0.45, 0.0]},
                        {"name": "b", "shape": "disk", "radius": 0.05, "mass": 1.0,
                         "position": [0.0, 0.0], "velocity": [1.0, 0.0]}]}
    world = _world(scene, solver)
    world.step(0.4)
    v = world.state.velocities[0]
    worst = max(worst, float(np.abs(v[0]).max()), abs(v[1, 0] + 1.0), abs(v[1, 1]))
    # (c) a puck into a corner exactly at 45 deg meets both cushions at once: v -> -v
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.0, 1.0]},
             "materials": {"restitution": 1.0},
             "bodies": [{"name": "p", "shape": "disk", "radius": 0.05, "mass": 1.0,
                         "position": [0.0, 0.0], "velocity": [1.0, 1.0]}]}
    world = _world(scene, solver)
    world.step(0.6)
    v = world.state.velocities[0, 0]
    worst = max(worst, abs(v[0] + 1.0), abs(v[1] + 1.0))
    if solver == "exact":
        # (d) one puck strikes two touching pucks that sit symmetrically on its path: the
        # sequential rule's result, computed independently in pair order
        r = 0.05
        scene = {"effects": ["rotation"], "materials": {"restitution": 1.0},
                 "bodies": [{"name": "s", "shape": "disk", "radius": r, "mass": 1.0,
                             "position": [-0.3, 0.0], "velocity": [1.0, 0.0]},
                            {"name": "u", "shape": "disk", "radius": r, "mass": 2.0,
                             "position": [r * math.sqrt(3), r]},
                            {"name": "d", "shape": "disk", "radius": r, "mass": 0.5,
                             "position": [r * math.sqrt(3), -r]}]}
        world = physics.World(scene)
        m = np.array([1.0, 2.0, 0.5])
        p0 = world.momentum()[0].copy()
        e0 = world.kinetic_energy()[0]
        c = world.step(0.35)
        # the striker touches both when its centre reaches x = 0 (t = 0.3 s)
        t_hit = float(c.time[0])
        x0 = np.array([b["position"] for b in scene["bodies"]], dtype=float)
        x0[0, 0] += t_hit
        ref = _sequential_reference(x0, np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]]), m, r)
        simultaneous = np.all(np.abs(c.time - t_hit) == 0.0) and len(c) >= 2
        worst = max(worst, float(np.abs(world.state.velocities[0] - ref).max()),
                    float(np.abs(world.momentum()[0] - p0).max()),
                    abs(world.kinetic_energy()[0] - e0) / e0, 0.0 if simultaneous else math.inf)
    return Measurement(worst, "Newton's cradle (5 disks); puck against a cushion struck by a "
                       "puck; 45 deg corner hit (v -> -v)"
                       + ("; one puck into two at once vs an independent sequential-impulse "
                          "reference" if solver == "exact" else ""))


# ---------------------------------------------------------------------------------------------
# 8. a driven mallet pressing into a cushion: resting contact, Zeno bounces, Painleve
# ---------------------------------------------------------------------------------------------

TABLE = [1.2, 0.8]


def _mallet(position):
    return {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3, "driven": True,
            "position": position}


def _pressed_scenes():
    """(label, scene, force, effects-with-friction) for the sustained-load cases."""
    puck = {"name": "puck", "shape": "disk", "radius": 0.04, "mass": 0.05,
            "position": [0.5, 0.0]}
    rod = {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1,
           "position": [0.4, 0.2], "angle": 0.7}
    out = []
    for e in (0.0, 0.5, 0.9):
        out.append((f"puck into cushion e={e}",
                    {"table": {"size": TABLE}, "effects": ["rotation", "walls"],
                     "materials": {"restitution": e}, "bodies": [puck, _mallet([0.3, 0.0])]},
                    (2.0, 0.0)))
        out.append((f"rod into corner e={e}",
                    {"table": {"size": TABLE}, "effects": ["rotation", "walls"],
                     "materials": {"restitution": e}, "bodies": [rod, _mallet([0.1, 0.0])]},
                    (2.0, 1.5)))
    return out


def _painleve_scenes():
    """A rod leaning on the bottom cushion, pushed by the mallet so that it slides along it."""
    out = []
    for mu in (0.3, 0.8, 2.0):
        for e in (0.0, 0.5):
            angle = 0.6
            rod = {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1,
                   "position": [0.0, -0.4 + 0.01 + 0.15 * math.sin(angle)], "angle": angle}
            out.append((f"painleve mu={mu} e={e}",
                        {"table": {"size": TABLE},
                         "effects": ["rotation", "walls", "contact_friction"],
                         "materials": {"restitution": e, "friction": mu},
                         "bodies": [rod, _mallet([-0.25, -0.3])]},
                        (3.0, -1.0)))
    return out


def _loaded_run(scene, force, solver, steps=150, release=100, dt=0.02):
    """Push with ``force`` for ``release`` steps, then let go. Returns the worst numbers.

    * ``overlap``: deepest overlap (m) at any step's end;
    * ``gain_exact``: worst ``dKE - F.dx`` (J) over steps the event loop finished alone
      (round-off: the work of a constant force is exact, contacts never add energy);
    * ``gain_settled``: worst ``dKE - F.dx`` over steps that settled (fixed substeps of h), in
      units of ``|F| x budget``. There ``F.dx`` overstates nothing but misses the work of the
      kinematic motion that positional correction undid: a substep's correction moves the
      mallet back by at most the distance it moved into the contact in that substep,
      ``h |v'|`` with ``v'`` its velocity after the substep's kick. The budget is that distance
      summed over the step, ``dt (v + |F| h / m)`` with ``v = sqrt(2 KE_max / m)`` (kinetic
      energy bounds the mallet's speed; contacts never add any), plus 1e-9 m; <= 1 passes;
    * ``gain_free``: worst KE increase (relative) after the release (no force: nothing may add
      energy, settling included);
    * ``events``/``substeps``: most per step (cost).
    """
    world = _world(scene, solver)
    im = world.index("mallet")
    F = np.asarray(force, dtype=float)
    fnorm = float(np.linalg.norm(F))
    world.set_force("mallet", F)
    out = dict(overlap=0.0, gain_exact=0.0, gain_settled=0.0, gain_free=0.0, events=0,
               substeps=0, fallback=0, finite=True, escaped=False)
    hw = np.array(TABLE) / 2
    ke_max = 1e-12
    for k in range(steps):
        if k == release:
            world.set_force("mallet", [0.0, 0.0])
            F = np.zeros(2)
        e0 = world.kinetic_energy()[0]
        x0 = world.state.positions[0, im].copy()
        world.step(dt)
        if not _finite(world):
            out["finite"] = False
            break
        e1 = world.kinetic_energy()[0]
        gain = e1 - e0 - float(F @ (world.state.positions[0, im] - x0))
        ls = world.last_step
        out["overlap"] = max(out["overlap"], -float(world.gaps().min()))
        out["events"] = max(out["events"], int(ls.events[0]))
        out["substeps"] = max(out["substeps"], int(ls.substeps[0]))
        out["fallback"] += int(ls.fallback[0])
        pos = world.state.positions[0]
        if np.any(np.abs(pos) > hw):
            out["escaped"] = True
        ke_max = max(ke_max, e1)
        if k >= release:
            # relative to the largest kinetic energy of the run (a body at rest may jitter)
            out["gain_free"] = max(out["gain_free"], (e1 - e0) / ke_max)
        elif ls.fallback[0] or solver != "exact":
            h = dt / max(int(ls.substeps[0]), 1)
            speed = math.sqrt(2 * max(e0, e1) / 0.3) + fnorm * dt / 0.3
            budget = dt * (speed + fnorm * h / 0.3) + 1e-9
            out["gain_settled"] = max(out["gain_settled"], gain / (fnorm * budget))
        else:
            out["gain_exact"] = max(out["gain_exact"], gain / max(e1, e0, 1e-12))
    return out


def _sustained(scenes, solver: str) -> tuple[dict, str]:
    agg: dict = {}
    for _label, scene, force in scenes:
        r = _loaded_run(scene, force, solver)
        for key, value in r.items():
            if key in ("finite",):
                agg[key] = agg.get(key, True) and value
            elif key == "escaped":
                agg[key] = agg.get(key, False) or value
            else:
                agg[key] = max(agg.get(key, 0), value)
    return agg, ", ".join(s[0] for s in scenes)


def _sustained_measure(scenes, solver, limits) -> Measurement:
    agg, labels = _sustained(scenes, solver)
    if not agg["finite"] or agg["escaped"]:
        return Measurement(math.inf, f"NaN or escape: {agg}")
    if solver == "exact" and agg["fallback"] == 0:
        # the exact solver must detect the resting bounces and settle (flagged), not grind
        return Measurement(math.inf, "no step was settled (fallback never flagged)")
    # the worst error is the largest ratio of a measured number to its limit (<= 1 passes)
    ratios = {k: agg[k] / lim for k, lim in limits.items()}
    worst = max(ratios.values())
    notes = (f"overlap {agg['overlap']:.1e} m, energy gain beyond work {agg['gain_exact']:.1e} "
             f"(event steps, rel.) / {agg['gain_settled']:.2f} of the correction budget "
             f"(settled steps), after release {agg['gain_free']:.1e} (rel.), "
             f"<= {agg['events']} events and {agg['substeps']} substeps per step, "
             f"{agg['fallback']} settled steps")
    return Measurement(worst, notes)


#: limits of the sustained-load numbers per solver; the measurement is the largest ratio
SUSTAINED_LIMITS = {
    "exact": {"overlap": 1e-9, "gain_exact": 1e-12, "gain_settled": 1.0, "gain_free": 1e-12,
              "events": 1000, "substeps": 1000},
    "fixed": {"overlap": 5e-3, "gain_settled": 1.0, "gain_free": 1e-12},
    # pymunk rests deep in a loaded contact and its bias velocities may add a little energy
    "pymunk": {"overlap": 1.5e-2, "gain_free": 1e-4},
}


def _pressed(solver: str) -> Measurement:
    return _sustained_measure(_pressed_scenes(), solver, SUSTAINED_LIMITS[solver])


def _painleve(solver: str) -> Measurement:
    return _sustained_measure(_painleve_scenes(), solver, SUSTAINED_LIMITS[solver])


def _jam_scene(ratio, e, v=6.0):
    """A light puck resting against the left cushion; a heavy one drives into it along x."""
    return {"table": {"size": TABLE}, "effects": ["rotation", "walls"],
            "materials": {"restitution": e},
            "bodies": [{"name": "light", "shape": "disk", "radius": 0.05, "mass": 1.0 / ratio,
                        "position": [-0.55, 0.0]},
                       {"name": "heavy", "shape": "disk", "radius": 0.05, "mass": 1.0,
                        "position": [0.0, 0.0], "velocity": [-v, 0.0]}]}


def _sandwich_scene(ratio, v=1.0):
    """A light puck at rest between two heavy ones closing on it at v each (e = 1)."""
    return {"effects": ["rotation"], "materials": {"restitution": 1.0},
            "bodies": [{"name": "left", "shape": "disk", "radius": 0.1, "mass": 1.0,
                        "position": [-0.5, 0.0], "velocity": [v, 0.0]},
                       {"name": "light", "shape": "disk", "radius": 0.05, "mass": 1.0 / ratio,
                        "position": [0.0, 0.0]},
                       {"name": "right", "shape": "disk", "radius": 0.1, "mass": 1.0,
                        "position": [0.5, 0.0], "velocity": [-v, 0.0]}]}


def _jammed(solver: str) -> Measurement:
    """e = 0: both end at rest (exact: the heavy puck stops against a chain ending in a cushion);
    e = 1: the heavy puck leaves at +v (the chain reflects it), energy kept; never an overlap.
    And a light puck squeezed between two heavy ones at e = 1: they leave at -+v, E kept (the
    block solve of a matrix lost 2e-4 of E at a ratio of 1e12; now QR, physics.jam)."""
    worst = 0.0
    for ratio in (1e6, 1e9, 1e12):
        world = _world(_sandwich_scene(ratio), solver)
        e0 = world.kinetic_energy()[0]
        world.step(0.6)  # squeezed at t ~ 0.33 s
        v = world.state.velocities[0]
        err = max(abs(v[0, 0] + 1.0), abs(v[2, 0] - 1.0), 2 / ratio) - 2 / ratio
        err = max(err, abs(world.kinetic_energy()[0] - e0) / e0,
                  -min(float(world.gaps().min()), 0.0) / 1e-3)
        worst = max(worst, err if _finite(world) else math.inf)
    for ratio in (1e2, 1e4, 1e6, 1e9, 1e12):
        for e in (0.0, 1.0):
            world = _world(_jam_scene(ratio, e), solver)
            e0 = world.kinetic_energy()[0]
            world.step(0.2)  # the heavy puck arrives at t = 0.075 s
            v = world.state.velocities[0]
            if e == 0.0:
                err = float(np.abs(v).max()) / 6.0
            else:  # reflected at nearly its speed: the light puck takes at most 2/ratio of it
                err = max(max(6.0 * (1 - 2 / ratio) - v[1, 0], 0.0) / 6.0,
                          abs(world.kinetic_energy()[0] - e0) / e0)
            err = max(err, -min(float(world.gaps().min()), 0.0) / 1e-3)
            worst = max(worst, err if _finite(world) else math.inf)
    return Measurement(worst, "light puck against a cushion, heavy one (1e2..1e12 x) drives "
                       "into it at 6 m/s: e = 0 both stop, e = 1 the heavy one leaves at >= "
                       "6 (1 - 2/ratio) m/s with E kept (relative); a light puck squeezed by two "
                       "heavy ones (1e6..1e12 x) closing at 1 m/s, e = 1: they leave at -+1 m/s "
                       "(to 2/ratio), E kept; overlap in mm")


def plastic_row_scene(n: int, masses, cushion: bool, v: float = 10.0, e: float = 0.0,
                      dy=None) -> dict:
    """A touching row of n pucks (r = 1 cm, masses in kg, cycled), struck along it by a puck of
    the first mass at v; with ``cushion`` it rests on the right cushion of a 2.6 m table.
    ``dy``: each puck's offset off the line (a zig-zag row: contacts not collinear)."""
    r, width = 0.01, 2.6
    dy = dy or [0.0] * n
    x = [0.0]
    for k in range(1, n):  # each puck touching the one before
        x.append(x[-1] + math.sqrt((2 * r) ** 2 - (dy[k] - dy[k - 1]) ** 2))
    shift = width / 2 - r - x[-1] if cushion else -x[-1]
    bodies = [{"name": "s", "shape": "disk", "radius": r, "mass": masses[0],
               "position": [shift - 2 * r - 0.005, dy[0]], "velocity": [v, 0.0]}]
    bodies += [{"name": f"c{k}", "shape": "disk", "radius": r, "mass": masses[k % len(masses)],
                "position": [shift + x[k], dy[k]]} for k in range(n)]
    scene = {"effects": ["rotation"], "materials": {"restitution": e}, "bodies": bodies}
    if cushion:
        scene.update(table={"size": [width, 0.4]}, effects=["rotation", "walls"])
    return scene


def _plastic_rows(solver: str) -> Measurement:
    """Long plastic jams (the many-body walk W12): 50 touching 1 kg pucks on a cushion, struck
    along the row at 10 m/s, all stop in that step (the settle left 9 of the 10 kg m/s in
    bodies that did not move); a free row of 20 alternating 1 and 1/ratio kg moves off as one
    body, its centre of mass following P t / M (the settle's equal-share correction moved it
    0.43 m in 1 s at 1e6). Error: the speed left (of 10 m/s), the velocity spread and the
    centre of mass's error (of the distance travelled), overlap in mm."""
    world = _world(plastic_row_scene(50, [1.0], True), solver)
    world.step(0.004)
    worst = float(np.abs(world.state.velocities[0]).max()) / 10.0
    worst = max(worst, -min(float(world.gaps().min()), 0.0) / 1e-3)
    worst = worst if _finite(world) else math.inf
    for ratio in (10.0, 1e3, 1e6):
        world = _world(plastic_row_scene(20, [1.0, 1.0 / ratio], False), solver)
        m = world.mass[0]
        com0 = (m[:, None] * world.state.positions[0]).sum(0) / m.sum()
        velocity = world.momentum()[0] / m.sum()
        for _ in range(50):
            world.step(0.004)
        com = (m[:, None] * world.state.positions[0]).sum(0) / m.sum()
        err = max(float(np.abs(com - com0 - velocity * 0.2).max()) / (velocity[0] * 0.2),
                  float(np.abs(world.state.velocities[0] - velocity).max()) / velocity[0],
                  -min(float(world.gaps().min()), 0.0) / 1e-3)
        worst = max(worst, err if _finite(world) else math.inf)
    return Measurement(worst, "50 pucks on a cushion struck at 10 m/s, e = 0: the speed left "
                       "after the step (of 10 m/s); a free row of 20 alternating 1 and 1/ratio "
                       "kg (ratio 10..1e6), struck: velocity spread and centre-of-mass error "
                       "after 0.2 s (relative); overlap in mm")


def wedge_scene(mu: float, heavy: float = 1e3, e: float = 0.0) -> dict:
    """A 1 kg puck on the bottom cushion; a heavier disk lands on it along a normal 30 degrees
    from the vertical. The puck's two contact forces can line up along the chord between its
    contact points, 15 degrees off each normal: for mu > tan 15 deg = 0.268 the wedge locks
    (the heavy disk stops going down, the puck can only roll out); below, the puck squirts."""
    rl, rh = 0.03, 0.05
    low = np.array([0.0, -0.5 + rl])
    high = low + (rl + rh + 0.002) * np.array([math.cos(math.radians(60)),
                                               math.sin(math.radians(60))])
    return {"table": {"size": [2.0, 1.0]}, "effects": ["rotation", "walls", "contact_friction"],
            "materials": {"restitution": e, "friction": mu},
            "bodies": [{"name": "puck", "shape": "disk", "radius": rl, "mass": 1.0,
                        "position": low.tolist()},
                       {"name": "heavy", "shape": "disk", "radius": rh, "mass": heavy,
                        "position": high.tolist(), "velocity": [-1.0, -1.0]}]}


#: the locked wedge's puck velocity (m/s) at a mass ratio of 1e3: fixed substeps converge
#: there (5,000..50,000 substeps: -0.6441; pymunk locks it too)
WEDGE_LOCKED = -0.6441


def _wedge(solver: str) -> Measurement:
    """A self-locking wedge (``wedge_scene``, mu 0.5, e = 0): the jam's block solve had no
    friction and the puck squirted out at -2.62 m/s; the friction block locks it. Error: the
    puck's x velocity against the locked one, at mass ratios 1e3..1e9; and at e = 0.5 and 1
    (no reference: Poisson's restitution on the whole impulse) the puck stays below 2 m/s and
    no energy is gained (the excess, m/s and relative energy, counts as error)."""
    worst = 0.0
    for heavy in (1e3, 1e6, 1e9):
        world = _world(wedge_scene(0.5, heavy), solver)
        world.step(0.01)
        err = abs(world.state.velocities[0, 0, 0] - WEDGE_LOCKED)
        for e in (0.5, 1.0):
            w = _world(wedge_scene(0.5, heavy, e), solver)
            e0 = w.kinetic_energy()[0]
            w.step(0.01)
            err = max(err, float(np.linalg.norm(w.state.velocities[0, 0])) - 2.0,
                      w.kinetic_energy()[0] / e0 - 1.0)
            err = err if _finite(w) else math.inf
        worst = max(worst, err if _finite(world) else math.inf)
    return Measurement(worst, "1 kg puck on a cushion, a disk 1e3..1e9 x heavier lands on it "
                       "30 deg from the vertical (mu 0.5): e = 0, the puck's velocity against "
                       "the locked -0.6441 m/s; e = 0.5, 1: its speed beyond 2 m/s and the "
                       "relative energy gained")


# ---------------------------------------------------------------------------------------------
# 9. tiny and huge time steps
# ---------------------------------------------------------------------------------------------


def _billiards(e=1.0, n=4):
    bodies = []
    rng = np.random.default_rng(3)
    for i in range(n):
        shape = "disk" if i % 2 == 0 else "rod"
        b = {"name": f"b{i}", "shape": shape, "mass": float(rng.uniform(0.05, 0.3)),
             "position": [-0.45 + 0.3 * i, 0.1 * (-1) ** i],
             "velocity": rng.uniform(-1.5, 1.5, 2).tolist(), "angle": float(rng.uniform(0, 3))}
        if shape == "disk":
            b["radius"] = 0.04
        else:
            b.update(length=0.16, thickness=0.02, omega=float(rng.uniform(-5, 5)))
        bodies.append(b)
    return {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
            "materials": {"restitution": e}, "bodies": bodies}


def _time_steps(solver: str) -> Measurement:
    worst = 0.0
    scene = _billiards()
    # tiny steps: 2000 steps of 1e-7 s, then 1e4 steps of 1e-5 s, against one step each
    for dt, n in ((1e-7, 2000), (1e-5, 10_000)):
        a = _world(scene, solver)
        b = _world(scene, solver)
        for _ in range(n):
            a.step(dt)
        b.step(dt * n)
        diff = np.abs(a.get_state()["state"] - b.get_state()["state"]).max()
        worst = max(worst, float(diff))
    # huge step: 100 s at once (thousands of cushion hits, past max_events): E kept, no escape
    world = _world(scene, solver)
    e0 = world.kinetic_energy()[0]
    world.step(100.0)
    hw = np.array([0.6, 0.4])
    inside = np.all(np.abs(world.state.positions[0]) <= hw)
    de = abs(world.kinetic_energy()[0] - e0) / e0
    worst = max(worst, de, 0.0 if inside and _finite(world) else math.inf,
                world.gaps().min() < -1e-9 and math.inf or 0.0)
    fb = bool(world.last_step.fallback[0])
    return Measurement(worst, "n steps of dt vs one step of n dt (dt = 1e-7, 1e-5 s; state "
                       "difference, m and m/s); one step of 100 s"
                       + (" (max_events reached, settled)" if fb else "")
                       + f": energy drift {de:.1e}, nothing outside")


# ---------------------------------------------------------------------------------------------
# 10. bodies starting exactly in contact
# ---------------------------------------------------------------------------------------------


def _start_in_contact(solver: str) -> Measurement:
    worst = 0.0
    # touching and approaching: the impact happens at t = 0 with the closed-form result
    for vx in (1.0, -1.0):
        scene = {"effects": ["rotation"], "materials": {"restitution": 1.0},
                 "bodies": [{"name": "a", "shape": "disk", "radius": 0.05, "mass": 1.0,
                             "velocity": [vx, 0.0]},
                            {"name": "b", "shape": "disk", "radius": 0.05, "mass": 3.0,
                             "position": [0.1, 0.0]}]}
        world = _world(scene, solver)
        c = world.step(0.01)
        v = world.state.velocities[0]
        if vx > 0:  # head-on, masses 1 and 3: v_a' = -V/2, v_b' = V/2
            worst = max(worst, abs(v[0, 0] + 0.5), abs(v[1, 0] - 0.5),
                        abs(float(c.time[0])) if solver == "exact" else 0.0)
        else:  # separating: nothing happens
            worst = max(worst, float(len(c)), abs(v[0, 0] + 1.0), abs(v[1, 0]))
    # touching a cushion and a rod lying flat on one
    scene = {"effects": ["rotation", "walls"], "table": {"size": [1.0, 1.0]},
             "materials": {"restitution": 0.5},
             "bodies": [{"name": "p", "shape": "disk", "radius": 0.05, "mass": 1.0,
                         "position": [0.45, 0.0], "velocity": [2.0, 0.0]},
                        {"name": "r", "shape": "rod", "length": 0.3, "thickness": 0.02,
                         "mass": 1.0, "position": [0.0, -0.49], "velocity": [0.0, -1.0]}]}
    world = _world(scene, solver)
    world.step(0.01)
    v = world.state.velocities[0]
    worst = max(worst, abs(v[0, 0] + 1.0), abs(v[1, 1] - 0.5), abs(world.state.omegas[0, 1]))
    # touching a cushion where adding the reach rounds up (0.55 + 0.05 > 0.6 in float64) is legal
    edge = {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
            "bodies": [{"name": "p", "shape": "disk", "radius": 0.05, "mass": 1.0,
                        "position": [-0.55, 0.35], "velocity": [-1.0, 0.0]}]}
    world = _world(edge, solver)
    world.step(0.01)
    worst = max(worst, abs(world.state.velocities[0, 0, 0] - 1.0))
    # overlap beyond the tolerance is refused, naming both bodies (a cushion: naming the body)
    refused = 0
    scene["bodies"][0]["position"] = [0.45 + 1e-6, 0.0]
    pair = {"effects": ["rotation"],
            "bodies": [{"name": "a", "shape": "disk", "radius": 0.05, "mass": 1.0},
                       {"name": "b", "shape": "rod", "length": 0.2, "thickness": 0.02,
                        "mass": 1.0, "position": [0.16 - 1e-6, 0.0]}]}
    for bad, words in ((scene, "'p' must lie inside the table"), (pair, "'a' and 'b' overlap")):
        try:
            _world(bad, solver)
        except SceneError as exc:
            refused += words in str(exc)
    if refused != 2:
        worst = math.inf
    return Measurement(worst, "disk-disk touching (approaching: impulse at t = 0; separating: "
                       "none), disk on a cushion (also where x + r rounds past the edge), rod "
                       "flat on a cushion; 1e-6 m overlap -> SceneError naming the pair")


# ---------------------------------------------------------------------------------------------
# the catalogue
# ---------------------------------------------------------------------------------------------

_SUSTAINED_CHECKS = ("nothing passes through the cushion or the mallet (deepest overlap at a "
                     "step's end), no NaN, no escape, bounded cost per step (events, substeps), "
                     "and no energy gain beyond the applied force's work: round-off in steps "
                     "the event loop finishes, within the positional correction's budget in "
                     "settled steps, none at all once the force is released; the worst error "
                     "is the largest ratio of a number to its limit (<= 1 passes)")

CASES: tuple[Case, ...] = (
    Case("mass_ratio", "Seed §1 over mass ratios m1/m2 = 1e-12..1e12",
         "exact: V1, V2, omega1 equal the seed's closed forms (relative to V, V2 and omega1); "
         "fixed/pymunk: linear momentum and kinetic energy (e = 1) conserved, finite",
         "rel.", _mass_ratios,
         {"exact": Claim(1e-13), "fixed": Claim(1e-13), "pymunk": Claim(1e-9)},
         brief="closed forms (exact), p and E kept (fixed, pymunk) at m1/m2 = 1e-12..1e12"),
    Case("light_rod_limit", "Seed §1 limit m1/m2 -> 0",
         "V1, V2, |omega1| r equal the limit forms (physics.analytic.rod_strike_light_rod) to "
         "O(m1/m2)", "m/s", _light_rod_limit, {"exact": Claim(1e-11)},
         brief="the seed's limit forms for m1/m2 -> 0, to O(m1/m2)"),
    Case("static_and_pivots", "Static cushions, posts and pivots (inverse mass 0)",
         "v' = -e v off a static post; rod-cushion impulse, velocity and spin equal "
         "physics.analytic.rod_wall; a pivot never moves and angular momentum about it is "
         "conserved; impulse and spin equal (1+e) v / (1/m + l^2/I)", "rel.",
         _static_and_pivots,
         {"exact": Claim(1e-12), "fixed": Claim(1e-12), "pymunk": Claim(1e-9)},
         brief="v' = -e v off a post; rod-cushion closed form; pivot fixed, L kept"),
    Case("grazing", "Grazing contact: approach speed -> 0, normal ⟂ velocity",
         "no impulse, no sticking, no NaN when touching and sliding or passing tangentially "
         "(velocities and path unchanged); at approach angles down to 1e-11 rad, vn' = -e vn "
         "(relative to vn) and the tangential velocity untouched; from ~1e-12 rad the normal "
         "speed is below the round-off floor (1e-12 of the point speeds) and the contact is "
         "plastic whatever e, held with no pulling impulse", "rel.", _grazing,
         {"exact": Claim(1e-9), "fixed": Claim(1e-12), "pymunk": Claim(1e-9)},
         brief="tangential passes get no impulse; vn' = -e vn down to 1e-11 rad, plastic "
               "below round-off (~1e-12 rad)"),
    Case("theta_90", "theta -> 90 deg (lever arm -> 0)",
         "seed's closed forms at theta = 90 deg - 1e-1..1e-11 rad; exactly end-on: no spin "
         "at all", "V, V/r", _theta_90, {"exact": Claim(1e-12)},
         brief="closed forms up to 1e-11 rad from end-on; no spin exactly end-on"),
    Case("thin_and_long_rods", "Zero-thickness, very long (1 km) and very short (1 µm) rods",
         "seed's closed forms; a bare or 1 um rod's tip striking another's side obeys the "
         "impulse law at every tolerance (1e-3..1e-12 m); two zero-thickness rods meet (no "
         "pass-through) and conserve "
         "p, L and E; a zero-thickness rod flat on a cushion turning into it never overlaps it "
         "by more than the tolerance", "rel.", _rods_thin_and_long, {"exact": Claim(1e-11)},
         brief="closed forms at thickness 0, 1 km, 1 µm; thin rods never pass through"),
    Case("restitution_limits", "e = 0 and e = 1 on off-line impacts",
         "normal relative point velocity after = -e x before at the reported contact point "
         "and normal; kinetic energy kept for e = 1", "rel.", _restitution_limits,
         {"exact": Claim(1e-12)},
         brief="vn' = -e vn at the contact point for e = 0 and 1; E kept at e = 1"),
    Case("fast_strike", "Very fast strikes onto a 1 mm rod (tunnelling)",
         "exact: every strike at 1e2..1e6 radii per step bounces back, x-momentum conserved "
         "(worst relative error); fixed (1 substep) and pymunk (10): the fraction that "
         "passes through, which the docs promise is all of them", "rel. / fraction",
         _fast_strikes,
         {"exact": Claim(1e-12),
          "fixed": Claim(1.0, at_least=True, meaning="tunnels (documented)"),
          "pymunk": Claim(1.0, at_least=True, meaning="tunnels (documented)")},
         brief="exact bounces back at 1e2..1e6 radii per step; fixed, pymunk tunnel"),
    Case("simultaneous", "Simultaneous contacts (sequential impulses in pair order)",
         "Newton's cradle ends with only the last disk moving at V; a puck struck against a "
         "cushion sends the striker back at -V; a 45 deg corner hit reverses v; a puck "
         "striking two at once matches an independent sequential-impulse reference; E, p kept",
         "m/s", _simultaneous,
         {"exact": Claim(1e-12), "fixed": Claim(1e-12)},
         brief="Newton's cradle, corner hits, two at once vs a sequential reference"),
    Case("jammed_chain", "A light puck pinned between a heavy one and a cushion, or between "
         "two heavy ones (jam)",
         "mass ratios 1e2..1e12: e = 0: both at rest afterwards; e = 1: the heavy puck is "
         "reflected at its speed (less at most 2/ratio of it) with E kept; two heavy pucks "
         "squeezing a light one (1e6..1e12 x) at e = 1 leave as if they had met, E kept; no "
         "overlap (the sequential sweeps cannot converge here: the block solve of the jam "
         "takes over)",
         "rel.", _jammed, {"exact": Claim(1e-9)},
         brief="light puck jammed by 1e2..1e12 x heavier ones: stops / reflects, E kept"),
    Case("plastic_rows", "Long plastic jams: a row of 50 pucks struck against a cushion, a "
         "free row of 20 alternating light and heavy (e = 0)",
         "the cushion's row stops in the strike's step; the free row (mass ratios 10..1e6) "
         "moves off as one body, its centre of mass following P t / M; no overlap (51 and 20 "
         "touching pairs: the block solve of the jam takes up to 64)",
         "rel.", _plastic_rows, {"exact": Claim(1e-9)},
         brief="rows of 20-50 touching pucks struck at e = 0: stop / move as one body"),
    Case("locked_wedge", "A self-locking wedge: a puck jammed under a heavy disk against a "
         "cushion, with friction (mu 0.5 > tan 15 deg)",
         "mass ratios 1e3..1e9: e = 0, the puck rolls out at the locked velocity fixed substeps "
         "converge to (-0.6441 m/s; it squirted out at -2.62 when the jam's block solve had no "
         "friction); e = 0.5, 1: below 2 m/s, no energy gained",
         "m/s", _wedge, {"exact": Claim(2e-3)},
         brief="puck wedged under a 1e3..1e9 x heavier disk, mu 0.5: locks, no energy gain"),
    Case("pressed_into_cushion", "Mallet pressing a puck into a cushion / a rod into a corner "
         "(e = 0, 0.5, 0.9; Zeno bounces)", _SUSTAINED_CHECKS, "ratio to limit", _pressed,
         {"exact": Claim(1.0), "fixed": Claim(1.0), "pymunk": Claim(1.0)},
         brief="puck pressed into a cushion: overlap, energy beyond work, cost per step"),
    Case("painleve", "Rod pushed by the mallet, sliding with friction along a cushion "
         "(Painlevé; mu = 0.3, 0.8, 2, e = 0, 0.5)", _SUSTAINED_CHECKS, "ratio to limit",
         _painleve, {"exact": Claim(1.0), "fixed": Claim(1.0)},
         brief="Painlevé: a rod pushed along a cushion, mu up to 2: the same limits"),
    Case("time_steps", "Tiny and huge time steps",
         "n steps of dt = 1e-7 / 1e-5 s reach the state of one step of n dt (walled table, "
         "4 bodies, e = 1); one step of 100 s keeps E and everything on the table",
         "m, m/s, rel.", _time_steps, {"exact": Claim(1e-9)},
         brief="n steps of dt (1e-7 s) = one step of n dt; one 100 s step keeps E"),
    Case("start_in_contact", "Bodies starting exactly in contact",
         "touching is legal: an approaching pair is resolved at t = 0 with the closed-form "
         "result, a separating one untouched (disk-disk, disk-cushion, rod flat on a cushion); "
         "overlap beyond the tolerance raises SceneError naming the pair", "m/s",
         _start_in_contact,
         {"exact": Claim(1e-12), "fixed": Claim(1e-12), "pymunk": Claim(1e-5)},
         brief="touching pairs resolved at t = 0; overlap -> SceneError naming the pair"),
)


def by_name(name: str) -> Case:
    for case in CASES:
        if case.name == name:
            return case
    raise KeyError(f"no case {name!r}; cases: {[c.name for c in CASES]}")
