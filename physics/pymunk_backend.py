"""The ``pymunk`` solver: the same scene on Chipmunk2D through pymunk (docs/design.md §4).

This is the peer most users would pick instead of the exact solver, kept here so that the
accuracy benchmark can price both on the same scenes. ``physics.World`` builds a
:class:`PymunkBackend` when the solver block is ``{mode: pymunk, iterations: N, substeps: N}``;
``world.step(dt)`` then runs ``substeps`` pymunk steps of ``dt / substeps`` on every element and
copies the result back into the world's packed state and contact buffers, so that ``world.state``,
``world.step``'s :class:`~physics.world.Contacts` and ``world.last_step`` look the same whichever
solver ran. This module is the only one that imports pymunk.

Mapping (one ``pymunk.Space`` per batch element, the one Python loop over elements that the
project allows):

* ``disk`` -> ``Circle(radius)``; ``rod`` (capsule) -> ``Segment((-L/2, 0), (L/2, 0),
  radius=thickness/2)``; the body's local x axis is the rod's axis, so pymunk's ``angle`` is the
  world's (rad, CCW from +x).
* mass and moment of inertia are the world's (``world.mass``, ``world.inertia``), so inertia
  overrides such as ``thin_rod`` carry over; without the ``rotation`` effect the moment is
  ``inf``. ``static`` bodies are ``Body.STATIC``; a ``pivot`` is a dynamic body pinned at its
  centre to the space's static body by a ``PivotJoint`` (finite mass, so the pin is only as
  rigid as ``iterations`` make it — part of what the benchmark prices). The world reports a
  pivot where every solver does, at its pin with zero velocity (its angle and spin are
  pymunk's): the joint's give stays inside the space, so ``reset``, ``set_state`` and snapshots
  keep the world's rule that pivots do not move.
* ``walls``: four static segments whose inner surfaces lie on the table's edges (left, right,
  bottom, top = bodies ``N..N+3``). They are *thick* (radius ``WALL_DEPTH`` x the smaller half
  size of the table, core moved outward by that radius, extended past the corners) so that a
  body pushed deep into a cushion within one step is still pushed back in: a radius-0 segment
  would let a centre cross it and flip the normal. Their bounding boxes end on the table edges,
  so the broad phase costs the same as for thin segments.
* materials: Chipmunk multiplies the two shapes' elasticities and frictions; here a
  ``pre_solve`` callback per contact pair sets ``arbiter.restitution`` / ``arbiter.friction`` to
  the scene's effective per-pair values (``world._materials``), so per-pair overrides and
  ``set_material`` act exactly. Chipmunk's friction is its own (Coulomb, solved jointly with the
  normal impulse by sequential impulses), not the project's sequential stage: with ``mu > 0``
  the two models differ by design.
* ``driven`` bodies get ``world._forces`` applied before every pymunk step.
* ``table_friction`` is implemented by two Chipmunk joints per sliding body (a pivot and a gear
  joint to the static body, ``max_bias = 0``, ``max_force`` the cloth's force and torque:
  ``PymunkBackend._set_cloth``) with the model of ``physics.effects``: speed reduced by
  ``mu_t g h`` along the velocity and ``|omega|`` by ``mu_t g h / k`` per step of ``h``, never
  reversed; driven bodies exempt. Integrated per step (first order), like the ``fixed`` solver,
  for a sliding body; solved with the contacts (sequential impulses), so two things differ
  from the other solvers (walk W29a): the joints are *static* friction too (a body another
  pushes with less than its cloth friction stays at rest, where exact and fixed, kinetic only,
  let it creep: README's known failures; a puck pressed on a cushion has part of the load on
  the cloth), and in a bounce's pymunk step Chipmunk's restitution target is the approach
  speed before that step's friction, so the bounce leaves ``mu_t g h`` faster along the
  normal than the model (a puck into a cushion at 2 m/s, e = 1, ``h`` = 1 ms: 1.80576 m/s
  against 1.80380; the Python ``velocity_func`` the joints replaced did the same). An
  effect outside ``SUPPORTED_EFFECTS`` (none today) raises
  :class:`~physics.scene.SceneError` naming it.

Knobs (set on every space):

* ``Space.iterations`` = the solver block's ``iterations`` (Chipmunk's sequential-impulse sweeps
  per step); ``dt / substeps`` is the pymunk step.
* ``collision_slop = COLLISION_SLOP = 0`` m. pymunk's default, 0.1, is in the user's length unit
  and tuned for pixels; in metres it would let bodies rest 10 cm deep in each other. Slop only
  gates Chipmunk's positional correction, which works on separate bias velocities, so it never
  changes the post-impact velocities the benchmark measures.
* ``collision_bias`` and ``collision_persistence`` keep pymunk's defaults (0.18% of an overlap
  left after 1 s; contacts cached for 3 steps for warm starting). Gravity 0, damping 1 (none),
  no sleeping.
* A new space takes ``WARM_STEPS`` empty steps before any body is added: Chipmunk allocates its
  contact buffers during its first ``collision_persistence + 1`` steps (about 16 µs each when
  collision handlers exist), a one-off cost that would otherwise land in the first
  ``world.step`` after every reset. With no bodies these steps change nothing.
* ``reset`` / ``set_state`` / ``restore`` that move bodies rebuild the element's space
  (``sync_from_world``), so that equal states step identically; this costs about 0.2 ms per
  element. Velocity-only changes are applied in place.

Reporting (what ``world.step`` returns): every pymunk step in which a pair's arbiter applied a
nonzero impulse is one contact, at the end of that pymunk step (``time``), at the mean of
Chipmunk's contact points (midway between the two surfaces), with Chipmunk's normal oriented from
body a to body b (``world.pair_a`` -> ``world.pair_b``; a cushion is always b) and the impulse
received by b in that pymunk step split into its normal part ``j`` and its part along
``t = (-n_y, n_x)`` (the impulse applied in the step: an arbiter Chipmunk cached from an earlier
touch holds an old impulse it does not apply, which ``total_impulse`` counts and the record
leaves out; starting from it, Chipmunk's solver can pull, ``j < 0``).
Chipmunk warm-starts and re-solves a contact over the steps its shapes overlap, so one physical
impact can be reported more than once (the later reports usually with ``j = 0`` and then
omitted). ``world.last_step``: ``substeps`` = pymunk steps, ``iterations`` = ``substeps x
Space.iterations`` (solver sweeps, the pymunk analogue of the exact solver's root-finding
iterations), ``events`` = 0.

Caveat: Chipmunk detects contacts after moving the bodies and corrects overlaps over later steps,
so the state after a ``step`` can hold overlaps of up to ``speed * dt / substeps``; the world's
overlap check in ``set_state`` (tolerance 1e-9 m for non-exact solvers) can then refuse a state
that pymunk itself produced.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pymunk

from spinstrike.physics.layout import (
    ANGLE,
    FRICTION,
    FRICTION_DECEL,
    OMEGA,
    REC_HELD,
    REC_J,
    REC_JT,
    REC_NX,
    REC_NY,
    REC_PX,
    REC_PY,
    REC_TIME,
    REC_WATCHED_J,
    RESTITUTION,
    SPIN_DECEL,
    STAT_CONTACTS,
    STAT_ITERATIONS,
    STAT_SUBSTEPS,
    STAT_WATCH,
    STAT_WATCHED,
    VX,
    VY,
    X,
    Y,
)
from spinstrike.physics.scene import SceneError

__all__ = ["COLLISION_SLOP", "SUPPORTED_EFFECTS", "WALL_DEPTH", "PymunkBackend"]

#: effects this backend can simulate; any other listed effect is a SceneError
SUPPORTED_EFFECTS = frozenset({"rotation", "walls", "contact_friction", "table_friction"})
#: Space.collision_slop, m (see module docstring)
COLLISION_SLOP = 0.0
#: cushion radius as a multiple of the table's smaller half size (see module docstring)
WALL_DEPTH = 1.0
#: empty steps a new space takes before bodies are added (see module docstring)
WARM_STEPS = 5
#: a speed (spin) at most this times one substep's cloth decrement is round-off of a stopped
#: body and is set to 0 (``PymunkBackend._set_cloth``)
STOPPED = 1e-9


class _Element:
    """One batch element's pymunk objects."""

    __slots__ = ("space", "bodies", "shapes", "walls", "joints", "cloth", "decel", "h")

    def __init__(self) -> None:
        self.space = pymunk.Space()
        self.bodies: list[pymunk.Body] = []
        self.shapes: list[pymunk.Shape] = []
        self.walls: list[pymunk.Segment] = []
        self.joints: list[pymunk.Constraint] = []
        # per body its cloth-friction joints [linear, angular] (None: no such friction)
        self.cloth: list[list[pymunk.Constraint | None]] = []
        self.decel: list[tuple[float, float]] = []  # per body [speed, spin] decel, m/s^2, rad/s^2
        self.h = 0.0  # the pymunk step the cloth joints' cached impulses are of (0: none yet)


