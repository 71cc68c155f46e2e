"""Near-parallel rod-on-rod and rod-on-cushion impacts across the flat-contact threshold
(``contacts.PARALLEL``: cores parallel to ~1e-6 rad count as flat).

A rod landing on another at a small tilt hits at the lower end of their overlap, turns, hits at
the other end, and so on until neither end approaches. Rigid bodies with Newton restitution at
each impact: the sequence, and so the outcome, is the same for every small tilt of one sign (only
the time between the impacts shrinks with it), a definite limit as the tilt goes to 0+; the
other sign gives the mirror sequence. Only the exactly parallel pair, whose two ends land at
once, is a different (simultaneous, two-point) impact: the known discontinuity of rigid-body
impact at tilt 0. The flat contact used to be one impulse through the overlap's middle, and the
steps around the threshold were settled: a rod falling on a rod offset by 0.3 m ended spinning
at -2.76 rad/s inside |tilt| < 1e-6, +0.21 at 1.005..1.02e-6 (settled) and +0.46 above (the
event-driven value). Here the outcome is checked against the limit computed independently
(:func:`_end_impacts`) for tilts a hair apart on both sides of the threshold and far from it.
"""

from __future__ import annotations

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.physics.layout import INV_INERTIA, INV_MASS

#: (falling rod's length, base's length, falling rod's x offset, base static (True), free
#: (False) or pivoted at its centre ("pivot"), restitution)
CASES = {
    "static base, offset 0.3 m, e = 1": (1.0, 1.0, 0.3, True, 1.0),
    "free base, 0.6 m rod on 1 m, e = 1": (0.6, 1.0, 0.1, False, 1.0),
    "free base, offset 0.2 m, e = 0.5": (1.0, 1.0, 0.2, False, 0.5),
    "static 0.6 m base under a 1 m rod, e = 1": (1.0, 0.6, 0.1, True, 1.0),
    # the flat contact's middle was the pivot here for offset 0, and near it for 0.3: the base
    # got (almost) no turn, -2.29 rad/s each inside the threshold against -3.21 above
    "pivoted base, offset 0.3 m, e = 1": (1.0, 1.0, 0.3, "pivot", 1.0),
}

#: tilts (rad) a hair apart on both sides of the threshold (1e-6), and far from it on both sides
TILTS = [0.99e-6, 0.999e-6, 0.9999e-6, 1e-6, 1.0001e-6, 1.001e-6, 1.01e-6, 1.1e-6, 2e-6,
         1e-8, 1e-7, 1e-5, 1e-4]


def _world(case: str, tilt: float) -> physics.World:
    la, lb, offset, static, e = CASES[case]
    base = dict(name="base", shape="rod", length=lb, thickness=0.02, position=[0.0, 0.0],
                angle=0.0)
    if static == "pivot":
        base.update(mass=2.0, pivot=True)
    else:
        base.update(static=True) if static else base.update(mass=2.0)
    rod = dict(name="rod", shape="rod", length=la, thickness=0.02, mass=1.0,
               position=[offset, 0.05], angle=tilt, velocity=[0.0, -1.0])
    return physics.World(dict(effects=["rotation"], materials=dict(restitution=e),
                              bodies=[rod, base]))


def _end_impacts(case: str, sign: float) -> tuple[float, float]:
    """The tilt -> 0 limit (sign +1: tilted counter-clockwise) of the falling rod's spin and
    vertical velocity: -e impacts at the overlap's ends in turn, the lower end first, until
    neither approaches (plain Python, independent of the engine's kernels)."""
    la, lb, offset, static, e = CASES[case]
    w = _world(case, 0.0)
    imr, iir = w.params[0, 0, INV_MASS], w.params[0, 0, INV_INERTIA]
    imb, iib = w.params[0, 1, INV_MASS], w.params[0, 1, INV_INERTIA]
    ends = [max(offset - la / 2, -lb / 2), min(offset + la / 2, lb / 2)]
    if sign < 0:
        ends.reverse()  # tilted clockwise, the right end is the lower
    return _alternate(ends, offset, e, (-1.0, 0.0, imr, iir), (0.0, 0.0, imb, iib))


