"""The world: B copies of a scene, stepped together.

State is a struct of numpy arrays with a leading batch axis (named views of one packed array, see
``physics.layout``)::

    world.state.positions   [B, N, 2]  m             world.state.angles  [B, N]  rad, CCW from +x
    world.state.velocities  [B, N, 2]  m/s           world.state.omegas  [B, N]  rad/s, CCW > 0

Per-body parameters are ``[B, N]`` arrays too, so every element can carry its own masses, sizes
and materials; the list of bodies and their shape kinds is fixed. Cushions (the ``walls`` effect)
are reported as bodies ``N..N+3`` (``WALL_NAMES``).

Every array a world exposes is read-only, and its attributes cannot be rebound: a value the
kernels use changes only through a validated change (:meth:`World.edit`, or the setters
``set_body``, ``set_material``, ``set_table``, ``set_state``, ``set_force``, ``reset``), so
what a user reads is what the kernels simulate. (The one exception is :attr:`World.buffers`,
the kernels' own packed buffers, which compiled batch kernels take and write: see
:meth:`World.run`.)
"""

from __future__ import annotations

import math
import os
import sys
import threading
import warnings
import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from spinstrike.physics.edit import (
    WorldEdit,
    as_batch,
    batch_rows,
    check_snapshot,
    first_overlap,
    warn_tolerance_above_radii,
)
from spinstrike.physics.events import pair_bodies, pair_geometry
from spinstrike.physics.jit import jit
from spinstrike.physics.kernels import STEP, TRAVEL_LIMIT, BatchKernel, Flags
from spinstrike.physics.layout import (
    ANGLE,
    CALENDAR_BODIES,
    CF_DT,
    CF_OVERLAP_TOL,
    CF_SETTLE,
    CF_TOL,
    CF_ZENO_SPEED,
    CI_CONTACT_FRICTION,
    CI_FIXED,
    CI_ITERATIONS,
    CI_MAX_EVENTS,
    CI_MAX_ITERATIONS,
    CI_ROTATION,
    CI_SUBSTEPS,
    CI_TABLE_FRICTION,
    CI_ZENO_IMPACTS,
    FALLBACK,
    FALLBACK_CAPPED,
    FALLBACK_JAMMED,
    FALLBACK_NONE,
    FALLBACK_NONFINITE,
    FALLBACK_SETTLED,
    FALLBACK_UNRESOLVED,
    FLOAT_FIELDS,
    FRICTION,
    FRICTION_DECEL,
    FX,
    FY,
    H_B,
    H_CALENDAR,
    H_FLOAT,
    H_INT,
    H_M,
    H_N,
    H_P,
    HALF_H,
    HALF_LENGTH,
    HALF_W,
    HEADER_SIZE,
    INT_FIELDS,
    INV_INERTIA,
    INV_MASS,
    LEVEL_CAN_JAM,
    LEVEL_MANY_BODIES,
    LEVEL_ONE_PAIR,
    LEVEL_ONE_PAIR_FRICTION,
    OMEGA,
    PARAM_COLUMNS,
    RADIUS,
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
    STAT_EVENTS,
    STAT_FALLBACK,
    STAT_ITERATIONS,
    STAT_SUBSTEPS,
    STAT_WATCH,
    STAT_WATCHED,
    STATE_COLUMNS,
    VX,
    VY,
    X,
    Y,
    field_shapes,
)
from spinstrike.physics.scene import (
    WALL_NAMES,
    ExactSolver,
    FixedSolver,
    PymunkSolver,
    Scene,
    SceneError,
    load_scene,
    solver_over,
)
from spinstrike.physics.shapes import radius_of_gyration
from spinstrike.physics.solvers import MAX_SETTLE_SUBSTEPS

__all__ = ["Buffers", "Contacts", "SimulationError", "State", "StepStats", "World"]

#: batch size from which the parallel kernels are used
PARALLEL_BATCH = 256

#: (fallback, capped) of each fallback code, for StepStats by one lookup: the three
#: comparisons and the flags of three arrays were ~4 of the ~10 us of a first ``last_step`` read
#: after a step (walk W28b F2: a single exact env's step is ~9 us)
_FALLBACK_FLAGS = np.zeros((len(FALLBACK), 2), bool)
_FALLBACK_FLAGS[[FALLBACK_JAMMED, FALLBACK_SETTLED, FALLBACK_CAPPED], 0] = True
_FALLBACK_FLAGS[FALLBACK_CAPPED, 1] = True

#: one parallel kernel at a time in a process: numba's workqueue threading layer (its choice
#: where neither TBB nor OpenMP is installed) aborts the process when two threads run parallel
#: regions at once (a threaded evaluation of two vector envs)
_PARALLEL_LOCK = threading.Lock()
#: whether this process has run a parallel kernel, and whether it is a fork of one that had:
#: GNU OpenMP (numba's layer here) kills a forked child at its first parallel region
#: ("fork() called from a process already using GNU OpenMP"), and a multiprocessing Pool then
#: waits for it forever, so such a child runs the serial kernels
_parallel_ran = False
_forked_after_parallel = False


#: every live world, so that a forked child gets each its own lock
_WORLDS: weakref.WeakSet = weakref.WeakSet()


def _after_fork_in_child() -> None:
    global _forked_after_parallel
    _forked_after_parallel = _forked_after_parallel or _parallel_ran
    # a world another thread was stepping or editing at the fork: its lock came over held, by
    # a thread the child does not have, and the child's first step of its copy waited for ever
    for world in list(_WORLDS):
        world.__dict__["_lock"] = threading.RLock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_in_child)

#: the per-element parameters an edit can change: (snapshot key, World attribute)
_PARAMETER_ARRAYS = [("mass", "_mass"), ("radius", "_radius"), ("half_length", "_half_length"),
                     ("inertia", "_inertia"), ("table_friction", "_table_mu"),
                     ("table_half_size", "_half"), ("materials", "_materials")]


def _read_only(a: np.ndarray) -> np.ndarray:
    """A view of ``a`` that numpy refuses to make writeable again (a plain view's flag could be
    set back, and a write then reached the world unchecked: walk W24a F7)."""
    return np.lib.stride_tricks.as_strided(a, writeable=False)


@dataclass(frozen=True)
class State:
    """Named, read-only views of the world's state (see module docstring for units).

    *Live* views, as MuJoCo's ``data.qpos``: they show the state as the world steps, so a
    trajectory is recorded with ``.copy()`` (``traj.append(world.state.positions.copy())``)
    or ``world.get_state()``; appending the views themselves keeps N references to the last
    state (walk W24a F3)."""

    positions: np.ndarray
    angles: np.ndarray
    velocities: np.ndarray
    omegas: np.ndarray


@dataclass(frozen=True)
class Buffers:
    """A world's two packed buffers (``physics.layout``), what compiled batch kernels take
    first (``World.run``). ``fbuf``: float64 fields; ``ibuf``: int64 header and fields."""

    fbuf: np.ndarray
    ibuf: np.ndarray


