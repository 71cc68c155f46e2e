"""Reference collisions with known answers, for the accuracy benchmark and its tests.

Every case is a set of *variants*: a scene (plain dict, no solver block) in which exactly one
collision happens within ``duration`` seconds, and the velocities and spins after it. The answers
never come from the solver under test:

* ``seed``: seed §1 over theta and m1/m2 — the closed form ``physics.analytic.rod_strike``
  (geometry of ``tests/physics/scenes.py::seed_strike``: a thin rod, ``I = m r^2/3``, slides at V
  into a small resting disk on the line through its tip's cap).
* ``rod_wall``: a translating rod strikes a cushion with its tip — the seed's wall formula
  ``physics.analytic.rod_wall`` (lever ``r cos theta``).
* ``offline_disk_rod``, ``disk_disk``, ``spinning_rod``, ``tunnel``: the impulse law
  (docs/design.md §2) applied at the contact geometry found here by an independent root finder: the
  gap of the two bodies as an analytic function of time (free flight: straight lines and uniform
  spin), sampled densely in float64 to bracket its first zero, which is then bisected in mpmath at
  40 digits. The impulse is evaluated in mpmath too.

For every variant, the same root finder also checks that no second contact (any pair, cushions
included) happens before ``duration``, and the window after the impact is cut to half the time
to the next contact of the reference motion.

Units SI; angles rad CCW from +x; the normal points from body a to body b (scene order); all
collisions frictionless (``contact_friction`` not listed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import mpmath
import numpy as np

from spinstrike.physics.analytic import rod_strike, rod_wall

__all__ = ["CASES", "Case", "Variant", "all_cases", "reference_contact"]

#: mpmath working precision (decimal digits) of the reference root finder and impulse law
DIGITS = 40
#: samples of the gap function over the search horizon (float64, to bracket the first root)
SAMPLES = 20001
#: longest window simulated after the impact, as a fraction of the time of approach
WINDOW = 0.25


# ---------------------------------------------------------------------------------------------
# data
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Body:
    """A body of a reference scene (SI units; ``h`` half-length of the core, 0 for a disk)."""

    name: str
    shape: str  # "disk" | "rod"
    mass: float
    inertia: float
    rho: float  # disk radius, or half the rod's thickness
    h: float = 0.0
    position: tuple[float, float] = (0.0, 0.0)
    angle: float = 0.0
    velocity: tuple[float, float] = (0.0, 0.0)
    omega: float = 0.0
    inertia_spec: Any = None  # what the scene says ("thin_rod"); default the number

    def scene(self) -> dict:
        d: dict[str, Any] = {"name": self.name, "shape": self.shape, "mass": self.mass,
                             "inertia": self.inertia if self.inertia_spec is None
                             else self.inertia_spec,
                             "position": list(self.position), "angle": self.angle,
                             "velocity": list(self.velocity), "omega": self.omega}
        if self.shape == "disk":
            d["radius"] = self.rho
        else:
            d["length"] = 2.0 * self.h
            d["thickness"] = 2.0 * self.rho
        return d


@dataclass(frozen=True)
class Variant:
    """One reference collision.

    Attributes:
        name: short label, unique within its case.
        scene: the scene dict (no solver block).
        t_contact: reference time of impact, s (the *time of approach*).
        duration: time to simulate, s (the impact and a collision-free window after it).
        velocities: [N, 2] reference velocities after the impact, m/s.
        omegas: [N] reference spins after, rad/s.
        speed: incoming speed, m/s: the relative velocity of the two contact points at impact.
        length: spin scale, m (the rod's half-length; the struck disk's radius without a rod).
        energy_in, energy_out: kinetic energy before and (reference) after, J.
        normal_fixed: the contact normal and lever arms do not depend on the gap at which the
            contact is taken (head-on impacts, flat faces, cushions): an event-driven solver is
            then at round-off at any tolerance.
        source: where the answer comes from.
        masses, inertias: [N] kg and kg m^2 of the bodies.
        t_next: when the reference motion after the impact would make its next contact, s
            (inf if none within the search horizon); simulations must end before it.
        detail: the root finder's and impulse law's result (``reference_contact``), also for
            variants whose answer is a closed form (the tests check that the two agree).
    """

    name: str
    scene: dict
    t_contact: float
    duration: float
    velocities: np.ndarray
    omegas: np.ndarray
    speed: float
    length: float
    energy_in: float
    energy_out: float
    normal_fixed: bool
    source: str
    masses: np.ndarray
    inertias: np.ndarray
    t_next: float
    detail: dict = field(default_factory=dict, repr=False, compare=False)

    def energy(self, velocities: np.ndarray, omegas: np.ndarray) -> float:
        """Kinetic energy (J) of the bodies at the given velocities [N, 2] and spins [N]."""
        v = np.asarray(velocities, dtype=float)
        return float(0.5 * (self.masses * (v**2).sum(-1)).sum()
                     + 0.5 * (self.inertias * np.asarray(omegas, dtype=float) ** 2).sum())


@dataclass(frozen=True)
class Case:
    """A named family of reference collisions."""

    name: str
    title: str
    variants: tuple[Variant, ...] = field(repr=False)


# ---------------------------------------------------------------------------------------------
# the independent reference: analytic gap, root bracketing + mpmath bisection, impulse law
# ---------------------------------------------------------------------------------------------


class _NumpyMath:
    cos = staticmethod(np.cos)
    sin = staticmethod(np.sin)
    sqrt = staticmethod(np.sqrt)
    clip = staticmethod(np.clip)
    minimum = staticmethod(np.minimum)


class _MpMath:
    cos = staticmethod(mpmath.cos)
    sin = staticmethod(mpmath.sin)
    sqrt = staticmethod(mpmath.sqrt)

    @staticmethod
    def clip(s, lo, hi):
        return max(lo, min(hi, s))

    @staticmethod
    def minimum(a, b):
        return min(a, b)


@dataclass
class _Motion:
    """A body's free flight from time t0: position, angle, velocity, spin (floats or mpf)."""

    x: Any
    y: Any
    angle: Any
    vx: Any
    vy: Any
    omega: Any
    t0: Any = 0.0

    def pose(self, t, M):
        dt = t - self.t0
        return self.x + self.vx * dt, self.y + self.vy * dt, self.angle + self.omega * dt