def _alternate(ends, offset, e, rod, base) -> tuple[float, float]:
    """-e impacts along y at the x of ``ends`` in turn, the first first, until neither end
    approaches: a rod centred at ``offset`` above a base centred at 0 (each ``(vy, spin,
    1/m, 1/I)``; a cushion is a base of zeros). Returns the rod's (spin, vy)."""
    (vr, wr, imr, iir), (vb, wb, imb, iib) = rod, base
    quiet, i = 0, 0
    while quiet < 2:
        x = ends[i]
        u = (vr + wr * (x - offset)) - (vb + wb * x)  # < 0: the rod's end approaches the base
        if u < -1e-14:
            k = imr + imb + (x - offset) ** 2 * iir + x * x * iib
            j = -(1.0 + e) * u / k
            vr, wr = vr + j * imr, wr + j * (x - offset) * iir
            vb, wb = vb - j * imb, wb - j * x * iib
            quiet = 0
        else:
            quiet += 1
        i = 1 - i
    return wr, vr


def _run(world: physics.World) -> None:
    """Ten steps of 10 ms, checked for what every step promises."""
    p0, e0 = world.momentum()[0].copy(), world.kinetic_energy()[0]
    l0 = world.angular_momentum()[0]
    for _ in range(10):
        world.step(0.01)
        assert world.last_step.fallback[0] == 0  # every step event-driven, none settled
        assert world.gaps()[0].min() >= -world.tolerance
    assert world.kinetic_energy()[0] <= e0 * (1.0 + 1e-12)
    if not world.params[0, 1, INV_MASS] == 0.0:  # a free base: momentum and L kept
        np.testing.assert_allclose(world.momentum()[0], p0, rtol=0, atol=1e-14)
    if world.params[0, 1, INV_INERTIA] > 0.0:  # free or pivoted at the origin: L about it kept
        assert world.angular_momentum()[0] == pytest.approx(l0, abs=1e-14)


@pytest.mark.parametrize("case", list(CASES))
def test_near_parallel_impacts_match_the_end_impacts_limit_across_the_threshold(case):
    _sweep(lambda sign: _end_impacts(case, sign), lambda tilt: _world(case, tilt), _run)


def _sweep(limit, world, run) -> None:
    """Both signs of every tilt in ``TILTS``: ``world(tilt)`` stepped by ``run`` ends with the
    falling rod's spin and vy at ``limit(sign)``."""
    for sign in (1.0, -1.0):
        spin, vy = limit(sign)
        for tilt in TILTS:
            w = world(sign * tilt)
            run(w)
            # the tilt's own effect is O(tilt): measured <= 0.5 tilt (rad/s, m/s)
            bound = 1e-8 + tilt
            assert w.state.omegas[0, 0] == pytest.approx(spin, abs=bound), (sign * tilt)
            assert w.state.velocities[0, 0, 1] == pytest.approx(vy, abs=bound), (sign * tilt)


@pytest.mark.parametrize("case", list(CASES))
def test_an_exactly_flat_landing_is_one_simultaneous_impact_within_the_one_sided_limits(case):
    # both ends land at once: the -e law at both (both impulses >= 0 in these cases), so the
    # rod bounces off flat without spin when e = 1 or the base is static; not the impulse
    # through the overlap's middle that spun the offset rod at -2.76 rad/s
    w = _world(case, 0.0)
    _run(w)
    lo, hi = sorted((_end_impacts(case, 1.0)[0], _end_impacts(case, -1.0)[0]))
    assert lo - 1e-12 <= w.state.omegas[0, 0] <= hi + 1e-12
    la, lb, offset, static, e = CASES[case]
    if static is True:
        assert w.state.omegas[0, 0] == pytest.approx(0.0, abs=1e-12)
        assert w.state.velocities[0, 0, 1] == pytest.approx(e, abs=1e-12)