@dataclass(frozen=True)
class Contacts:
    """The contacts one ``step`` resolved, as flat read-only arrays (each element has its own
    count).

    Attributes:
        batch: [K] batch index.  body_a, body_b: [K] body indices (b >= N: a cushion).
        time: [K] s since the start of the step.  point: [K, 2] m.
        normal: [K, 2] unit, from a to b.  impulse: [K] normal impulse j >= 0, N s.
        tangent_impulse: [K] friction impulse along t = (-n_y, n_x), N s.
        dropped: [B] contacts not stored because an element exceeded ``max_contacts``.
        dropped_impulse, dropped_tangent_impulse: [B] their normal and friction impulses,
            summed (N s): ``impulse`` summed per element plus these is the step's total.
        held: [K] bool, a held contact: a disk the exact solver held on a cushion under its
            force, recorded once when the hold ends, its impulse the push over the time held
            (the other records are impacts; the videos mark impacts only).

    Per body, ``m dv = F dt + sum(-(j n + jt t))`` over its records as a (``+(j n + jt t)``
    as b), to round-off, on every solver, where no cloth friction acts on it
    (``table_friction``: a deceleration, no record): a disk the exact solver holds on a
    cushion under its force is one record when the rest ends (at the step's end, or when
    something hits it), its impulse the cushion's whole push (``docs/design.md`` §4). The
    exception: the exact solver's held pairs (a striker left on a spinning rod) record their
    RATTLE substeps' impulses to ~1e-4 relative (``StepStats.substeps``).
    """

    batch: np.ndarray
    body_a: np.ndarray
    body_b: np.ndarray
    time: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    impulse: np.ndarray
    tangent_impulse: np.ndarray
    dropped: np.ndarray
    dropped_impulse: np.ndarray
    dropped_tangent_impulse: np.ndarray
    held: np.ndarray

    def __post_init__(self) -> None:
        for a in self.__dict__.values():
            a.flags.writeable = False

    def __len__(self) -> int:
        return int(self.batch.shape[0])


@dataclass(frozen=True)
class StepStats:
    """Cost accounting of the last step, per element (myPhysicsLab-style).

    Attributes:
        events: impacts and checkpoints processed by the exact solver.
        iterations: time-of-impact iterations (conservative advancement and bracketing).
        substeps: fixed substeps (the fixed solver, or the exact solver's settling; also, not
            flagged as ``fallback``, an exact step holding one pair's sustained e = 0 contact
            as a constraint: README, "Known failures").
        contacts: impulses applied.
        fallback: the exact solver settled the rest of the step with fixed substeps (a run of
            resting bounces, or ``max_events`` reached), or solved a jam (sweeps that did not
            converge) whose pairs have contact friction as a block without it, so that their
            friction in it was lost (a self-locking wedge squirts out: README, known failures).
        capped: that settling needed more substeps than its cap (``MAX_SETTLE_SUBSTEPS``,
            10^6), so the bound that keeps bodies from passing through each other did not hold
            (``World.step`` warns): forces or speeds about 10^6 times what the bodies' sizes
            allow within a step (a force of 10^14 N on a 0.3 kg disk in a 20 ms step).
        watched: impulses applied to the pair :meth:`World.watch` names, every one (also where
            there were more contacts than ``max_contacts`` records); 0 when none is watched.
        watched_impulse: the sum of those impulses along their normals (N s), every one.
    """

    events: np.ndarray
    iterations: np.ndarray
    substeps: np.ndarray
    contacts: np.ndarray
    fallback: np.ndarray
    capped: np.ndarray
    watched: np.ndarray
    watched_impulse: np.ndarray


class SimulationError(SceneError):
    """A step left a world's state no longer finite (NaN or infinite): inputs beyond what
    float64 carries, such as a speed of 1e160 m/s or a force of 1e200 N; the world keeps that
    state (``restore`` a snapshot or ``reset``). Or, on a walled table, a body would have
    travelled so far in the step that float64 cannot place it on the table (a puck at 1e12 m/s
    in a 20 ms step on a 0.8 m table): those elements were not stepped. ``elements``: the batch
    elements concerned."""

    def __init__(self, message: str, elements: np.ndarray) -> None:
        super().__init__(message)
        self.elements = elements