def _closest(core: Body, mc: _Motion, point: _Motion, t, M):
    """Closest point q of ``core``'s segment to ``point``'s centre p: (qx, qy, px, py, d)."""
    cx, cy, ca = mc.pose(t, M)
    px, py, _ = point.pose(t, M)
    ux, uy = M.cos(ca), M.sin(ca)
    s = M.clip((px - cx) * ux + (py - cy) * uy, -core.h, core.h)
    qx, qy = cx + s * ux, cy + s * uy
    d = M.sqrt((px - qx) ** 2 + (py - qy) ** 2)
    return qx, qy, px, py, d


def _wall_frame(wall: int, half):
    """Outward normal of cushion ``wall`` and its offset: inside means ``off - n.x > 0``."""
    hw, hh = half
    return [((-1, 0), hw), ((1, 0), hw), ((0, -1), hh), ((0, 1), hh)][wall]


def _wall_ends(A, motion, wall, half, t, M):
    """The outward normal of a cushion and the distances of body A's core ends from it:
    ``(nx, ny, (end0, d0), (end1, d1))``."""
    (nx, ny), off = _wall_frame(wall, half)
    cx, cy, ca = motion.pose(t, M)
    ex, ey = A.h * M.cos(ca), A.h * M.sin(ca)
    d0 = off - (nx * (cx + ex) + ny * (cy + ey))
    d1 = off - (nx * (cx - ex) + ny * (cy - ey))
    return nx, ny, ((cx + ex, cy + ey), d0), ((cx - ex, cy - ey), d1)


def _pair_gap(bodies, motions, pair, half, t, M):
    a, b = pair
    A = bodies[a]
    if b >= len(bodies):
        _, _, (_, d0), (_, d1) = _wall_ends(A, motions[a], b - len(bodies), half, t, M)
        return M.minimum(d0, d1) - A.rho
    B = bodies[b]
    if B.shape == "disk":
        d = _closest(A, motions[a], motions[b], t, M)[4]
    else:
        assert A.shape == "disk", "the reference handles rod-disk, disk-disk and rod-cushion"
        d = _closest(B, motions[b], motions[a], t, M)[4]
    return d - A.rho - B.rho