# A rod flat on a cushion (the infinite-mass body): the same limit at the rod's two core ends.
# It was one impulse through the middle, which no tilt produces: a 1 m rod falling at 1 m/s onto
# the bottom cushion (e = 1) left spinning at +-0.14055 rad/s for every tilt above 1e-6 rad and
# at 0 below it; at 1.0-1.01e-6 the step was settled (+-1e-5 rad/s), and at e = 0.5 the settled
# band reached 2e-6 (-0.43 rad/s, bouncing at 0.62 m/s where the end impacts give 0.34).

#: (restitution, spin before, rad/s)
WALL_CASES = {"e = 1": (1.0, 0.0), "e = 0.5": (0.5, 0.0), "e = 1, spinning": (1.0, 0.3),
              "e = 0.5, spinning": (0.5, 0.3)}
#: the falling rod's centre above the cushion's contact height, m, and its speed, m/s
DROP, SPEED = 0.05, 1.0


def _wall_world(case: str, tilt: float) -> physics.World:
    """A 1 m, 20 mm, 1 kg rod falling onto the bottom cushion of a walled 1.2 m x 0.8 m table,
    turned so that it is at about ``tilt`` (same sign) when it lands."""
    e, omega = WALL_CASES[case]
    rod = dict(name="rod", shape="rod", length=1.0, thickness=0.02, mass=1.0,
               position=[0.05, -0.4 + 0.01 + DROP], angle=tilt - omega * DROP / SPEED,
               velocity=[0.0, -SPEED], omega=omega)
    return physics.World(dict(table=dict(size=[1.2, 0.8]), effects=["rotation", "walls"],
                              materials=dict(restitution=e), bodies=[rod]))


def _wall_end_impacts(case: str, sign: float) -> tuple[float, float]:
    """The tilt -> 0 limit of the rod's spin and vertical velocity on the cushion: -e impacts
    at its core's ends in turn (the lower first: the left for sign +1) until neither approaches
    (plain Python)."""
    e, omega = WALL_CASES[case]
    w = _wall_world(case, 0.0)
    im, ii = w.params[0, 0, INV_MASS], w.params[0, 0, INV_INERTIA]
    ends = [-0.5, 0.5] if sign > 0 else [0.5, -0.5]
    return _alternate(ends, 0.0, e, (-SPEED, omega, im, ii), (0.0, 0.0, 0.0, 0.0))


def _run_on_cushion(world: physics.World) -> None:
    """Ten steps of 10 ms: none settled, no overlap, no energy gained; only the cushion's
    normal component (y) of the momentum changes."""
    e0 = world.kinetic_energy()[0]
    for _ in range(10):
        world.step(0.01)
        assert world.last_step.fallback[0] == 0
        assert world.gaps()[0].min() >= -world.tolerance
    assert world.kinetic_energy()[0] <= e0 * (1.0 + 1e-12)
    assert world.state.velocities[0, 0, 0] == 0.0


@pytest.mark.parametrize("case", list(WALL_CASES))
def test_a_rod_landing_near_flat_on_a_cushion_matches_the_end_impacts_limit(case):
    _sweep(lambda sign: _wall_end_impacts(case, sign), lambda tilt: _wall_world(case, tilt),
           _run_on_cushion)