class World:
    """B copies of a scene, stepped together by the scene's (or the given) solver.

    Args:
        scene: a :class:`~spinstrike.physics.scene.Scene`, a dict, a YAML string or a path.
        batch_size: B, the number of copies.
        solver: overrides the scene's solver block: a dict such as ``{"mode": "fixed",
            "substeps": 8}``, a mode name, or a solver model. Of the scene's mode, it keeps
            the scene's values it leaves out; another mode, or a model, replaces the block.
        max_contacts: contacts stored per element per step (more are counted in
            ``Contacts.dropped``, never silently lost).

    Attributes (read-only):
        scene, solver, batch_size, n_bodies, max_contacts, names (bodies, then cushions),
        shapes, effects and their flags (``rotation``, ``walls``, ``contact_friction``,
        ``table_friction``), ``static``/``pivot``/``driven`` [N], ``mass`` [B, N] kg,
        ``inertia`` [B, N] kg m^2, ``radius`` [B, N] m (disk radius / half the rod thickness),
        ``half_length`` [B, N] m, ``table_mu`` [B], ``gravity`` m/s^2, ``pair_a``/``pair_b``
        [P] the bodies of every contact pair, ``state``, ``forces``, ``time``, ``params``.
    """

    def __init__(self, scene: Any, batch_size: int = 1, solver: Any = None,
                 max_contacts: int = 64) -> None:
        self._lock = threading.RLock()
        _WORLDS.add(self)
        self.scene: Scene = load_scene(scene)
        for name, value in (("batch_size", batch_size), ("max_contacts", max_contacts)):
            if (isinstance(value, bool) or not isinstance(value, (int, np.integer))
                    or value < 1):
                raise SceneError(f"{name}: must be an integer >= 1 (got {value!r})")
        self.solver = (solver_over(self.scene.solver, solver) if solver is not None
                       else self.scene.solver)
        self._tolerance = (self.solver.tolerance if isinstance(self.solver, ExactSolver)
                           else 1e-9)
        self.batch_size = B = int(batch_size)
        self.max_contacts = int(max_contacts)
        self.effects = frozenset(self.scene.effects)
        self.rotation = "rotation" in self.effects
        self.walls = "walls" in self.effects
        self.contact_friction = "contact_friction" in self.effects
        self.table_friction = "table_friction" in self.effects
        bodies = self.scene.bodies
        self.n_bodies = len(bodies)
        self.names: tuple[str, ...] = tuple(b.name for b in bodies) + (
            WALL_NAMES if self.walls else ())
        self.shapes = tuple(b.shape for b in bodies)
        self.static = _read_only(np.array([b.static for b in bodies]))
        self.pivot = _read_only(np.array([b.pivot for b in bodies]))
        self.driven = _read_only(np.array([b.driven for b in bodies]))
        self._fixed = _read_only(self.static | self.pivot)
        self._any_static = bool(self.static.any())
        self._any_fixed = bool(self._fixed.any())
        table = self.scene.table
        self.gravity = table.gravity

        # per-body physical parameters [B, N] and the table's friction [B] (private; the public
        # names are read-only views, made in _make_views)
        self._mass = np.tile([b.mass if not b.static else math.inf for b in bodies], (B, 1))
        self._radius = np.tile([b.core_radius for b in bodies], (B, 1)).astype(float)
        self._half_length = np.tile([b.half_length for b in bodies], (B, 1)).astype(float)
        self._inertia = np.tile([b.moment if not b.static else math.inf for b in bodies], (B, 1))
        self._table_mu = np.full(B, table.friction)

        pairs = self._pair_list()
        self._pair_rows: dict[tuple[str, str], np.ndarray] = {}
        #: many bodies: the exact solver steps on its broadphase and event calendar, and its
        #: settling and the fixed solver visit only the pairs close enough to touch (lists made
        #: in the calendar's rows)
        self._calendar = (isinstance(self.solver, (ExactSolver, FixedSolver))
                          and self.n_bodies >= CALENDAR_BODIES)
        self._alloc_buffers(len(pairs[0]))
        size = table.size if table.size is not None else (math.inf, math.inf)
        self._half[:] = 0.5 * np.asarray(size, dtype=float)
        self._pair_a[:], self._pair_b[:] = pairs
        if self._calendar:
            self._pair_index[:] = -1
            self._pair_index[pairs[0], pairs[1]] = np.arange(len(pairs[0]))
            body = np.asarray(pairs[1]) < self.n_bodies
            self._pair_index[np.asarray(pairs[1])[body], np.asarray(pairs[0])[body]] = \
                np.flatnonzero(body)
        self._init_materials()
        self._params[:] = self._derive_params(self._mass, self._inertia, self._radius,
                                              self._half_length, self._table_mu)
        self._configure_solver()
        warn_tolerance_above_radii(self, self._radius)
        self._initial = self._initial_state()
        self._state[:] = np.nan  # nothing placed yet: reset() below places every body, checked
        self._make_views()
        self._backend = None
        self._revision = 0
        self._parallel = B >= PARALLEL_BATCH
        #: compile-time flags of the kernels (kernels.FLAGS)
        self.flags = Flags(isinstance(self.solver, FixedSolver), self.rotation,
                           self.contact_friction, self.table_friction, self._contact_level(),
                           self._can_lie_flat(pairs))
        #: what follows a batch kernel's own arguments: the flags (parallel), or the range of
        #: elements then the flags (the serial body); and the kernels' compiled entry points
        self._tail = self.flags if self._parallel else (0, B, *self.flags)
        self._entries: dict = {}
        #: counts the changes of the world (steps, edits, restores): an edit whose copies
        #: are older is refused (``WorldEdit.commit``)
        self._version = 0
        self._dt = 0.0
        self._last_step: StepStats | None = None
        self._last_contacts: Contacts | None = None
        e, ei = np.zeros(0), np.zeros(0, dtype=np.int64)
        self._no_contacts = Contacts(ei, ei, ei, e, np.zeros((0, 2)), np.zeros((0, 2)), e,
                                     e.copy(), np.zeros(B, dtype=np.int64), np.zeros(B),
                                     np.zeros(B), np.zeros(0, dtype=bool))
        self._frozen = True
        self.reset()  # the scene's placement, checked as any other change
        if isinstance(self.solver, PymunkSolver):
            self._attach_backend()

    def _contact_level(self) -> int:
        """The ``jam`` flag's level (``kernels.FLAGS``, ``layout.LEVEL``)."""
        if self._calendar:
            return LEVEL_MANY_BODIES
        if len(self._pair_a) >= 2:
            return LEVEL_CAN_JAM
        return LEVEL_ONE_PAIR_FRICTION if self.contact_friction else LEVEL_ONE_PAIR

    def _can_lie_flat(self, pairs: tuple[list[int], list[int]]) -> bool:
        """The ``flat`` flag (``kernels.FLAGS``): a contact pair of two rods, or of a rod and a
        cushion, which the solvers resolve at both ends when it lies flat
        (``contacts.flat_points``). Shapes never change, so neither does the flag."""
        rod = [shape == "rod" for shape in self.shapes] + [True] * 4  # the cushions
        return any(rod[a] and rod[b] for a, b in zip(*pairs, strict=True))

    def __setattr__(self, name: str, value: Any) -> None:
        if name.startswith("_") or not self.__dict__.get("_frozen", False):
            object.__setattr__(self, name, value)
            return
        raise AttributeError(
            f"World.{name} is read-only: change parameters with world.edit(), set_body, "
            "set_material or set_table, and state with set_state, set_force or reset")

    def _attach_backend(self) -> None:
        from spinstrike.physics.pymunk_backend import PymunkBackend

        self._backend = PymunkBackend(self)

    # ------------------------------------------------------------------------------------------
    # construction helpers
    # ------------------------------------------------------------------------------------------

    def _pair_list(self) -> tuple[list[int], list[int]]:
        """Every pair that can touch: body pairs (not two static bodies), then body-cushion. In
        a pair with a static body, as with a cushion, the static body is b (the README's
        convention), wherever the scene lists it."""
        bodies = self.scene.bodies
        N = self.n_bodies
        pa, pb = [], []
        for i in range(N):
            for j in range(i + 1, N):
                if bodies[i].static and bodies[j].static:
                    continue
                a, b = (j, i) if bodies[i].static else (i, j)
                pa.append(a)
                pb.append(b)
        if self.walls:
            for i in range(N):
                if not bodies[i].static:
                    for w in range(4):
                        pa.append(i)
                        pb.append(N + w)
        return pa, pb

    def _init_materials(self) -> None:
        mats = self.scene.materials
        self._materials[:, :, RESTITUTION] = mats.restitution
        self._materials[:, :, FRICTION] = mats.friction
        for pair in mats.pairs:
            rows = self.pair_rows(*pair.bodies)
            if pair.restitution is not None:
                self._materials[:, rows, RESTITUTION] = pair.restitution
            if pair.friction is not None:
                self._materials[:, rows, FRICTION] = pair.friction

    def pair_rows(self, a: str, b: str) -> np.ndarray:
        """Contact pairs between bodies ``a`` and ``b`` (``"walls"``: every cushion)."""
        rows = self._pair_rows.get((a, b))
        if rows is None:
            rows = self._pair_rows[a, b] = _read_only(self._find_pair_rows(a, b))
        return rows

    def _find_pair_rows(self, a: str, b: str) -> np.ndarray:
        def ids(name: str) -> set[int]:
            if name == "walls":
                return set(range(self.n_bodies, self.n_bodies + 4)) if self.walls else set()
            return {self.index(name)}

        ia, ib = ids(a), ids(b)
        pa, pb = self._pair_a, self._pair_b
        rows = [p for p in range(len(pa))
                if (pa[p] in ia and pb[p] in ib) or (pa[p] in ib and pb[p] in ia)]
        if not rows:
            raise SceneError(f"materials: no contact pair between {a!r} and {b!r}")
        return np.asarray(rows)

    def _derive_params(self, mass: np.ndarray, inertia: np.ndarray, radius: np.ndarray,
                       half_length: np.ndarray, table_mu: np.ndarray) -> np.ndarray:
        """Packed parameter rows ``[n, N, 6]`` (inverse masses and inertias, sizes, cloth
        decelerations) derived from the given elements' values: the one place they are
        computed."""
        p = np.empty(mass.shape + (PARAM_COLUMNS,))
        dynamic = ~self.static & ~self.pivot
        with np.errstate(divide="ignore"):
            p[..., INV_MASS] = np.where(dynamic, 1.0 / mass, 0.0)
            p[..., INV_INERTIA] = np.where(~self.static & self.rotation, 1.0 / inertia, 0.0)
        p[..., RADIUS] = radius
        p[..., HALF_LENGTH] = half_length
        sliding = dynamic & ~self.driven
        decel = table_mu[:, None] * self.gravity * float(self.table_friction)
        p[..., FRICTION_DECEL] = np.where(sliding, decel, 0.0)
        # (over: a deceleration near the float range over a small k is an infinite one, which
        # stops the spin at once, as it should; the numpy warning named nothing)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            k = radius_of_gyration(np.where(self.static, 1.0, mass),
                                   np.where(self.static, 1.0, inertia))
            p[..., SPIN_DECEL] = np.where(~self.static & ~self.driven & (k > 0), decel / k, 0.0)
        return p

    def _alloc_buffers(self, n_pairs: int) -> None:
        """One float64 and one int64 buffer holding every array the kernels touch (see
        ``physics.layout``): state, parameters, forces, table, materials, contact records,
        statistics, the solvers' scratch rows and the solver configuration."""
        shapes = field_shapes(self.batch_size, self.n_bodies, n_pairs, self.max_contacts,
                              self._calendar)
        offsets: dict[str, int] = {}
        totals = []
        for table, start in ((FLOAT_FIELDS, 0), (INT_FIELDS, HEADER_SIZE)):
            total = start
            for name in table.names:
                offsets[name] = total
                total += math.prod(shapes[name])
            totals.append(total)
        self._fbuf = np.zeros(totals[0])
        self._ibuf = np.zeros(totals[1], dtype=np.int64)
        self._ibuf[[H_B, H_N, H_P, H_M, H_CALENDAR]] = (self.batch_size, self.n_bodies, n_pairs,
                                                        self.max_contacts, self._calendar)
        self._ibuf[H_FLOAT:H_FLOAT + len(FLOAT_FIELDS)] = [offsets[f] for f in FLOAT_FIELDS.names]
        self._ibuf[H_INT:H_INT + len(INT_FIELDS)] = [offsets[f] for f in INT_FIELDS.names]
        self._make_buffer_views()
        self._stats[:, STAT_WATCH] = -1  # no pair watched (World.watch); kept in pickles

    def _make_buffer_views(self) -> None:
        """The private named views of the buffers: ``_state``, ``_params``, ... (one per
        field of ``FLOAT_FIELDS`` / ``INT_FIELDS``)."""
        ib = self._ibuf
        shapes = field_shapes(int(ib[H_B]), int(ib[H_N]), int(ib[H_P]), int(ib[H_M]),
                              bool(ib[H_CALENDAR]))
        for table, buf, head in ((FLOAT_FIELDS, self._fbuf, H_FLOAT), (INT_FIELDS, ib, H_INT)):
            for name in table.names:
                o = int(ib[head + table[name]])
                view = buf[o:o + math.prod(shapes[name])].reshape(shapes[name])
                object.__setattr__(self, "_" + name, view)

    def _configure_solver(self) -> None:
        s = self.solver
        self._icfg[CI_ROTATION] = self.rotation
        self._icfg[CI_CONTACT_FRICTION] = self.contact_friction
        self._icfg[CI_TABLE_FRICTION] = self.table_friction
        self._icfg[CI_FIXED] = isinstance(s, FixedSolver)
        self._fcfg[CF_OVERLAP_TOL] = self._tolerance
        if isinstance(s, ExactSolver):
            self._fcfg[[CF_TOL, CF_ZENO_SPEED, CF_SETTLE]] = (s.tolerance, s.zeno_speed,
                                                             s.settle_substep)
            self._icfg[[CI_MAX_EVENTS, CI_MAX_ITERATIONS, CI_ZENO_IMPACTS]] = (
                s.events_for(self.n_bodies), s.max_iterations, s.zeno_impacts)
        elif isinstance(s, FixedSolver):
            self._icfg[[CI_SUBSTEPS, CI_ITERATIONS]] = (s.substeps, s.iterations)

    def _initial_state(self) -> np.ndarray:
        s = np.zeros((self.n_bodies, STATE_COLUMNS))
        for i, b in enumerate(self.scene.bodies):
            s[i, [X, Y]] = b.position
            s[i, ANGLE] = b.angle
            s[i, [VX, VY]] = b.velocity
            s[i, OMEGA] = b.omega
        return s

    #: public read-only views, rebuilt after unpickling
    _PUBLIC_VIEWS = ("state", "mass", "radius", "half_length", "inertia", "table_mu", "pair_a",
                     "pair_b")

    def _make_views(self) -> None:
        s = self._state
        views = {"state": State(_read_only(s[..., X:Y + 1]), _read_only(s[..., ANGLE]),
                                _read_only(s[..., VX:VY + 1]), _read_only(s[..., OMEGA])),
                 "mass": self._mass, "radius": self._radius, "half_length": self._half_length,
                 "inertia": self._inertia, "table_mu": self._table_mu,
                 "pair_a": self._pair_a, "pair_b": self._pair_b}
        for name, value in views.items():
            object.__setattr__(self, name,
                               _read_only(value) if isinstance(value, np.ndarray) else value)

    def __getstate__(self) -> dict:
        fields = {"_" + n for n in (*FLOAT_FIELDS.names, *INT_FIELDS.names)}
        drop = fields | set(self._PUBLIC_VIEWS) | {"_backend", "_last_step", "_last_contacts",
                                                   "_entries", "_lock"}
        with self._lock:  # the buffers as one step left them (pickled after this returns:
            # a copy or pickle made while another thread stepped was torn, walk W26b F3)
            return {k: v.copy() if isinstance(v, np.ndarray) else v
                    for k, v in self.__dict__.items() if k not in drop}

    def __copy__(self) -> World:
        """A deep copy: a shallow one shared the state buffers, so stepping the copy moved the
        original (walk W25 F8)."""
        import copy

        return copy.deepcopy(self)

    def __setstate__(self, d: dict) -> None:
        self.__dict__.update(d)
        self.__dict__.setdefault("_version", 0)  # (pickled before it was kept)
        self.__dict__.update(_backend=None, _last_step=None, _last_contacts=None, _entries={},
                             _lock=threading.RLock())
        _WORLDS.add(self)
        self._make_buffer_views()
        self._make_views()
        if isinstance(self.solver, PymunkSolver):
            self._attach_backend()

    # ------------------------------------------------------------------------------------------
    # names and parameters
    # ------------------------------------------------------------------------------------------

    def index(self, name: str) -> int:
        """Index of a body or cushion by name."""
        try:
            return self.names.index(name)
        except ValueError:
            raise SceneError(f"unknown body {name!r}; bodies: {list(self.names)}") from None

    def body_index(self, body: int | str) -> int:
        """Index of a body (not a cushion) given by name or index."""
        if isinstance(body, str):
            i = self.index(body)
        elif isinstance(body, (int, np.integer)) and not isinstance(body, bool):
            i = int(body)
        else:
            raise SceneError(f"body: must be a name or an index (got {body!r})")
        if not 0 <= i < self.n_bodies:
            if isinstance(body, str):
                raise SceneError(f"body: {body!r} is a cushion, not a body (cushions have no "
                                 f"parameters or state; set_table moves them)")
            raise SceneError(f"body index {i} out of range [0, {self.n_bodies})")
        return i

    @property
    def params(self) -> np.ndarray:
        """Read-only packed parameter rows ``[B, N, 6]`` (see ``physics.layout``)."""
        return _read_only(self._params)

    @property
    def tolerance(self) -> float:
        """Overlap (m) beyond which bodies count as overlapping: the exact solver's tolerance,
        else 1e-9 m."""
        return self._tolerance

    def edit(self, env: Any = None) -> WorldEdit:
        """A validated change of elements ``env`` (all if None): parameters, materials, table
        and state set together, checked once and written once (see ``physics.edit``)::

            with world.edit(env) as e:
                e.set_body("rod", length=lengths)
                e.set_state(positions=p, angles=a, velocities=0.0, omegas=0.0)
        """
        return WorldEdit(self, env)

    def set_body(self, body: int | str, *, mass: Any = None, radius: Any = None,
                 length: Any = None, thickness: Any = None, inertia: Any = None,
                 env: Any = None) -> None:
        """Change a body's numeric parameters, for all elements or those in ``env``.

        Values are scalars or arrays over the selected elements (kg, m, m, m, kg m^2). The
        inertia is re-derived from the shape unless given here (or fixed by a numeric
        ``inertia`` in the scene). A change that makes bodies overlap raises
        :class:`SceneError` naming them, and the world is unchanged.
        """
        with self.edit(env) as e:
            e.set_body(body, mass=mass, radius=radius, length=length, thickness=thickness,
                       inertia=inertia)

    def set_material(self, a: str, b: str, *, restitution: Any = None, friction: Any = None,
                     env: Any = None) -> None:
        """Change the restitution / friction of the pair(s) between ``a`` and ``b``."""
        with self.edit(env) as e:
            e.set_material(a, b, restitution=restitution, friction=friction)

    def set_table(self, *, friction: Any = None, size: Any = None, env: Any = None) -> None:
        """Change the table's friction coefficient or size ([w, h], m) per element; a size
        that leaves a body outside the table (with ``walls``) raises :class:`SceneError`."""
        with self.edit(env) as e:
            e.set_table(friction=friction, size=size)

    def restitution(self, a: str, b: str) -> np.ndarray:
        """Restitution of the pair between ``a`` and ``b`` per element, shape [B] (``"walls"``:
        the cushions', if the four agree; else name one, e.g. ``"wall_left"``)."""
        return self._material(a, b, RESTITUTION, "restitution")

    def friction(self, a: str, b: str) -> np.ndarray:
        """Contact friction coefficient of the pair between ``a`` and ``b`` per element, [B]
        (``"walls"`` as for :meth:`restitution`)."""
        return self._material(a, b, FRICTION, "friction")

    def watch(self, a: str, b: str) -> None:
        """Count every impulse between bodies ``a`` and ``b`` in ``last_step.watched``: the
        contact records keep the first ``max_contacts`` of a step, so counting a pair's
        contacts in them misses those beyond (an env's hits in a step that settles a rod
        pressed into a cushion). One pair at a time; it stays watched from step to step."""
        rows = self.pair_rows(a, b)
        if len(rows) != 1:
            raise SceneError(f"watch: one pair of bodies, not {a!r} with {b!r}")
        self._stats[:, STAT_WATCH] = int(rows[0])

    def _material(self, a: str, b: str, column: int, field: str) -> np.ndarray:
        values = self._materials[:, self.pair_rows(a, b), column]
        if np.any(values != values[:, :1]):  # "walls": four cushions set apart
            raise SceneError(f"{field}: the pairs between {a!r} and {b!r} differ "
                             f"({values[0].tolist()} in element 0); name one cushion "
                             f"({', '.join(WALL_NAMES)})")
        return values[:, 0].copy()

    @property
    def table_half_size(self) -> np.ndarray:
        """Read-only [B, 2] half width and half height of the table, m (inf when unbounded)."""
        return _read_only(self._half)

    # ------------------------------------------------------------------------------------------
    # state
    # ------------------------------------------------------------------------------------------

    def set_state(self, *, positions: Any = None, angles: Any = None, velocities: Any = None,
                  omegas: Any = None, env: Any = None, body: int | str | None = None) -> None:
        """Set (part of) the state, for all elements or those in ``env``, all bodies or ``body``.

        Arrays broadcast to ``[b, n, 2]`` / ``[b, n]`` for the selection, as numpy broadcasts:
        a 1-D ``omegas`` of length n is per body, for every element (where b == n too: give
        per-element values as ``[b, 1]``, or one body's with ``body=``). To move a body of
        yours (pymunk's kinematic body), drive it: ``driven: true`` and ``set_force``, or its
        velocity each step; positions set into contact are refused (an overlap). Raises
        :class:`SceneError` for NaN, for moving a static body or a pivot's centre, for spin
        without the ``rotation`` effect, or for a change that makes bodies overlap by more than
        the tolerance; the world is unchanged then.
        """
        with self.edit(env) as e:
            e.set_state(positions=positions, angles=angles, velocities=velocities,
                        omegas=omegas, body=body)

    @property
    def time(self) -> np.ndarray:
        """Read-only [B] simulated time of each element since construction or its last reset,
        s."""
        return _read_only(self._time)

    @property
    def dt(self) -> float:
        """Length of the last (or running) step, s."""
        return self._dt

    def get_state(self, parameters: bool = False) -> dict[str, np.ndarray]:
        """A copy of the full physical state (state arrays, forces, time), for ``restore``, with
        the bodies' names (``bodies``: ``restore`` refuses a snapshot of other bodies).

        ``parameters=True`` adds the per-element parameters an edit changes (masses, moments,
        sizes, materials, the table's friction and size), so that ``restore`` also undoes an
        edit: what a snapshot of a randomised episode needs (an env's ``get_physics_state``)."""
        with self._lock:  # of one step, whatever other threads do (walk W26b F3)
            snap = {"state": self._state.copy(), "forces": self._forces.copy(),
                    "time": self._time.copy(), "bodies": np.array(self.names)}
            if parameters:
                snap |= {key: getattr(self, name).copy() for key, name in _PARAMETER_ARRAYS}
        return snap

    def restore(self, snapshot: dict[str, np.ndarray], env: Any = None) -> None:
        """Put back a snapshot from ``get_state`` (all elements, or those in ``env``); its
        parameters too, if it has them. With ``env``, the snapshot is either the whole batch's
        (its rows ``env`` are put back) or has one row per selected element (a B = 1 world's
        snapshot into element ``env=[i]``, walk W24a F9); ``load_element`` copies an element
        of a live world."""
        with self._lock:
            self._restore(snapshot, env)

    def _restore(self, snapshot: dict[str, np.ndarray], env: Any) -> None:
        rows = batch_rows(env, self.batch_size)
        names = [("state", "_state"), ("forces", "_forces"), ("time", "_time")]
        missing = [key for key, _ in names if key not in snapshot]
        have = [key for key, _ in _PARAMETER_ARRAYS if key in snapshot]
        with_params = len(have) == len(_PARAMETER_ARRAYS)
        if have and not with_params:
            missing += [key for key, _ in _PARAMETER_ARRAYS if key not in snapshot]
        if missing:
            raise SceneError(f"snapshot: missing {missing} (get_state() has state, forces and "
                             f"time; get_state(parameters=True) adds "
                             f"{[key for key, _ in _PARAMETER_ARRAYS]})")
        if with_params:
            names += _PARAMETER_ARRAYS
        # (a snapshot saved before the names were recorded has none)
        theirs = [str(n) for n in np.ravel(snapshot.get("bodies", self.names))]
        if theirs != list(self.names):
            raise SceneError(f"snapshot: another scene's (its bodies are {theirs}; this world's "
                             f"are {list(self.names)})")
        arrays = {}
        for key, name in names:
            mine = getattr(self, name)
            value = np.asarray(snapshot[key])
            whole = value.shape == mine.shape
            if not whole and value.shape != (len(rows), *mine.shape[1:]):
                raise SceneError(f"snapshot: {key} shape {value.shape} is neither the whole "
                                 f"batch's {mine.shape} nor the selected elements' "
                                 f"{(len(rows), *mine.shape[1:])}")
            if name in ("_state", "_forces", "_time"):
                value = as_batch(value, value.shape, f"snapshot.{key}")
            elif value.dtype.kind not in "iuf" or np.isnan(value).any():
                # parameters may be inf (a static body's mass, an unbounded table)
                raise SceneError(f"snapshot: {key} must be numbers, not NaN")
            arrays[name] = value[rows] if whole else value
        check_snapshot(self, arrays)
        params = None
        if with_params:
            params = self._derive_params(arrays["_mass"], arrays["_inertia"], arrays["_radius"],
                                         arrays["_half_length"], arrays["_table_mu"])
        if isinstance(self.solver, ExactSolver) and len(self._pair_a):
            pm = self._params[rows] if params is None else params
            half = arrays.get("_half", self._half[rows])
            e, p, g = first_overlap(np.ascontiguousarray(arrays["_state"]), pm,
                                    np.ascontiguousarray(half), self._pair_a, self._pair_b,
                                    self.tolerance)
            if e >= 0:
                a, b = self.names[self._pair_a[p]], self.names[self._pair_b[p]]
                raise SceneError(f"snapshot.state: {a!r} and {b!r} overlap by {-g:.3g} m in "
                                 f"element {rows[e]}: the exact solver's states never overlap "
                                 f"(a snapshot of another solver's world, or edited?)")
        for name, value in arrays.items():
            getattr(self, name)[rows] = value
        if with_params:
            self._params[rows] = params
        self._version += 1
        self._sync_backend(params=with_params, state=True)

    def load_element(self, other: World, b: int, env: Any = None) -> None:
        """Copy element ``b`` of ``other`` (same scene layout) into elements ``env`` of this
        world: parameters, materials, table, state, forces and clock. For what-if runs (an oracle
        trying strikes in a scratch world) and replays."""
        if other.names != self.names or other.shapes != self.shapes:
            raise SceneError("load_element: the worlds' bodies differ")
        rows = batch_rows(env, self.batch_size)
        names = [name for _, name in _PARAMETER_ARRAYS] + ["_state", "_forces", "_time"]
        with other._lock:  # copied first: never both locks at once (two threads loading
            element = {name: getattr(other, name)[b].copy() for name in names}  # crosswise)
        with self._lock:
            for name in names:
                getattr(self, name)[rows] = element[name]
            self._params[rows] = self._derive_params(self._mass[rows], self._inertia[rows],
                                                     self._radius[rows],
                                                     self._half_length[rows],
                                                     self._table_mu[rows])
            self._version += 1
            self._sync_backend(params=True, state=True)

    def reset(self, env: Any = None) -> None:
        """Put the selected elements back in the scene's initial state (parameters are kept)."""
        with self.edit(env) as e:
            e.set_state(positions=self._initial[:, X:Y + 1], angles=self._initial[:, ANGLE],
                        velocities=self._initial[:, VX:VY + 1], omegas=self._initial[:, OMEGA])
            e.set_time(0.0)
            for i in np.flatnonzero(self.driven):
                e.set_force(int(i), 0.0)

    def set_force(self, body: int | str, force: Any, env: Any = None) -> None:
        """Apply a constant force (N, [.., 2]) to a ``driven`` body from now on."""
        with self.edit(env) as e:
            e.set_force(body, force)

    @property
    def forces(self) -> np.ndarray:
        """Read-only [B, N, 2] applied forces, N."""
        return _read_only(self._forces)

    @property
    def lock(self) -> threading.RLock:
        """The world's lock (re-entrant): every step, edit, snapshot (``get_state``,
        ``restore``, ``load_element``) and ``last_step``/``last_contacts`` holds it, so threads
        sharing a world take turns, step by step (its kernels run without the GIL: steps were
        lost or mixed up, walk W26b). Hold it to read several things of one step from a
        thread while another steps: ``with world.lock: x = world.state.positions.copy()``.
        Not pickled: a copy has its own."""
        return self._lock

    @property
    def revision(self) -> int:
        """How many times the world was changed other than by stepping (edits, ``restore``,
        ``load_element``): what was computed from its state at one revision (an env's
        observation) is stale at another."""
        return self.__dict__.get("_revision", 0)

    def _sync_backend(self, params: bool = False, state: bool = False) -> None:
        # every change other than a step comes through here (edits, restore, load_element)
        self._revision = self.revision + 1
        if self._backend is not None:
            if params:
                self._backend.sync_params()
            if state:
                self._backend.sync_from_world()

    def gaps(self, state: np.ndarray | None = None) -> np.ndarray:
        """[B, P] gap (m) of every contact pair (``pair_a``, ``pair_b``); negative = overlap."""
        return self._gaps_of(self._state if state is None else state, self._params, self._half)

    def _gaps_of(self, state: np.ndarray, params: np.ndarray, half: np.ndarray) -> np.ndarray:
        out = np.empty((state.shape[0], len(self._pair_a)))
        _pair_gaps(np.ascontiguousarray(state), np.ascontiguousarray(params),
                   np.ascontiguousarray(half), self._pair_a, self._pair_b, out)
        return out

    # ------------------------------------------------------------------------------------------
    # stepping
    # ------------------------------------------------------------------------------------------

    @property
    def buffers(self) -> Buffers:
        """The packed buffers compiled batch kernels take first (see :meth:`run`): writable,
        as the kernels write them; a write outside a kernel skips every check an edit makes."""
        return Buffers(self._fbuf, self._ibuf)

    def run(self, kernel: BatchKernel, *args: Any, dt: float | None = None) -> Any:
        """Run a compiled batch kernel over this world (the one place that dispatches a step).

        Sets the step length ``dt`` (s) if given, runs the kernel's parallel version from
        ``PARALLEL_BATCH`` elements and its serial one below (the world's compile-time
        ``flags`` appended to ``args``, see ``kernels.FLAGS``), or its Python version on the
        pymunk backend, then books the step (``last_step``, ``last_contacts``). Returns what
        the kernel returns.
        """
        lock = self._lock  # (acquire/release: half the cost of a with block, on every step)
        lock.acquire()
        try:
            return self._run(kernel, args, dt)
        finally:
            lock.release()

    def _run(self, kernel: BatchKernel, args: tuple, dt: float | None) -> Any:
        if dt is not None and dt != self._dt:
            self._set_dt(dt)
        self._version += 1
        if self._backend is not None:
            if kernel.stepwise is None:
                raise SceneError(f"{kernel.name}: not available on the pymunk backend")
            result = kernel.stepwise(self, *args)
        else:
            if self._parallel and _forked_after_parallel:
                self._go_serial()
            entry = self._entries.get(kernel)
            if entry is None:
                entry = self._entries[kernel] = kernel.entry(self._parallel, self._fbuf,
                                                             self._ibuf, args, self._tail)
            if self._parallel:
                global _parallel_ran
                _parallel_ran = True
                with _PARALLEL_LOCK:
                    result = entry(self._fbuf, self._ibuf, *args, *self._tail)
            else:
                result = entry(self._fbuf, self._ibuf, *args, *self._tail)
        # the statistics and contact records stay in the buffers until the next step: last_step
        # and last_contacts copy them out on first use
        d = self.__dict__  # the per-step bookkeeping bypasses __setattr__'s check (hot path)
        d["_last_step"] = d["_last_contacts"] = None
        return result

    def _go_serial(self) -> None:
        """Run the serial kernels from now on (a fork of a process that ran parallel ones)."""
        self.__dict__.update(_parallel=False, _tail=(0, self.batch_size, *self.flags),
                             _entries={})

    def _set_dt(self, dt: Any) -> None:
        if isinstance(dt, np.ndarray) and dt.ndim == 0 and dt.dtype.kind in "iuf":
            dt = dt.item()  # one number (np.clip's or np.asarray's, walk W24a F8)
        if isinstance(dt, bool) or not isinstance(dt, (int, float, np.integer, np.floating)):
            # float() took "0.1" and True (a 1 s step); one dt for every element
            raise SceneError(f"dt: must be one number of seconds, the same for all elements (got "
                             f"{dt!r} of type {type(dt).__name__})")
        value = float(dt)
        if not (math.isfinite(value) and value >= 0.0):
            raise SceneError(f"dt: must be a finite number >= 0 s (got {dt!r})")
        self._fcfg[CF_DT] = self._dt = value

    def step(self, dt: float) -> Contacts:
        """Advance every element by ``dt`` seconds; return the contacts resolved.

        Raises :class:`SimulationError` if an element's state is no longer finite after the
        step, or if a body of an element on a walled table would travel so far in it that
        float64 cannot place it on the table (beyond ``kernels.TRAVEL_LIMIT``, 2**32, times
        the table's smaller half size: that element is not stepped, the others are); warns
        (``RuntimeWarning``) if the exact solver's settling hit its cap of substeps
        (``last_step.capped``).
        """
        lock = self._lock  # the step, its report and its contacts (walk W26b)
        lock.acquire()
        try:
            if type(dt) is not float:  # checked here: run() reads None as "the last dt", and
                self._set_dt(dt)       # True == 1.0 would pass as an unchanged 1 s step
                dt = self._dt
            if self._run(STEP, (), dt) >= FALLBACK_CAPPED:
                self.check_fallback()
            if self.walls and isinstance(self.solver, FixedSolver) and \
                    not self.__dict__.get("_warned_off_table"):
                self._check_off_table()
            return self._step_contacts()
        finally:
            lock.release()

    def _check_off_table(self) -> None:
        """Warn (once) of bodies the fixed solver or the pymunk backend left with their centre
        off a walled table: their contacts are discrete (the fixed solver's said nothing, walk
        W24a F2: 1e60 N put a mallet 1.7e41 m off the table; such a step is now refused by the
        travel bound, ``kernels.TRAVEL_LIMIT``, and this stays a guard)."""
        off = (np.abs(self._state[..., X:Y + 1]) > self._half[:, None, :]).any(axis=-1)
        found = np.argwhere(off & ~self._fixed[None, :])
        if found.size:
            self._warn_off_table([(int(b), int(i)) for b, i in found])

    def check_fallback(self, code: np.ndarray | None = None, dt: float | None = None) -> None:
        """What ``step`` does after its kernel, for a kernel run with :meth:`run` (the envs'):
        raise :class:`SimulationError` for the elements the last step left no longer finite
        or did not step (their travel beyond the table's resolution), else warn for those
        whose settling was capped. ``code``: each element's ``fallback`` statistic
        (``layout.FALLBACK``), the last step's by default (an env's strike passes the worst of
        its chunks, and ``dt``, their length)."""
        if code is None:
            code = self._stats[:, STAT_FALLBACK]
        bad = np.flatnonzero(code == FALLBACK_NONFINITE)
        if bad.size:
            rows = np.isfinite(self._state[bad]).all(axis=2)  # [elements, bodies]
            bodies = [self.names[i] for i in np.flatnonzero(~rows.all(axis=0))]
            raise SimulationError(
                f"step: the state of element(s) {_few(bad)} is no longer finite (bodies "
                f"{bodies}): a speed, spin or force too large for float64 (it or its product "
                f"with the step overflowed). The world keeps that state: "
                f"restore a snapshot or reset it", bad)
        far = np.flatnonzero(code == FALLBACK_UNRESOLVED)
        if far.size:
            raise self._unresolved(far, self.dt if dt is None else dt)
        capped = np.flatnonzero(code == FALLBACK_CAPPED)
        speeds = self._core_speeds(capped)
        fastest = self.names[int(np.argmax(speeds.max(axis=0)))]
        force = np.hypot(self._forces[capped, :, 0], self._forces[capped, :, 1]).max()
        warnings.warn(
            f"step: element(s) {_few(capped)}: the exact solver's settling needed more than its "
            f"cap of {MAX_SETTLE_SUBSTEPS:,} substeps, so bodies may have passed through each "
            f"other in this step (last_step.capped): speeds and forces this large for the "
            f"bodies' sizes (now up to {speeds.max():.3g} m/s, body {fastest!r}, its centre's "
            f"speed and its spin times its half-length; forces set up to {force:.3g} N) need a "
            f"shorter step ({self.dt:g} s now)", RuntimeWarning, stacklevel=_caller_level())

    def _core_speeds(self, rows: np.ndarray) -> np.ndarray:
        """[rows, N] speed of the fastest point of each body's core in elements ``rows``, as
        the solvers' bounds see it: its centre's speed plus its spin times its half-length (a
        light pivoted rod spun to 9e4 rad/s has a centre at rest and tips at 1e4 m/s)."""
        state = self._state[rows]
        return (np.hypot(state[..., VX], state[..., VY])
                + np.abs(state[..., OMEGA]) * self._half_length[rows])

    def _unresolved(self, far: np.ndarray, dt: float) -> SimulationError:
        """The error for elements ``far`` a step of ``dt`` seconds left alone: a body's travel
        in it (``kernels.travel``, here in numpy) beyond ``TRAVEL_LIMIT`` half sizes of the
        table."""
        params, forces = self._params[far], self._forces[far]
        speed = self._core_speeds(far)
        push = np.hypot(forces[..., FX], forces[..., FY]) * params[..., INV_MASS]
        with np.errstate(over="ignore", invalid="ignore"):
            reach = speed * dt + 0.5 * push * dt ** 2  # [elements, bodies]
        e, i = np.unravel_index(np.nanargmax(np.where(np.isnan(reach), -1.0, reach)),
                                reach.shape)
        half = self._half[far[e]]
        return SimulationError(
            f"step: element(s) {_few(far)} not stepped: body {self.names[i]!r} would travel "
            f"up to {reach[e, i]:.3g} m in this {dt:g} s step (speed "
            f"{speed[e, i]:.3g} m/s, its spin times its half-length included; force "
            f"{np.hypot(*forces[e, i]):.3g} N), more than 2**{math.log2(TRAVEL_LIMIT):.0f} "
            f"({TRAVEL_LIMIT:.2g}) times the "
            f"walled table's half size ({min(half):g} m), beyond what float64 resolves there "
            f"(its cushions would put it anywhere). Those elements keep their state and "
            f"clock; the others stepped. Lower the speed or force, or shorten the step",
            far)

    @property
    def backend(self):
        """The pymunk backend stepping this world (``solver: pymunk``), else None; its
        ``space(b)`` is element b's ``pymunk.Space``."""
        return self._backend

    def _step_backend(self) -> int:
        """``STEP`` on the pymunk backend (the compiled element steps zero their own rows);
        returns the worst ``fallback`` statistic, as the compiled step does."""
        watch = self._stats[:, STAT_WATCH].copy()  # the watched pair stays
        self._stats[:] = 0
        self._stats[:, STAT_WATCH] = watch
        self._crec[:, self.max_contacts] = 0.0  # the sums beyond the records
        # elements no force works on cannot gain kinetic energy (checked until it is warned)
        unforced = None if self.__dict__.get("_warned_gain") else ~self._forces.any(axis=(1, 2))
        before = self.kinetic_energy() if unforced is not None and unforced.any() else None
        self._backend.step(self.dt)
        self._time += self.dt
        finite = np.isfinite(self._state).all(axis=(1, 2))
        if finite.all():
            if self.walls and not self.__dict__.get("_warned_off_table"):
                self._check_off_table()
            if before is not None:
                self._warn_gain(before, unforced)
            return FALLBACK_NONE
        self._stats[~finite, STAT_FALLBACK] = FALLBACK_NONFINITE
        return FALLBACK_NONFINITE

    #: a pymunk step's relative kinetic energy gain that is warned of (round-off is ~1e-15)
    PYMUNK_GAIN = 1e-6

    def _warn_gain(self, before: np.ndarray, unforced: np.ndarray) -> None:
        """Warn, once per world, that an element no force works on gained kinetic energy in a
        pymunk step: Chipmunk's iterative solver adds energy at e = 1 without friction too
        (walk W19: two 1 kg rods on a walled table, +2.5 % in one step, 1.027x after 300; four
        bodies 12.6x), where nothing said so."""
        after = self.kinetic_energy()
        gain = np.where(unforced & (before > 0), (after - before) / np.where(before > 0, before,
                                                                              1.0), 0.0)
        gained = np.flatnonzero(gain > self.PYMUNK_GAIN)
        if not gained.size:
            return
        self.__dict__["_warned_gain"] = True
        worst = int(np.argmax(gain))
        warnings.warn(
            f"step: on the pymunk backend, element(s) {_few(gained)} gained kinetic energy with "
            f"no force on any body (up to {100 * gain[worst]:.3g} % in this {self.dt:g} s "
            f"step: {before[worst]:.3g} J to {after[worst]:.3g} J): "
            f"Chipmunk's iterative contact solver can add energy, at e = 1 and without "
            f"friction too; more substeps and iterations make it smaller (the exact and fixed "
            f"solvers never gain). Warned once per world",
            RuntimeWarning, stacklevel=_caller_level())

    def _warn_off_table(self, off: list[tuple[int, int]]) -> None:
        """Warn, once per world, that bodies on the pymunk backend or the fixed solver ended a
        step with their centre off a walled table (``off``: (element, body), found by
        :meth:`_check_off_table`): discrete contacts let them through a cushion (a mallet at
        30 m/s in ``RodSpinControl-v0`` left the table on pymunk, and nothing said so)."""
        if self.__dict__.get("_warned_off_table"):
            return
        self.__dict__["_warned_off_table"] = True
        elements = np.unique([b for b, _ in off])
        names = sorted({self.names[i] for _, i in off})
        on = ("on the pymunk backend" if self._backend is not None
              else "on the fixed solver")
        why = ("Chipmunk's discrete contacts" if self._backend is not None
               else "its discrete contacts (a body moving more than the pair's radii in a "
                    "substep)")
        warnings.warn(
            f"step: {on}, body(ies) {names} of element(s) "
            f"{_few(elements)} ended the step with the centre off the table: "
            f"{why} let them through a cushion (the exact solver cannot "
            f"tunnel; more substeps make it rarer). Warned once per world",
            RuntimeWarning, stacklevel=_caller_level())

    @property
    def last_step(self) -> StepStats:
        """Cost accounting of the last step, per element (see :class:`StepStats`)."""
        with self._lock:
            return self._step_stats()

    def _step_stats(self) -> StepStats:
        if self._last_step is None:
            st = self._stats.copy()
            flags = _FALLBACK_FLAGS[st[:, STAT_FALLBACK]]
            watched_impulse = self._crec[:, self.max_contacts, REC_WATCHED_J].copy()
            for a in (st, flags, watched_impulse):  # and so their columns
                a.flags.writeable = False
            self.__dict__["_last_step"] = StepStats(
                st[:, STAT_EVENTS], st[:, STAT_ITERATIONS], st[:, STAT_SUBSTEPS],
                st[:, STAT_CONTACTS], flags[:, 0], flags[:, 1], st[:, STAT_WATCHED],
                watched_impulse)
        return self._last_step

    @property
    def last_contacts(self) -> Contacts:
        """The contacts the last step resolved (what ``step`` returned)."""
        with self._lock:
            return self._step_contacts()

    def _step_contacts(self) -> Contacts:
        if self._last_contacts is None:
            self.__dict__["_last_contacts"] = self._collect()
        return self._last_contacts

    def _collect(self) -> Contacts:
        counts = self._stats[:, STAT_CONTACTS].copy()
        if not counts.any():
            return self._no_contacts
        stored = np.minimum(counts, self.max_contacts)
        b, k = np.nonzero(np.arange(self.max_contacts)[None, :] < stored[:, None])
        p = self._cpair[b, k]
        rec = self._crec[b, k]
        over = self._crec[:, self.max_contacts]  # the sums beyond the records (zero if none)
        return Contacts(b, self._pair_a[p], self._pair_b[p], rec[:, REC_TIME],
                        rec[:, [REC_PX, REC_PY]], rec[:, [REC_NX, REC_NY]], rec[:, REC_J],
                        rec[:, REC_JT], counts - stored, over[:, REC_J].copy(),
                        over[:, REC_JT].copy(), rec[:, REC_HELD] != 0.0)

    # ------------------------------------------------------------------------------------------
    # conserved quantities
    # ------------------------------------------------------------------------------------------

    def _finite_mass(self) -> np.ndarray:
        return np.where(self._params[..., INV_MASS] > 0, self._mass, 0.0)

    def _finite_inertia(self) -> np.ndarray:
        return np.where(self._params[..., INV_INERTIA] > 0, self._inertia, 0.0)

    def kinetic_energy(self) -> np.ndarray:
        """[B] translational plus rotational kinetic energy of the movable bodies, J (inf
        where float64 cannot hold it: a body at 1e300 m/s, with no overflow warning)."""
        with np.errstate(over="ignore"):
            v2 = (self._state[..., VX:VY + 1] ** 2).sum(-1)
            return 0.5 * (self._finite_mass() * v2).sum(-1) + 0.5 * (
                self._finite_inertia() * self._state[..., OMEGA] ** 2).sum(-1)

    def momentum(self) -> np.ndarray:
        """[B, 2] linear momentum of the bodies with finite mass, kg m/s."""
        return (self._finite_mass()[..., None] * self._state[..., VX:VY + 1]).sum(1)

    def angular_momentum(self, about: Any = (0.0, 0.0)) -> np.ndarray:
        """[B] angular momentum about a fixed point (CCW positive), kg m^2/s."""
        r = self._state[..., X:Y + 1] - np.asarray(about, dtype=float)
        v = self._state[..., VX:VY + 1]
        orbital = r[..., 0] * v[..., 1] - r[..., 1] * v[..., 0]
        return (self._finite_mass() * orbital).sum(-1) + (
            self._finite_inertia() * self._state[..., OMEGA]).sum(-1)