def _geometry(bodies, motions, pair, half, t):
    """Contact point and normal (a -> b) at time t, in mpmath."""
    M = _MpMath
    a, b = pair
    A = bodies[a]
    if b >= len(bodies):
        nx, ny, (end0, d0), (end1, d1) = _wall_ends(A, motions[a], b - len(bodies), half, t, M)
        sx, sy = end0 if d0 <= d1 else end1
        nx, ny = mpmath.mpf(nx), mpmath.mpf(ny)
        return sx + A.rho * nx, sy + A.rho * ny, nx, ny
    B = bodies[b]
    if B.shape == "disk":
        qx, qy, px, py, d = _closest(A, motions[a], motions[b], t, M)
        nx, ny = (px - qx) / d, (py - qy) / d
        return qx + A.rho * nx, qy + A.rho * ny, nx, ny
    qx, qy, px, py, d = _closest(B, motions[b], motions[a], t, M)
    nx, ny = (qx - px) / d, (qy - py) / d
    return px + A.rho * nx, py + A.rho * ny, nx, ny


def _pairs(bodies, walls: bool):
    n = len(bodies)
    out = [(i, j) for i in range(n) for j in range(i + 1, n)]
    if walls:
        out += [(i, n + w) for i in range(n) for w in range(4)]
    return out


def _first_root(bodies, motions, pairs, half, t_from, horizon, skip_first=False):
    """Earliest (t, pair) in (t_from, t_from + horizon] with a zero gap, or (None, None)."""
    ts = np.linspace(float(t_from), float(t_from) + horizon, SAMPLES)
    float_motions = [_Motion(*(float(v) for v in (m.x, m.y, m.angle, m.vx, m.vy, m.omega,
                                                  m.t0))) for m in motions]
    best_k, best_pair = None, None
    for pair in pairs:
        g = _pair_gap(bodies, float_motions, pair, half, ts, _NumpyMath)
        lo = 1 if skip_first else 0
        if not skip_first and g[0] <= 0:
            raise ValueError(f"pair {pair} touches at t = {t_from}")
        hits = np.nonzero(g[lo:] <= 0.0)[0]
        if len(hits):
            k = int(hits[0]) + lo
            if best_k is None or k < best_k:
                best_k, best_pair = k, pair
    if best_k is None:
        return None, None
    lo, hi = mpmath.mpf(ts[best_k - 1]), mpmath.mpf(ts[best_k])
    for _ in range(4 * DIGITS):
        mid = (lo + hi) / 2
        if _pair_gap(bodies, motions, best_pair, half, mid, _MpMath) > 0:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2, best_pair


def _energy(bodies, v, w):
    return sum(0.5 * B.mass * (vx * vx + vy * vy) + 0.5 * B.inertia * wi * wi
               for B, (vx, vy), wi in zip(bodies, v, w, strict=True))


