"""The world: B copies of a scene, stepped together.

State is a struct of numpy arrays with a leading batch axis (named views of one packed array, see
``physics.layout``)::

    world.state.positions   [B, N, 2]  m             world.state.angles  [B, N]  rad, CCW from +x
    world.state.velocities  [B, N, 2]  m/s           world.state.omegas  [B, N]  rad/s, CCW > 0

Per-body parameters are ``[B, N]`` arrays too, so every element can carry its own masses, sizes
and materials (``set_body``, ``set_material``); the list of bodies and their shape kinds is fixed.
Cushions (the ``walls`` effect) are reported as bodies ``N..N+3`` (``WALL_NAMES``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from spinstrike.physics.events import pair_bodies, pair_geometry
from spinstrike.physics.layout import (
    ANGLE,
    CF_DT,
    CF_SETTLE,
    CF_TOL,
    CF_ZENO_SPEED,
    CI_CONTACT_FRICTION,
    CI_ITERATIONS,
    CI_MAX_EVENTS,
    CI_MAX_ITERATIONS,
    CI_ROTATION,
    CI_SUBSTEPS,
    CI_TABLE_FRICTION,
    CI_ZENO_IMPACTS,
    FLOAT_FIELDS,
    FRICTION,
    FRICTION_DECEL,
    H_B,
    H_C,
    H_FLOAT,
    H_INT,
    H_M,
    H_N,
    H_P,
    HALF_LENGTH,
    HEADER,
    INT_FIELDS,
    INV_INERTIA,
    INV_MASS,
    OMEGA,
    RADIUS,
    REC_J,
    REC_JT,
    REC_NY,
    REC_PX,
    REC_TIME,
    RESTITUTION,
    SPIN_DECEL,
    STAT_COLUMNS,
    STAT_CONTACTS,
    STAT_EVENTS,
    STAT_FALLBACK,
    STAT_ITERATIONS,
    STAT_SUBSTEPS,
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
    body_inertia,
    load_scene,
    validate_solver,
)
from spinstrike.physics.shapes import radius_of_gyration
from spinstrike.physics.solvers import (
    exact_batch_parallel,
    exact_batch_serial,
    fixed_batch_parallel,
    fixed_batch_serial,
)

__all__ = ["Contacts", "State", "StepStats", "World"]

#: batch size from which the parallel kernels are used
PARALLEL_BATCH = 256


@dataclass(frozen=True)
class State:
    """Named, read-only views of the world's state (see module docstring for units)."""

    positions: np.ndarray
    angles: np.ndarray
    velocities: np.ndarray
    omegas: np.ndarray