class PymunkBackend:
    """Steps a :class:`physics.World` with pymunk (see the module docstring).

    Args:
        world: the world; its scene, parameters and state are read from it, and results are
            written back into ``world._state`` and its contact and statistics buffers.

    Raises:
        SceneError: the scene lists an effect pymunk cannot express here.
    """

    def __init__(self, world: Any) -> None:
        unsupported = sorted(set(world.effects) - SUPPORTED_EFFECTS)
        if unsupported:
            raise SceneError(f"effects: the pymunk solver cannot simulate {unsupported}; "
                             f"it supports {sorted(SUPPORTED_EFFECTS)}")
        self.world = world
        B = world.batch_size
        self._elements: list[_Element] = [None] * B  # type: ignore[list-item]
        # per element and pair: [restitution, friction], read by the pre_solve callbacks
        self._mats: list[list[list[float]]] = [[[0.0, 0.0] for _ in world.pair_a] for _ in range(B)]
        self._written = np.full_like(world._state, np.nan)
        # recording context of the running step: [element, time within the step (s), count,
        # Chipmunk's dt_coef: this pymunk step's length over the last one's]
        self._ctx: list[Any] = [0, 0.0, 0, 1.0]
        self._load_materials()
        for b in range(B):
            self._build(b)
        self._written[:] = world._state

    # ------------------------------------------------------------------------------------------
    # building and syncing
    # ------------------------------------------------------------------------------------------

    def _load_materials(self) -> None:
        mats = self.world._materials
        for b, rows in enumerate(self._mats):
            for p, cell in enumerate(rows):
                cell[0] = float(mats[b, p, RESTITUTION])
                cell[1] = float(mats[b, p, FRICTION])

    def _wall_geometry(self, b: int) -> list[tuple[tuple[tuple[float, float], ...], float]]:
        hw, hh = (float(v) for v in self.world._half[b])
        r = WALL_DEPTH * min(hw, hh)
        ext = hw + hh + 2.0 * r  # past the corners
        xl, xr, yb, yt = -hw - r, hw + r, -hh - r, hh + r
        return [(((xl, -ext), (xl, ext)), r), (((xr, -ext), (xr, ext)), r),
                (((-ext, yb), (ext, yb)), r), (((-ext, yt), (ext, yt)), r)]

    def _build(self, b: int) -> None:
        """(Re)create element b's space from the world's parameters and state."""
        w = self.world
        el = _Element()
        sp = el.space
        sp.iterations = int(w.solver.iterations)
        sp.collision_slop = COLLISION_SLOP
        sp.gravity = (0.0, 0.0)
        sp.damping = 1.0
        for _ in range(WARM_STEPS):  # allocate Chipmunk's contact buffers now, not in step()
            sp.step(1.0)
        state = w._state[b]
        for i in range(w.n_bodies):
            if w.static[i]:
                body = pymunk.Body(body_type=pymunk.Body.STATIC)
            else:
                body = pymunk.Body(float(w.mass[b, i]), self._moment(b, i))
            body.position = (float(state[i, X]), float(state[i, Y]))
            body.angle = float(state[i, ANGLE])
            if not w.static[i]:
                body.velocity = (float(state[i, VX]), float(state[i, VY]))
                body.angular_velocity = float(state[i, OMEGA])
            if w.shapes[i] == "disk":
                shape: pymunk.Shape = pymunk.Circle(body, float(w.radius[b, i]))
            else:
                h = float(w.half_length[b, i])
                shape = pymunk.Segment(body, (-h, 0.0), (h, 0.0), float(w.radius[b, i]))
            shape.collision_type = i
            shape.elasticity = 1.0
            shape.friction = 0.0
            sp.add(body, shape)
            el.bodies.append(body)
            el.shapes.append(shape)
            if w.pivot[i]:
                joint = pymunk.PivotJoint(sp.static_body, body, body.position)
                joint.collide_bodies = True
                sp.add(joint)
                el.joints.append(joint)
            el.cloth.append([None, None])
            el.decel.append((0.0, 0.0))
        if w.walls:
            for k, ((a, c), r) in enumerate(self._wall_geometry(b)):
                seg = pymunk.Segment(sp.static_body, a, c, r)
                seg.collision_type = w.n_bodies + k
                seg.elasticity = 1.0
                seg.friction = 0.0
                sp.add(seg)
                el.walls.append(seg)
        for p in range(len(w.pair_a)):
            cell = self._mats[b][p]
            held = [0.0, 0.0]  # the arbiter's impulse before the solve (see _materials_callback)
            sp.on_collision(int(w.pair_a[p]), int(w.pair_b[p]),
                            pre_solve=_materials_callback(cell, held, self._ctx),
                            post_solve=self._record_callback(p, held))
        self._elements[b] = el
        self._set_cloth(b)

    def _moment(self, b: int, i: int) -> float:
        return float(self.world.inertia[b, i]) if self.world.rotation else math.inf

    def _set_cloth(self, b: int, renew: bool = False) -> None:
        """Install, update or remove the table-friction joints of element b's bodies.

        Per sliding body, a :class:`pymunk.PivotJoint` from the static body to its centre and a
        :class:`pymunk.GearJoint` (ratio 1), both with ``max_bias = 0`` (no pull back towards
        an anchor, velocity only) and ``max_force`` the cloth's force ``m mu_t g`` and torque
        ``I mu_t g / k``: each substep of ``h`` takes up to ``mu_t g h`` off the speed along the
        velocity and ``mu_t g h / k`` off ``|omega|`` and never reverses them, the law of
        ``physics.effects`` (Chipmunk clamps the joint's impulse vector by its length). This is
        how a pymunk user writes top-down friction, in C: it was a Python ``velocity_func``
        per body and substep, ~37 % of the backend's time in the control env (walk W28b F2).
        Solved with the contacts by the same sequential impulses, not before them. A stopped
        body keeps a residual of round-off (the joint's effective mass times ``1 / m`` is not
        exactly 1) that decays to denormals but never to 0; :meth:`step` sets a speed or spin
        below :data:`STOPPED` times one substep's decrement to 0, as the law would in the
        next substep, so that a stopped body is at rest, velocity and spin 0, as on the other
        solvers (tests and users compare with 0).

        ``renew``: new joints in place of the old, whose cached impulses are of another pymunk
        step length. Chipmunk warm-starts a joint with its last impulse times ``dt / prev_dt``
        but clamps the sum with the unscaled one: after a step of ``h0`` a step of ``h1``
        took ``F (2 h1 - h0)`` off instead of ``F h1`` (0.1 s then 0.3 s: 0.5 s of friction).
        :meth:`step` renews them when its pymunk step differs from the last one's.
        """
        w = self.world
        el = self._elements[b]
        sp = el.space
        for i, body in enumerate(el.bodies):
            if w.static[i]:
                continue
            decel = float(w._params[b, i, FRICTION_DECEL]) if w.table_friction else 0.0
            spin = float(w._params[b, i, SPIN_DECEL]) if w.table_friction and w.rotation else 0.0
            el.decel[i] = (decel, spin)
            for k, (need, force) in enumerate(((decel > 0.0, body.mass * decel),
                                               (spin > 0.0, body.moment * spin))):
                joint = el.cloth[i][k]
                if renew and joint is not None:
                    sp.remove(joint)
                    joint = None
                if need and joint is None:
                    joint = (pymunk.PivotJoint(sp.static_body, body, (0.0, 0.0), (0.0, 0.0))
                             if k == 0 else pymunk.GearJoint(sp.static_body, body, 0.0, 1.0))
                    joint.max_bias = 0.0  # no pull back to an anchor: friction only
                    sp.add(joint)
                    el.cloth[i][k] = joint
                elif not need and joint is not None:
                    sp.remove(joint)
                    el.cloth[i][k] = joint = None
                if joint is not None:
                    joint.max_force = force

    def sync_from_world(self) -> None:
        """Take over the world's state after ``set_state`` / ``reset`` / ``restore``.

        An element whose positions or angles changed is rebuilt from scratch: a fresh space has
        no cached contacts (warm-starting impulses), no pending positional correction and fresh
        shape ids, so the same state always steps bit-for-bit the same way, whatever came before
        (about 0.2 ms per element). An element whose velocities alone changed keeps its space
        (and its cached contacts: a velocity change is a continuation of the motion). Elements
        whose state did not change are left alone.
        """
        w = self.world
        state = w._state
        diff = state != self._written
        moved = np.any(diff[..., [X, Y, ANGLE]], axis=(1, 2))
        kicked = np.any(diff, axis=(1, 2)) & ~moved
        for b in np.nonzero(moved)[0]:
            self._build(int(b))
        for b in np.nonzero(kicked)[0]:
            el = self._elements[int(b)]
            for i, body in enumerate(el.bodies):
                if not w.static[i]:
                    r = state[int(b), i]
                    body.velocity = (float(r[VX]), float(r[VY]))
                    body.angular_velocity = float(r[OMEGA])
        self._written[:] = state

    def sync_params(self) -> None:
        """Take over changed parameters (``set_body``, ``set_material``, ``set_table``) in place."""
        w = self.world
        if not self._elements or self._elements[0] is None:
            return
        self._load_materials()
        for b, el in enumerate(self._elements):
            for i, (body, shape) in enumerate(zip(el.bodies, el.shapes, strict=True)):
                if not w.static[i]:
                    body.mass = float(w.mass[b, i])
                    body.moment = self._moment(b, i)
                if w.shapes[i] == "disk":
                    shape.unsafe_set_radius(float(w.radius[b, i]))
                else:
                    h = float(w.half_length[b, i])
                    shape.unsafe_set_endpoints((-h, 0.0), (h, 0.0))
                    shape.unsafe_set_radius(float(w.radius[b, i]))
            if el.walls:
                for seg, ((a, c), r) in zip(el.walls, self._wall_geometry(b), strict=True):
                    seg.unsafe_set_endpoints(a, c)
                    seg.unsafe_set_radius(r)
            # static shapes (cushions, and static bodies resized above) stay in the broad
            # phase's static index with their old bounding boxes until reindexed: a post grown
            # in a scene without walls was passed through
            el.space.reindex_static()
            self._set_cloth(b)

    def space(self, b: int) -> pymunk.Space:
        """Element b's pymunk space (rebuilt when the world moves its bodies)."""
        return self._elements[b].space

    # ------------------------------------------------------------------------------------------
    # stepping
    # ------------------------------------------------------------------------------------------

    def _record_callback(self, p: int, held: list[float]):
        w = self.world
        ctx = self._ctx
        cpair, crec, stats = w._cpair, w._crec, w._stats
        M = w.max_contacts

        def post_solve(arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
            J = arbiter.total_impulse  # received by shape a (= body a): b receives -J
            jx = J.x - held[0]  # applied in this step (_materials_callback)
            jy = J.y - held[1]
            if jx == 0.0 and jy == 0.0:
                return
            n = arbiter.normal  # from shape a to shape b
            k = ctx[2]
            ctx[2] = k + 1
            b = ctx[0]
            nx, ny = n.x, n.y
            j, jt = -(jx * nx + jy * ny), -(jy * nx - jx * ny)  # along n and t = (-ny, nx)
            if p == stats[b, STAT_WATCH]:  # counted and summed also where the records are full
                stats[b, STAT_WATCHED] += 1
                crec[b, M, REC_WATCHED_J] += j
            if k >= M:  # the records are full: summed in row M (layout.RECORD)
                crec[b, M, REC_J] += j
                crec[b, M, REC_JT] += jt
                return
            px = py = 0.0
            points = arbiter.contact_point_set.points
            for cp in points:
                px += cp.point_a.x + cp.point_b.x
                py += cp.point_a.y + cp.point_b.y
            m = 2.0 * max(len(points), 1)
            cpair[b, k] = p
            rec = crec[b, k]
            rec[REC_TIME] = ctx[1]
            rec[REC_PX] = px / m
            rec[REC_PY] = py / m
            rec[REC_NX] = nx
            rec[REC_NY] = ny
            rec[REC_J] = j
            rec[REC_JT] = jt
            rec[REC_HELD] = 0.0

        return post_solve

    def step(self, dt: float) -> None:
        """Advance every element by ``dt`` s in ``substeps`` pymunk steps; write the results
        (the world checks for bodies Chipmunk let through a cushion, ``World._check_off_table``).
        """
        w = self.world
        n = int(w.solver.substeps)
        h = dt / n
        state = w._state
        stats = w._stats
        driven = [i for i in range(w.n_bodies) if w.driven[i]]
        pivot = w.pivot
        forces = w._forces
        ctx = self._ctx
        for b, el in enumerate(self._elements):
            ctx[0] = b
            ctx[2] = 0
            sp = el.space
            bodies = el.bodies
            push = [(bodies[i], (float(forces[b, i, 0]), float(forces[b, i, 1]))) for i in driven]
            coef = 1.0  # Chipmunk's dt_coef of the first pymunk step (_materials_callback)
            if dt > 0.0 and h != el.h:
                if el.h:  # cached impulses of another step length (see _set_cloth)
                    self._set_cloth(b, renew=True)
                    coef = h / el.h
                el.h = h
            if dt > 0.0:
                for k in range(n):
                    ctx[1] = (k + 1) * h
                    ctx[3] = coef if k == 0 else 1.0
                    for body, f in push:
                        body.force = f
                    sp.step(h)
            row = state[b]
            for i, body in enumerate(bodies):
                if w.static[i]:
                    continue
                r = row[i]
                decel, spin = el.decel[i]
                r[ANGLE] = body.angle
                w_i = body.angular_velocity
                if spin > 0.0 and abs(w_i) <= STOPPED * spin * h:
                    w_i = body.angular_velocity = 0.0  # stopped by the cloth (see _set_cloth)
                r[OMEGA] = w_i
                if pivot[i]:  # reported at its pin, at rest (see the module docstring)
                    continue
                x, y = body.position
                vx, vy = body.velocity
                if decel > 0.0 and math.hypot(vx, vy) <= STOPPED * decel * h:
                    vx = vy = 0.0
                    body.velocity = (0.0, 0.0)
                r[X] = x
                r[Y] = y
                r[VX] = vx
                r[VY] = vy
            stats[b, STAT_CONTACTS] = ctx[2]
            if dt > 0.0:
                stats[b, STAT_SUBSTEPS] = n
                stats[b, STAT_ITERATIONS] = n * sp.iterations
        self._written[:] = state


def _materials_callback(cell: list[float], held: list[float], ctx: list[Any]):
    """pre_solve: the scene's effective restitution and friction of one pair (``cell``); and
    into ``held`` the part of the impulse the arbiter holds that this step does not apply
    (subtracted from ``total_impulse`` after the solve, ``_record_callback``):

    * Chipmunk keeps a separated pair's arbiter cached (``collision_persistence`` steps) and,
      where the pair touches again, starts it as a first contact (no warm start) with the old
      accumulated impulse still in it, so ``total_impulse`` after the solve counted an impulse
      not applied in this step (a rack of 15 pucks: 0.41 N s off a body's change of momentum):
      all of it is held;
    * a warm-started arbiter applies its cached impulse ``J`` again, times ``dt_coef`` (this
      pymunk step's length over the last one's, ``ctx[3]``), and its accumulator goes on from
      ``J`` unscaled: the step applied ``total_impulse + (dt_coef - 1) J``, so ``(1 - dt_coef) J``
      is held. Where ``world.step``'s length changed, a held contact's first record was off by
      ``(dt_coef - 1) J`` (a 2 N push held on a cushion: -6.7 %, +50 %; walk W29a F1)."""

    def pre_solve(arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        arbiter.restitution = cell[0]
        arbiter.friction = cell[1]
        if arbiter.is_first_contact:
            J = arbiter.total_impulse
            held[0] = J.x
            held[1] = J.y
        elif ctx[3] != 1.0:
            J = arbiter.total_impulse
            held[0] = (1.0 - ctx[3]) * J.x
            held[1] = (1.0 - ctx[3]) * J.y
        else:
            held[0] = held[1] = 0.0

    return pre_solve