def reference_contact(bodies: list[Body], e: float = 1.0, half: tuple[float, float] | None = None,
                      horizon: float = 1.0) -> dict:
    """The first collision of free-flying bodies, by the independent reference.

    Args:
        bodies: the bodies (rods may only meet disks or cushions).
        e: restitution.
        half: table half sizes (m) when the scene has cushions, else None.
        horizon: search window, s.

    Returns:
        dict with ``t`` (time of impact, s), ``pair`` (a, b; b >= N is a cushion), ``point``,
        ``normal``, ``j`` (impulse), ``velocities`` [N, 2], ``omegas`` [N] after, ``speed``
        (relative contact-point speed before), ``t_next`` (next contact of the motion after,
        or inf), all floats.
    """
    with mpmath.workdps(DIGITS):
        mp = mpmath.mpf
        motions = [_Motion(mp(B.position[0]), mp(B.position[1]), mp(B.angle), mp(B.velocity[0]),
                           mp(B.velocity[1]), mp(B.omega)) for B in bodies]
        pairs = _pairs(bodies, half is not None)
        t, pair = _first_root(bodies, motions, pairs, half, 0.0, horizon)
        if t is None:
            raise ValueError("no contact within the horizon")
        px, py, nx, ny = _geometry(bodies, motions, pair, half, t)
        a, b = pair
        wall = b >= len(bodies)
        poses = [m.pose(t, _MpMath) for m in motions]
        v = [[m.vx, m.vy] for m in motions]
        w = [m.omega for m in motions]

        def point_velocity(i):
            rx, ry = px - poses[i][0], py - poses[i][1]
            return v[i][0] - w[i] * ry, v[i][1] + w[i] * rx, rx * ny - ry * nx

        vax, vay, rna = point_velocity(a)
        vbx, vby, rnb = (0, 0, 0) if wall else point_velocity(b)
        dvx, dvy = vbx - vax, vby - vay
        vn = dvx * nx + dvy * ny
        A = bodies[a]
        k = 1 / mp(A.mass) + rna**2 / mp(A.inertia)
        if not wall:
            B = bodies[b]
            k += 1 / mp(B.mass) + rnb**2 / mp(B.inertia)
        j = -(1 + mp(e)) * vn / k
        v[a] = [v[a][0] - j * nx / A.mass, v[a][1] - j * ny / A.mass]
        w[a] = w[a] - rna * j / A.inertia
        if not wall:
            v[b] = [v[b][0] + j * nx / B.mass, v[b][1] + j * ny / B.mass]
            w[b] = w[b] + rnb * j / B.inertia
        after = [_Motion(p[0], p[1], p[2], vi[0], vi[1], wi, t)
                 for p, vi, wi in zip(poses, v, w, strict=True)]
        t_next, _ = _first_root(bodies, after, pairs, half, t, horizon, skip_first=True)
        return {
            "t": float(t), "pair": pair, "point": (float(px), float(py)),
            "normal": (float(nx), float(ny)), "j": float(j), "vn": float(vn),
            "velocities": np.array([[float(c) for c in vi] for vi in v]),
            "omegas": np.array([float(wi) for wi in w]),
            "speed": float(mpmath.sqrt(dvx**2 + dvy**2)),
            "t_next": math.inf if t_next is None else float(t_next),
        }


def _variant(name, bodies, *, e=1.0, half=None, horizon=1.0, normal_fixed=False,
             closed_form=None, source="impulse law at the root-found contact (mpmath)"):
    ref = reference_contact(bodies, e=e, half=half, horizon=horizon)
    t = ref["t"]
    window = min(WINDOW * t, 0.5 * (ref["t_next"] - t))
    v, w = ref["velocities"], ref["omegas"]
    if closed_form is not None:
        v, w = closed_form
        v, w = np.asarray(v, dtype=float), np.asarray(w, dtype=float)
    scene: dict[str, Any] = {"effects": ["rotation"] + (["walls"] if half else []),
                             "materials": {"restitution": e},
                             "bodies": [B.scene() for B in bodies]}
    if half:
        scene["table"] = {"size": [2 * half[0], 2 * half[1]]}
    rods = [B.h for B in bodies if B.shape == "rod"]
    length = max(rods) if rods else bodies[ref["pair"][1]].rho
    v0 = [B.velocity for B in bodies]
    w0 = [B.omega for B in bodies]
    return Variant(name, scene, t, t + window, v, w, ref["speed"], length,
                   _energy(bodies, v0, w0), _energy(bodies, v, w), normal_fixed, source,
                   np.array([B.mass for B in bodies]), np.array([B.inertia for B in bodies]),
                   ref["t_next"], ref)


# ---------------------------------------------------------------------------------------------
# the cases
# ---------------------------------------------------------------------------------------------


def _named(name: str, e: float) -> str:
    """A variant's name, with its restitution where it is not 1 (the names of e = 1 variants
    are those of the tables before e < 1 variants were added)."""
    return name if e == 1.0 else f"{name} e={e:g}"