@dataclass(frozen=True)
class Contacts:
    """The contacts one ``step`` resolved, as flat arrays (each element has its own count).

    Attributes:
        batch: [K] batch index.  body_a, body_b: [K] body indices (b >= N: a cushion).
        time: [K] s since the start of the step.  point: [K, 2] m.
        normal: [K, 2] unit, from a to b.  impulse: [K] normal impulse j >= 0, N s.
        tangent_impulse: [K] friction impulse along t = (-n_y, n_x), N s.
        dropped: [B] contacts not stored because an element exceeded ``max_contacts``.
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

    def __len__(self) -> int:
        return int(self.batch.shape[0])


@dataclass(frozen=True)
class StepStats:
    """Cost accounting of the last step, per element (myPhysicsLab-style).

    Attributes:
        events: impacts and checkpoints processed by the exact solver.
        iterations: time-of-impact iterations (conservative advancement and bracketing).
        substeps: fixed substeps (the fixed solver, or the exact solver's settling).
        contacts: impulses applied.
        fallback: the exact solver settled the rest of the step with fixed substeps (a run of
            resting bounces, or ``max_events`` reached).
    """

    events: np.ndarray
    iterations: np.ndarray
    substeps: np.ndarray
    contacts: np.ndarray
    fallback: np.ndarray


def _as_batch(value: Any, shape: tuple[int, ...], field: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    try:
        arr = np.broadcast_to(arr, shape)
    except ValueError:
        raise SceneError(
            f"{field}: expected shape {shape} or broadcastable, got {arr.shape}") from None
    if not np.all(np.isfinite(arr)):
        raise SceneError(f"{field}: must be finite numbers (got NaN or inf)")
    return arr


def _batch_index(env: Any, batch_size: int) -> Any:
    if env is None:
        return slice(None)
    idx = np.asarray(env)
    if idx.dtype == bool:
        if idx.shape != (batch_size,):
            raise SceneError(f"env: boolean mask must have shape ({batch_size},)")
        return idx
    if np.any((idx < 0) | (idx >= batch_size)):
        raise SceneError(f"env: indices must lie in [0, {batch_size})")
    return idx


class World:
    """B copies of a scene, stepped together by the scene's (or the given) solver.

    Args:
        scene: a :class:`~physics.scene.Scene`, a dict, a YAML string or a path.
        batch_size: B, the number of copies.
        solver: overrides the scene's solver block (a dict such as ``{"mode": "fixed",
            "substeps": 8}``, a mode name, or a solver model).
        max_contacts: contacts stored per element per step (more are counted in
            ``Contacts.dropped``, never silently lost).
    """

    def __init__(self, scene: Any, batch_size: int = 1, solver: Any = None,
                 max_contacts: int = 64) -> None:
        self.scene: Scene = load_scene(scene)
        if not isinstance(batch_size, (int, np.integer)) or batch_size < 1:
            raise SceneError(f"batch_size: must be an integer >= 1 (got {batch_size!r})")
        self.solver = validate_solver(solver) if solver is not None else self.scene.solver
        self.batch_size = B = int(batch_size)
        self.effects = frozenset(self.scene.effects)
        self.rotation = "rotation" in self.effects
        self.walls = "walls" in self.effects
        self.contact_friction = "contact_friction" in self.effects
        self.table_friction = "table_friction" in self.effects
        bodies = self.scene.bodies
        self.n_bodies = len(bodies)
        walls = WALL_NAMES if self.walls else ()
        self.names: tuple[str, ...] = tuple(b.name for b in bodies) + walls
        self.static = np.array([b.static for b in bodies])
        self.pivot = np.array([b.pivot for b in bodies])
        self.driven = np.array([b.driven for b in bodies])
        self.shapes = tuple(b.shape for b in bodies)
        self._inertia_model = [b.inertia for b in bodies]

        # per-body physical parameters [B, N]
        self.mass = np.tile([b.mass if not b.static else math.inf for b in bodies], (B, 1))
        self.radius = np.tile([b.core_radius for b in bodies], (B, 1)).astype(float)
        self.half_length = np.tile([b.half_length for b in bodies], (B, 1)).astype(float)
        self.inertia = np.tile([b.moment if not b.static else math.inf for b in bodies], (B, 1))
        table = self.scene.table
        self.table_mu = np.full(B, table.friction)
        self.gravity = table.gravity
        size = table.size if table.size is not None else (math.inf, math.inf)

        self.max_contacts = int(max_contacts)
        pairs = self._pair_list()
        self._alloc_buffers(len(pairs[0]))
        self._hw[:] = 0.5 * np.asarray(size, dtype=float)
        self._init_pairs(*pairs)
        self._update_params()
        self._configure_solver()
        self._initial = self._initial_state()
        self._state[:] = self._initial
        self._make_views()
        self._check_overlap(slice(None))
        self._backend = None
        if isinstance(self.solver, PymunkSolver):
            from spinstrike.physics.pymunk_backend import PymunkBackend

            self._backend = PymunkBackend(self)
        self._last_stats = np.zeros_like(self._stats)
        self._last_step = None
        e = np.zeros(0)
        ei = np.zeros(0, dtype=np.int64)
        self._no_contacts = Contacts(ei, ei, ei, e, np.zeros((0, 2)), np.zeros((0, 2)), e, e,
                                     np.zeros(self.batch_size, dtype=np.int64))
        for arr in (e, ei, self._no_contacts.point, self._no_contacts.normal,
                    self._no_contacts.dropped):
            arr.flags.writeable = False

    # ------------------------------------------------------------------------------------------
    # construction helpers
    # ------------------------------------------------------------------------------------------

    def _pair_list(self) -> tuple[list[int], list[int]]:
        """Every pair that can touch: body pairs (not two static bodies), then body-cushion."""
        bodies = self.scene.bodies
        N = self.n_bodies
        pa, pb = [], []
        for i in range(N):
            for j in range(i + 1, N):
                if bodies[i].static and bodies[j].static:
                    continue
                pa.append(i)
                pb.append(j)
        if self.walls:
            for i in range(N):
                if not bodies[i].static:
                    for w in range(4):
                        pa.append(i)
                        pb.append(N + w)
        return pa, pb

    def _init_pairs(self, pa: list[int], pb: list[int]) -> None:
        self.pair_a[:] = pa
        self.pair_b[:] = pb
        mats = self.scene.materials
        self._materials[:, :, RESTITUTION] = mats.restitution
        self._materials[:, :, FRICTION] = mats.friction
        for pair in mats.pairs:
            rows = self._pair_rows(*pair.bodies)
            if pair.restitution is not None:
                self._materials[:, rows, RESTITUTION] = pair.restitution
            if pair.friction is not None:
                self._materials[:, rows, FRICTION] = pair.friction

    def _pair_rows(self, a: str, b: str) -> np.ndarray:
        def ids(name: str) -> set[int]:
            if name == "walls":
                return set(range(self.n_bodies, self.n_bodies + 4)) if self.walls else set()
            return {self.index(name)}

        ia, ib = ids(a), ids(b)
        rows = [p for p in range(len(self.pair_a))
                if (self.pair_a[p] in ia and self.pair_b[p] in ib)
                or (self.pair_a[p] in ib and self.pair_b[p] in ia)]
        if not rows:
            raise SceneError(f"materials: no contact pair between {a!r} and {b!r}")
        return np.asarray(rows)

    def _update_params(self) -> None:
        """Derive inverse masses, inertias and friction decelerations (once per change)."""
        p = self._params
        dynamic = ~self.static & ~self.pivot
        with np.errstate(divide="ignore"):
            p[..., INV_MASS] = np.where(dynamic, 1.0 / self.mass, 0.0)
            p[..., INV_INERTIA] = np.where(~self.static & self.rotation, 1.0 / self.inertia, 0.0)
        p[..., RADIUS] = self.radius
        p[..., HALF_LENGTH] = self.half_length
        sliding = dynamic & ~self.driven
        decel = self.table_mu[:, None] * self.gravity * float(self.table_friction)
        p[..., FRICTION_DECEL] = np.where(sliding, decel, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = radius_of_gyration(np.where(self.static, 1.0, self.mass),
                                   np.where(self.static, 1.0, self.inertia))
            p[..., SPIN_DECEL] = np.where(~self.static & ~self.driven & (k > 0), decel / k, 0.0)
        if getattr(self, "_backend", None) is not None:
            self._backend.sync_params()

    _VIEWS = ("_state", "_params", "_forces", "_hw", "_materials", "_crec", "_toi", "_fcfg",
              "_time", "pair_a", "pair_b", "_cpair", "_stats", "_kind", "_changed", "_icfg",
              "_ctime", "_cgeo", "_cimp")

    def _alloc_buffers(self, n_pairs: int) -> None:
        """One float64 and one int64 buffer holding every array the kernels touch (see
        ``physics.layout``): state, parameters, forces, table, materials, contact records,
        statistics, the solvers' scratch rows and the solver configuration."""
        B, N, M = self.batch_size, self.n_bodies, self.max_contacts
        shapes = field_shapes(B, N, n_pairs, M)
        offsets = {}
        for fields in (FLOAT_FIELDS, INT_FIELDS):
            total = HEADER if fields is INT_FIELDS else 0
            for name in fields:
                offsets[name] = total
                total += int(np.prod(shapes[name]))
            if fields is FLOAT_FIELDS:
                self._fbuf = np.zeros(total)
            else:
                self._ibuf = np.zeros(total, dtype=np.int64)
        self._ibuf[[H_B, H_N, H_P, H_M, H_C]] = (B, N, n_pairs, M, STAT_COLUMNS)
        self._ibuf[H_FLOAT:H_FLOAT + len(FLOAT_FIELDS)] = [offsets[f] for f in FLOAT_FIELDS]
        self._ibuf[H_INT:H_INT + len(INT_FIELDS)] = [offsets[f] for f in INT_FIELDS]
        self._offsets = offsets
        self._make_buffer_views()

    def _make_buffer_views(self) -> None:
        shapes = field_shapes(self.batch_size, self.n_bodies, int(self._ibuf[H_P]),
                              self.max_contacts)
        for fields, buf in ((FLOAT_FIELDS, self._fbuf), (INT_FIELDS, self._ibuf)):
            for name in fields:
                o = self._offsets[name]
                view = buf[o:o + int(np.prod(shapes[name]))].reshape(shapes[name])
                setattr(self, name if name.startswith("pair_") else "_" + name, view)
        self._ctime = self._crec[..., REC_TIME]
        self._cgeo = self._crec[..., REC_PX:REC_NY + 1]
        self._cimp = self._crec[..., REC_J:REC_JT + 1]

    def _configure_solver(self) -> None:
        s = self.solver
        self._icfg[CI_ROTATION] = self.rotation
        self._icfg[CI_CONTACT_FRICTION] = self.contact_friction
        self._icfg[CI_TABLE_FRICTION] = self.table_friction
        if isinstance(s, ExactSolver):
            self._fcfg[[CF_TOL, CF_ZENO_SPEED, CF_SETTLE]] = (s.tolerance, s.zeno_speed,
                                                             s.settle_substep)
            self._icfg[[CI_MAX_EVENTS, CI_MAX_ITERATIONS, CI_ZENO_IMPACTS]] = (
                s.max_events, s.max_iterations, s.zeno_impacts)
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

    def _make_views(self) -> None:
        def ro(a: np.ndarray) -> np.ndarray:
            v = a.view()
            v.flags.writeable = False
            return v

        s = self._state
        self.state = State(ro(s[..., X:Y + 1]), ro(s[..., ANGLE]), ro(s[..., VX:VY + 1]),
                           ro(s[..., OMEGA]))

    def __getstate__(self) -> dict:
        d = self.__dict__.copy()
        d.pop("state")
        for name in self._VIEWS:
            d.pop(name)  # views into the two buffers, rebuilt on unpickling
        d["_backend"] = None
        return d

    def __setstate__(self, d: dict) -> None:
        self.__dict__.update(d)
        self._make_buffer_views()
        self._make_views()
        if isinstance(self.solver, PymunkSolver):
            from spinstrike.physics.pymunk_backend import PymunkBackend

            self._backend = PymunkBackend(self)

    # ------------------------------------------------------------------------------------------
    # names and parameters
    # ------------------------------------------------------------------------------------------

    def index(self, name: str) -> int:
        """Index of a body or cushion by name."""
        try:
            return self.names.index(name)
        except ValueError:
            raise SceneError(f"unknown body {name!r}; bodies: {list(self.names)}") from None

    def _body(self, body: int | str) -> int:
        i = self.index(body) if isinstance(body, str) else int(body)
        if not 0 <= i < self.n_bodies:
            raise SceneError(f"body index {i} out of range [0, {self.n_bodies})")
        return i

    @property
    def params(self) -> np.ndarray:
        """Read-only packed parameter rows ``[B, N, 6]`` (see ``physics.layout``)."""
        v = self._params.view()
        v.flags.writeable = False
        return v

    def set_body(self, body: int | str, *, mass: Any = None, radius: Any = None,
                 length: Any = None, thickness: Any = None, inertia: Any = None,
                 env: Any = None) -> None:
        """Change a body's numeric parameters, for all elements or those in ``env``.

        Values are scalars or arrays over the selected elements. The inertia is re-derived from
        the shape unless given here (or fixed by a numeric ``inertia`` in the scene).
        """
        i = self._body(body)
        idx = _batch_index(env, self.batch_size)
        n = len(np.arange(self.batch_size)[idx])
        name = self.names[i]
        shape = self.shapes[i]
        if self.static[i] and mass is not None:
            raise SceneError(f"{name}.mass: a static body has no finite mass")
        if shape == "disk" and (length is not None or thickness is not None):
            raise SceneError(f"{name}: a disk has radius only (no length or thickness)")
        if shape == "rod" and radius is not None:
            raise SceneError(f"{name}.radius: a rod has length and thickness, not radius")
        checks = (("mass", mass, True), ("radius", radius, True), ("length", length, True),
                  ("thickness", thickness, False), ("inertia", inertia, True))
        values = {}
        for field, value, strict in checks:
            if value is None:
                continue
            arr = _as_batch(value, (n,), f"{name}.{field}")
            if np.any(arr <= 0) if strict else np.any(arr < 0):
                raise SceneError(f"{name}.{field}: must be {'>' if strict else '>='} 0 "
                                 f"(got {arr.min()})")
            values[field] = arr
        if "mass" in values:
            self.mass[idx, i] = values["mass"]
        if "radius" in values:
            self.radius[idx, i] = values["radius"]
        if "thickness" in values:
            self.radius[idx, i] = 0.5 * values["thickness"]
        if "length" in values:
            self.half_length[idx, i] = 0.5 * values["length"]
        if "inertia" in values:
            self.inertia[idx, i] = values["inertia"]
        elif not self.static[i] and not isinstance(self._inertia_model[i], float):
            self.inertia[idx, i] = body_inertia(shape, self.mass[idx, i], self.radius[idx, i],
                                                self.half_length[idx, i], self._inertia_model[i])
        self._update_params()
        self._check_overlap(idx)

    def set_material(self, a: str, b: str, *, restitution: Any = None, friction: Any = None,
                     env: Any = None) -> None:
        """Change the restitution / friction of the pair(s) between ``a`` and ``b``."""
        rows = self._pair_rows(a, b)
        idx = _batch_index(env, self.batch_size)
        n = len(np.arange(self.batch_size)[idx])
        if restitution is not None:
            e = _as_batch(restitution, (n,), "restitution")
            if np.any((e < 0) | (e > 1)):
                raise SceneError(f"restitution: must lie in [0, 1] (got {e.min()}..{e.max()})")
            sel = np.ix_(np.arange(self.batch_size)[idx], rows, [RESTITUTION])
            self._materials[sel] = e[:, None, None]
        if friction is not None:
            mu = _as_batch(friction, (n,), "friction")
            if np.any(mu < 0):
                raise SceneError(f"friction: must be >= 0 (got {mu.min()})")
            if np.any(mu > 0) and not self.contact_friction:
                raise SceneError("friction: is set but the scene does not list the "
                                 "'contact_friction' effect")
            sel = np.ix_(np.arange(self.batch_size)[idx], rows, [FRICTION])
            self._materials[sel] = mu[:, None, None]
        if self._backend is not None:
            self._backend.sync_params()

    def set_table(self, *, friction: Any = None, size: Any = None, env: Any = None) -> None:
        """Change the table's friction coefficient or size per element."""
        idx = _batch_index(env, self.batch_size)
        n = len(np.arange(self.batch_size)[idx])
        if friction is not None:
            mu = _as_batch(friction, (n,), "table.friction")
            if np.any(mu < 0):
                raise SceneError(f"table.friction: must be >= 0 (got {mu.min()})")
            if np.any(mu > 0) and not self.table_friction:
                raise SceneError("table.friction: is set but the scene does not list the "
                                 "'table_friction' effect")
            self.table_mu[idx] = mu
        if size is not None:
            s = _as_batch(size, (n, 2), "table.size")
            if np.any(s <= 0):
                raise SceneError("table.size: must be positive lengths (m)")
            self._hw[idx] = 0.5 * s
        self._update_params()

    def restitution(self, a: str, b: str) -> np.ndarray:
        """Restitution of the pair between ``a`` and ``b`` per element, shape [B]."""
        return self._materials[:, self._pair_rows(a, b)[0], RESTITUTION].copy()

    def friction(self, a: str, b: str) -> np.ndarray:
        """Contact friction coefficient of the pair between ``a`` and ``b`` per element, [B]."""
        return self._materials[:, self._pair_rows(a, b)[0], FRICTION].copy()

    @property
    def table_half_size(self) -> np.ndarray:
        """[B, 2] half width and half height of the table, m (inf when unbounded)."""
        return self._hw.copy()

    # ------------------------------------------------------------------------------------------
    # state
    # ------------------------------------------------------------------------------------------

    def set_state(self, *, positions: Any = None, angles: Any = None, velocities: Any = None,
                  omegas: Any = None, env: Any = None, body: int | str | None = None) -> None:
        """Set (part of) the state, for all elements or those in ``env``, all bodies or ``body``.

        Arrays broadcast to ``[b, n, 2]`` / ``[b, n]`` for the selection. Raises
        :class:`SceneError` for NaN, for moving a static body or a pivot's centre, for spin
        without the ``rotation`` effect, or for a change that makes bodies overlap by more than
        the tolerance; the world is unchanged then.
        """
        idx = _batch_index(env, self.batch_size)
        rows = np.arange(self.batch_size)[idx]
        cols = np.arange(self.n_bodies) if body is None else np.array([self._body(body)])
        sel = np.ix_(rows, cols)
        b, n = len(rows), len(cols)
        new = self._state.copy()
        if positions is not None:
            pos = _as_batch(positions, (b, n, 2), "positions")
            moved = np.any(pos != self._state[sel][..., X:Y + 1], axis=(0, 2))
            fixed = (self.static | self.pivot)[cols]
            if np.any(moved & fixed):
                raise SceneError(f"positions: static bodies and pivots cannot move "
                                 f"({[self.names[c] for c in cols[moved & fixed]]})")
            new[sel + (slice(X, Y + 1),)] = pos
        if angles is not None:
            ang = _as_batch(angles, (b, n), "angles")
            if np.any((ang != self._state[sel][..., ANGLE]) & self.static[cols]):
                raise SceneError("angles: a static body cannot turn")
            new[sel + (ANGLE,)] = ang
        if velocities is not None:
            vel = _as_batch(velocities, (b, n, 2), "velocities")
            if np.any((np.abs(vel).sum(axis=(0, 2)) > 0) & (self.static | self.pivot)[cols]):
                raise SceneError("velocities: static bodies and pivots must have zero velocity")
            new[sel + (slice(VX, VY + 1),)] = vel
        if omegas is not None:
            om = _as_batch(omegas, (b, n), "omegas")
            if np.any(om != 0) and not self.rotation:
                raise SceneError("omegas: nonzero spin but the scene does not list the "
                                 "'rotation' effect")
            if np.any((om != 0).any(axis=0) & self.static[cols]):
                raise SceneError("omegas: a static body cannot spin")
            new[sel + (OMEGA,)] = om
        self._check_overlap(idx, new)
        self._state[:] = new
        if self._backend is not None:
            self._backend.sync_from_world()

    @property
    def time(self) -> np.ndarray:
        """[B] simulated time of each element since construction or its last reset, s."""
        return self._time

    def _place(self, env: np.ndarray, positions: np.ndarray, angles: np.ndarray,
               velocities: np.ndarray, omegas: np.ndarray) -> None:
        """Write full state rows for elements ``env`` (arrays ``[len(env), N, ...]``) without
        :meth:`set_state`'s checks of bodies' kinds and overlaps: for callers that place bodies
        apart by construction (the envs' resets and strikes). Non-finite values still raise."""
        if not (np.isfinite(positions).all() and np.isfinite(velocities).all()
                and np.isfinite(angles).all() and np.isfinite(omegas).all()):
            raise SceneError("state: must be finite numbers (got NaN or inf)")
        s = self._state
        s[env, :, X:Y + 1] = positions
        s[env, :, ANGLE] = angles
        s[env, :, VX:VY + 1] = velocities
        s[env, :, OMEGA] = omegas
        if self._backend is not None:
            self._backend.sync_from_world()

    def get_state(self) -> dict[str, np.ndarray]:
        """A copy of the full physical state (state arrays, forces, time), for ``restore``."""
        return {"state": self._state.copy(), "forces": self._forces.copy(),
                "time": self.time.copy()}

    def restore(self, snapshot: dict[str, np.ndarray], env: Any = None) -> None:
        """Put back a snapshot from ``get_state`` (all elements, or those in ``env``)."""
        idx = _batch_index(env, self.batch_size)
        state = np.asarray(snapshot["state"], dtype=float)
        if state.shape != self._state.shape:
            raise SceneError(f"snapshot: state shape {state.shape} != {self._state.shape}")
        if not np.all(np.isfinite(state)):
            raise SceneError("snapshot: state must be finite")
        self._state[idx] = state[idx]
        self._forces[idx] = snapshot["forces"][idx]
        self._time[idx] = snapshot["time"][idx]
        if self._backend is not None:
            self._backend.sync_from_world()

    def load_element(self, other: World, b: int, env: Any = None) -> None:
        """Copy element ``b`` of ``other`` (same scene layout) into elements ``env`` of this
        world: parameters, materials, table, state, forces and clock. For what-if runs (an oracle
        trying strikes in a scratch world) and replays."""
        if other.names != self.names or other.shapes != self.shapes:
            raise SceneError("load_element: the worlds' bodies differ")
        idx = _batch_index(env, self.batch_size)
        for name in ("mass", "radius", "half_length", "inertia"):
            getattr(self, name)[idx] = getattr(other, name)[b]
        self.table_mu[idx] = other.table_mu[b]
        self._hw[idx] = other._hw[b]
        self._materials[idx] = other._materials[b]
        self._update_params()
        self._state[idx] = other._state[b]
        self._forces[idx] = other._forces[b]
        self._time[idx] = other.time[b]
        if self._backend is not None:
            self._backend.sync_from_world()

    def reset(self, env: Any = None) -> None:
        """Put the selected elements back in the scene's initial state (parameters are kept)."""
        idx = _batch_index(env, self.batch_size)
        self._state[idx] = self._initial
        self._forces[idx] = 0.0
        self._time[idx] = 0.0
        self._check_overlap(idx)
        if self._backend is not None:
            self._backend.sync_from_world()

    def set_force(self, body: int | str, force: Any, env: Any = None) -> None:
        """Apply a constant force (N, [.., 2]) to a ``driven`` body from now on."""
        i = self._body(body)
        if not self.driven[i]:
            raise SceneError(f"{self.names[i]}: forces can only be applied to bodies marked "
                             "'driven: true' in the scene")
        idx = _batch_index(env, self.batch_size)
        n = len(np.arange(self.batch_size)[idx])
        self._forces[idx, i] = _as_batch(force, (n, 2), f"{self.names[i]}.force")

    @property
    def forces(self) -> np.ndarray:
        """Read-only [B, N, 2] applied forces, N."""
        v = self._forces.view()
        v.flags.writeable = False
        return v

    def gaps(self, state: np.ndarray | None = None) -> np.ndarray:
        """[B, P] gap (m) of every contact pair (``pair_a``, ``pair_b``); negative = overlap."""
        s = self._state if state is None else state
        out = np.empty((self.batch_size, len(self.pair_a)))
        _pair_gaps(s, self._params, self._hw, self.pair_a, self.pair_b, out)
        return out

    def _tolerance(self) -> float:
        return self.solver.tolerance if isinstance(self.solver, ExactSolver) else 1e-9

    def _check_overlap(self, idx: Any, state: np.ndarray | None = None) -> None:
        """Raise if bodies overlap by more than the tolerance.

        With a proposed ``state`` (``set_state``), only overlap that the change creates or
        deepens is an error: the fixed and pymunk solvers can themselves leave bodies slightly
        overlapping after an impact, and setting, say, velocities must not be refused for that.
        """
        if len(self.pair_a) == 0:
            return
        tol = self._tolerance()
        g = self.gaps(state)[idx]
        bad = g < -tol
        if state is not None and np.any(bad):
            bad &= g < self.gaps()[idx] - tol
        if np.any(bad):
            e, p = np.argwhere(bad)[0]
            a, b = self.names[self.pair_a[p]], self.names[self.pair_b[p]]
            raise SceneError(f"bodies: {a!r} and {b!r} overlap by {-g[e, p]:.3g} m in element "
                             f"{np.arange(self.batch_size)[idx][e]} (touching is allowed, overlap "
                             f"beyond the tolerance {self._tolerance():g} m is not)")

    # ------------------------------------------------------------------------------------------
    # stepping
    # ------------------------------------------------------------------------------------------

    def step(self, dt: float) -> Contacts:
        """Advance every element by ``dt`` seconds; return the contacts resolved."""
        dt = float(dt)
        if not (math.isfinite(dt) and dt >= 0.0):
            raise SceneError(f"dt: must be a finite number >= 0 s (got {dt})")
        if self._backend is not None:
            self._stats[:] = 0  # the compiled kernels zero each element's row themselves
            self._backend.step(dt)
            self._time += dt
        else:
            self._fcfg[CF_DT] = dt
            parallel = self.batch_size >= PARALLEL_BATCH
            if isinstance(self.solver, ExactSolver):
                kernel = exact_batch_parallel if parallel else exact_batch_serial
            else:
                kernel = fixed_batch_parallel if parallel else fixed_batch_serial
            kernel(self._fbuf, self._ibuf)  # advances the clock too
        self._finish_step()
        return self._collect()

    def _finish_step(self) -> None:
        """Freeze this step's statistics (``last_step`` is built from them on first use)."""
        self._last_stats = self._stats.copy()
        self._last_step = None

    @property
    def last_step(self) -> StepStats:
        """Cost accounting of the last ``step``, per element (see :class:`StepStats`)."""
        if self._last_step is None:
            st = self._last_stats
            self._last_step = StepStats(st[:, STAT_EVENTS], st[:, STAT_ITERATIONS],
                                        st[:, STAT_SUBSTEPS], st[:, STAT_CONTACTS],
                                        st[:, STAT_FALLBACK].astype(bool))
        return self._last_step

    def _collect(self) -> Contacts:
        counts = self._last_stats[:, STAT_CONTACTS]
        if not counts.any():
            return self._no_contacts
        stored = np.minimum(counts, self.max_contacts)
        b, k = np.nonzero(np.arange(self.max_contacts)[None, :] < stored[:, None])
        p = self._cpair[b, k]
        geo = self._cgeo[b, k]
        imp = self._cimp[b, k]
        return Contacts(b, self.pair_a[p], self.pair_b[p], self._ctime[b, k], geo[:, 0:2].copy(),
                        geo[:, 2:4].copy(), imp[:, 0].copy(), imp[:, 1].copy(), counts - stored)

    # ------------------------------------------------------------------------------------------
    # conserved quantities
    # ------------------------------------------------------------------------------------------

    def _finite_mass(self) -> np.ndarray:
        return np.where(self._params[..., INV_MASS] > 0, self.mass, 0.0)

    def _finite_inertia(self) -> np.ndarray:
        return np.where(self._params[..., INV_INERTIA] > 0, self.inertia, 0.0)

    def kinetic_energy(self) -> np.ndarray:
        """[B] translational plus rotational kinetic energy of the movable bodies, J."""
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


@numba.njit(cache=True)
def _pair_gaps(S, Pm, HW, PA, PB, out):
    n = S.shape[1]
    for b in range(S.shape[0]):
        for p in range(PA.shape[0]):
            a, c, wall = pair_bodies(p, PA, PB, n)
            out[b, p] = pair_geometry(S[b], Pm[b], a, c, wall, HW[b, 0], HW[b, 1])[0]