@pytest.mark.parametrize("e", [1.0, 0.5])
def test_a_rod_dropped_exactly_flat_on_a_cushion_bounces_flat(e):
    # both ends land at once: the simultaneous impact, a symmetric bounce without spin (what
    # the impulse through the middle gave too; a guard for the tie)
    w = _wall_world("e = 1" if e == 1.0 else "e = 0.5", 0.0)
    _run_on_cushion(w)
    assert w.state.omegas[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert w.state.velocities[0, 0, 1] == pytest.approx(e * SPEED, abs=1e-12)


# A flat pair's approach was judged at its contact point, the middle, for the time of impact:
# a rod lying flat on a cushion (or a rod) and turning has its middle at rest along the normal
# while one end goes in, so the contact went unseen until the tilt left the ~1e-6 rad band;
# the step stalled and was settled, the end 5e-4 m deep when a 1 ms step's settle met it (1 m
# rod at 1 rad/s). It is met at once now, an event like any other.

def _lying(omega: float, on: str, vy: float) -> physics.World:
    rod = dict(name="rod", shape="rod", length=1.0, thickness=0.02, mass=1.0, angle=0.0,
               velocity=[0.0, vy], omega=omega)
    if on == "cushion":
        bodies = [dict(rod, position=[0.05, -0.39])]
    else:
        bodies = [dict(rod, position=[0.0, 0.02]),
                  dict(name="base", shape="rod", length=1.0, thickness=0.02, static=True,
                       position=[0.0, 0.0], angle=0.0)]
    return physics.World(dict(table=dict(size=[1.2, 0.8]), effects=["rotation", "walls"],
                              materials=dict(restitution=0.5), bodies=bodies))


@pytest.mark.parametrize("on", ["cushion", "static rod"])
@pytest.mark.parametrize("omega,vy", [(1.0, 0.0), (-0.01, 0.0), (1.0, 0.1)])
def test_a_flat_pair_turning_into_contact_is_met_at_once(on, omega, vy):
    # the middle at rest (vy = 0) or leaving (vy = 0.1 < h omega) while an end goes in
    w = _lying(omega, on, vy)
    e0 = w.kinetic_energy()[0]
    c = w.step(0.001)
    assert w.last_step.fallback[0] == 0
    assert len(c) == 1 and c.time[0] <= 1e-12
    # the end going in (the left for omega > 0) takes the -e impact, the other then leaves
    x = -0.5 if omega > 0 else 0.5
    assert c.point[0, 0] == pytest.approx(w.state.positions[0, 0, 0] + x, abs=1e-3)
    assert w.gaps()[0].min() >= -w.tolerance
    for _ in range(20):
        w.step(0.001)
        assert w.last_step.fallback[0] == 0
        assert w.gaps()[0].min() >= -w.tolerance
    assert w.kinetic_energy()[0] <= e0 * (1.0 + 1e-12)


ROD = dict(shape="rod", length=0.4, thickness=0.02, mass=0.1)
DISK = dict(shape="disk", radius=0.03, mass=0.1)


@pytest.mark.parametrize("bodies, walls, flat", [
    ([ROD, DISK], False, False),                         # RodSpin-v0: a rod meets only a disk
    ([DISK, DISK, DISK], True, False),                    # pucks and cushions
    ([ROD, DISK], True, True),                            # RodSpinControl-v0: a rod on a cushion
    ([ROD, ROD], False, True),                            # two rods
    ([dict(ROD, static=True), dict(ROD, static=True), DISK], False, False),  # never touch
    ([dict(ROD, static=True), DISK], True, False),        # a static rod has no cushion pairs
    ([dict(ROD, pivot=True), DISK], True, True),          # a pivoted one has
])
def test_the_flat_flag_is_set_where_a_pair_can_lie_flat(bodies, walls, flat):
    """The ``flat`` compile-time flag (``kernels.FLAGS``): the flat-pair code is compiled only
    into worlds with a contact pair of two rods or of a rod and a cushion; every other world's
    pairs are never flat (``contacts.flat_points``: a disk's core is a point), so it steps the
    same without it (the goldens, recorded with it, pass bit for bit)."""
    spaced = [dict(b, name=f"b{i}", position=[0.0, 0.2 * i - 0.2]) for i, b in enumerate(bodies)]
    scene = dict(effects=["rotation", "walls"] if walls else ["rotation"], bodies=spaced)
    if walls:
        scene["table"] = dict(size=[1.2, 0.8])
    assert physics.World(scene).flags.flat == flat