def seed_case(thetas=(0.0, 30.0, 60.0, 85.0), ratios=(1e-3, 1.0, 1e3),
              inelastic=((30.0, 1.0, 0.5), (60.0, 1e-3, 0.0), (60.0, 1e3, 0.3))) -> Case:
    """Seed §1 over theta (deg) and m1/m2 at e = 1, and the (theta, m1/m2, e) of ``inelastic``:
    closed form ``rod_strike``."""
    r, V, gap, thickness, radius, m2 = 0.2, 1.0, 0.05, 1e-3, 0.005, 1.0
    layouts = [(th, ratio, 1.0) for th in thetas for ratio in ratios] + list(inelastic)
    variants = []
    for th, ratio, e in layouts:
        theta = math.radians(th)
        angle = math.pi / 2 - theta
        tip = (r * math.cos(angle), r * math.sin(angle))
        m1 = ratio * m2
        bodies = [
            Body("rod", "rod", m1, m1 * r * r / 3.0, thickness / 2, r, angle=angle,
                 velocity=(V, 0.0), inertia_spec="thin_rod"),
            Body("disk", "disk", m2, 0.5 * m2 * radius**2, radius,
                 position=(tip[0] + thickness / 2 + radius + gap, tip[1])),
        ]
        V1, V2, W1 = rod_strike(m1, m2, r, theta, V, e)
        closed = ([[V1, 0.0], [V2, 0.0]], [W1, 0.0])  # upper tip pushed back: CCW spin
        variants.append(_variant(_named(f"theta={th:g} m1/m2={ratio:g}", e), bodies, e=e,
                                 horizon=0.2, normal_fixed=True, closed_form=closed,
                                 source="closed form physics.analytic.rod_strike"))
    return Case("seed", "seed §1: rod tip strikes a resting disk (theta, m1/m2, e)",
                tuple(variants))


def rod_wall_case(thetas=(15.0, 30.0, 50.0, 70.0), inelastic=((30.0, 0.5), (50.0, 0.0))) -> Case:
    """A translating rod's leading tip strikes the right cushion, at e = 1 over ``thetas`` and
    at the (theta, e) of ``inelastic``: closed form ``rod_wall``."""
    r, m, V, rho, gap = 0.2, 0.7, 2.0, 0.005, 0.05
    inertia = m * ((2 * r) ** 2 + (2 * rho) ** 2) / 12.0
    variants = []
    for th, e in [(th, 1.0) for th in thetas] + list(inelastic):
        theta = math.radians(th)
        angle = math.pi / 2 - theta  # axis (sin t, cos t): the upper tip leads toward +x
        half = (r * math.sin(theta) + rho + gap, 1.0)
        bodies = [Body("rod", "rod", m, inertia, rho, r, angle=angle, velocity=(V, 0.0))]
        j, v_after, w_after = rod_wall(m, inertia, r * math.cos(theta), V, e)
        closed = ([[v_after, 0.0]], [w_after])  # the upper tip is pushed back: CCW
        variants.append(_variant(_named(f"theta={th:g}", e), bodies, e=e, half=half,
                                 horizon=0.2, normal_fixed=True, closed_form=closed,
                                 source="closed form physics.analytic.rod_wall"))
    return Case("rod_wall", "rod tip strikes a cushion (theta, e)", tuple(variants))


def offline_disk_rod_case() -> Case:
    """A disk slides into a resting rod off its line of centres: side and end-cap hits."""
    m_rod, h, rho, m_disk, R, V = 0.1, 0.2, 0.01, 0.05, 0.02, 2.0
    inertia = m_rod * ((2 * h) ** 2 + (2 * rho) ** 2) / 12.0
    layouts = [  # (rod angle deg, disk path y, normal fixed, e)
        (90.0, 0.10, True, 1.0), (90.0, 0.215, False, 1.0), (90.0, 0.225, False, 1.0),
        (60.0, 0.0, False, 1.0), (60.0, 0.12, False, 1.0), (30.0, 0.05, False, 1.0),
        (120.0, 0.15, False, 1.0), (45.0, 0.16, False, 1.0),
        (60.0, 0.12, False, 0.5), (45.0, 0.16, False, 0.0), (90.0, 0.215, False, 0.2),
    ]
    variants = []
    for deg, y, fixed, e in layouts:
        bodies = [Body("rod", "rod", m_rod, inertia, rho, h, angle=math.radians(deg)),
                  Body("disk", "disk", m_disk, 0.5 * m_disk * R * R, R, position=(-0.35, y),
                       velocity=(V, 0.0))]
        variants.append(_variant(_named(f"rod {deg:g} deg, y={y:g}", e), bodies, e=e,
                                 horizon=0.5, normal_fixed=fixed))
    return Case("offline_disk_rod", "disk strikes a resting rod off-line", tuple(variants))