#: the folders of SpinStrike's own modules (installed: spinstrike/physics, ...; a checkout:
#: physics/, envs/, ...), whose frames a warning skips to name the user's line
_OWN = tuple(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), name)
             + os.sep for name in ("physics", "envs", "agents", "benchmarks", "spinstrike"))


def _caller_level() -> int:
    """The ``stacklevel`` of the first frame outside SpinStrike's modules, for a warning
    issued by the function that calls this: the user's ``world.step`` or ``env.step`` line,
    however many of ours lie between (a fixed level named ``world.step``'s own line)."""
    level, frame = 1, sys._getframe(1)
    while frame is not None and frame.f_code.co_filename.startswith(_OWN):
        frame = frame.f_back
        level += 1
    return level


def _few(elements: np.ndarray, shown: int = 8) -> str:
    """Element indices for a message: all of a few, else the first ``shown`` and a count."""
    if elements.size <= shown:
        return str(elements.tolist())
    return f"{elements[:shown].tolist()[:-1]} ... ({elements.size} in all)"


@jit
def _pair_gaps(S, Pm, HW, PA, PB, out):
    n = S.shape[1]
    for b in range(S.shape[0]):
        for p in range(PA.shape[0]):
            a, c, wall = pair_bodies(p, PA, PB, n)
            out[b, p] = pair_geometry(S[b], Pm[b], a, c, wall, HW[b, HALF_W], HW[b, HALF_H])[0]