def disk_disk_case() -> Case:
    """Oblique disk-disk impacts over impact parameter, mass ratio and restitution."""
    R1, m1, R2, V = 0.03, 0.2, 0.02, 1.5
    variants = []
    for b_frac, m2, e in [(0.0, 0.1, 1.0), (0.5, 0.1, 1.0), (0.9, 0.1, 1.0), (0.0, 1.0, 1.0),
                          (0.5, 1.0, 1.0), (0.9, 1.0, 1.0), (0.5, 0.1, 0.5)]:
        bodies = [Body("striker", "disk", m1, 0.5 * m1 * R1 * R1, R1, position=(-0.15, 0.0),
                       velocity=(V, 0.0)),
                  Body("target", "disk", m2, 0.5 * m2 * R2 * R2, R2,
                       position=(0.05, b_frac * (R1 + R2)))]
        variants.append(_variant(f"b={b_frac:g} m2/m1={m2 / m1:g} e={e:g}", bodies, e=e,
                                 horizon=0.5, normal_fixed=b_frac == 0.0))
    return Case("disk_disk", "oblique disk-disk impact (impact parameter b/(R1+R2))",
                tuple(variants))


def spinning_rod_case() -> Case:
    """A translating, spinning rod sweeps its end into a resting disk (time of impact matters)."""
    h, thick, R, m_rod, m_disk = 0.2, 0.004, 0.02, 0.3, 0.1
    inertia = m_rod * ((2 * h) ** 2 + thick**2) / 12.0
    layouts = [  # (omega, rod velocity, disk position, e)
        (7.0, (0.4, -0.1), (0.05, 0.17), 1.0), (20.0, (0.4, -0.1), (0.05, 0.17), 1.0),
        (4.0, (0.1, 0.1), (0.1, 0.17), 1.0), (-9.0, (0.3, 0.2), (0.1, -0.15), 1.0),
        (40.0, (0.0, 0.0), (-0.08, 0.15), 1.0),
        (20.0, (0.4, -0.1), (0.05, 0.17), 0.5), (40.0, (0.0, 0.0), (-0.08, 0.15), 0.3),
        (4.0, (0.1, 0.1), (0.1, 0.17), 0.0),  # at e = 0 the others stay in contact: no one impact
    ]
    variants = []
    for w, vel, pos, e in layouts:
        bodies = [Body("rod", "rod", m_rod, inertia, thick / 2, h, velocity=vel, omega=w),
                  Body("disk", "disk", m_disk, 0.5 * m_disk * R * R, R, position=pos)]
        variants.append(_variant(_named(f"omega={w:g}", e), bodies, e=e, horizon=1.0))
    return Case("spinning_rod", "spinning rod sweeps into a resting disk", tuple(variants))


def tunnel_case(distances=(0.05, 0.25, 1.0), speed=100.0) -> Case:
    """A fast puck (5 mm) strikes a thin (1 mm) rod: fixed steps tunnel unless fine enough."""
    h, thick, m_rod, R, m_puck, y = 0.2, 0.001, 0.1, 0.005, 0.05, 0.05
    inertia = m_rod * ((2 * h) ** 2 + thick**2) / 12.0
    variants = []
    for d in distances:
        bodies = [Body("rod", "rod", m_rod, inertia, thick / 2, h, angle=math.pi / 2),
                  Body("puck", "disk", m_puck, 0.5 * m_puck * R * R, R, position=(-d, y),
                       velocity=(speed, 0.0))]
        variants.append(_variant(f"start {d:g} m", bodies, horizon=2 * d / speed,
                                 normal_fixed=True))
    return Case("tunnel", f"fast puck ({speed:g} m/s) strikes a 1 mm rod", tuple(variants))


_BUILDERS = {
    "seed": seed_case,
    "offline_disk_rod": offline_disk_rod_case,
    "disk_disk": disk_disk_case,
    "rod_wall": rod_wall_case,
    "spinning_rod": spinning_rod_case,
    "tunnel": tunnel_case,
}
#: case names, in report order
CASES = tuple(_BUILDERS)

_cache: dict[str, Case] = {}


def get_case(name: str) -> Case:
    """The named case (built once, then cached)."""
    if name not in _BUILDERS:
        raise KeyError(f"unknown case {name!r}; cases: {list(CASES)}")
    if name not in _cache:
        _cache[name] = _BUILDERS[name]()
    return _cache[name]


def all_cases() -> list[Case]:
    """Every reference case, in report order."""
    return [get_case(n) for n in CASES]
