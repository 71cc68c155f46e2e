"""Changing a world: one validated, batched change of parameters and state.

Every change a user (or an env's reset) makes to a world goes through a :class:`WorldEdit`::

    with world.edit(env=rows) as e:                  # elements ``rows`` (all if omitted)
        e.set_body("rod", length=lengths, mass=masses)
        reach = e.half_length[:, rod] + e.radius[:, rod]   # the edit's values, not yet written
        e.set_state(positions=..., angles=..., velocities=0.0, omegas=0.0)
        e.set_time(0.0)

Nothing is written until the block ends without an exception; then the whole change is checked
once — values (finite numbers, in range; strings and booleans are refused), kinds of bodies
(a static body does not move), and geometry: a change that leaves a body overlapping another or
a cushion (outside the table) by more than the tolerance raises :class:`SceneError` naming the
bodies, and the world is left as it was. The world's single-purpose setters (``set_body``,
``set_material``, ``set_table``, ``set_state``, ``set_force``, ``reset``) are each one such edit.

Overlap rule: no change may create or deepen an overlap beyond the tolerance. An overlap that
is already there (the fixed and pymunk solvers can leave one after an impact) may stay, unless a
change that places every body (positions of all bodies given, as a reset does) moves one of the
pair: a new placement starts without overlap, while writing back the state just read is fine.
"""

from __future__ import annotations

import math
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from spinstrike.physics.jit import jit
from spinstrike.physics.kernels import element_overlap
from spinstrike.physics.layout import (
    ANGLE,
    FRICTION,
    OMEGA,
    RESTITUTION,
    VX,
    VY,
    X,
    Y,
)
from spinstrike.physics.scene import SceneError, body_inertia, invertible

if TYPE_CHECKING:
    from spinstrike.physics.world import World

__all__ = ["WorldEdit", "as_batch", "batch_rows", "check_snapshot"]


def as_batch(value: Any, shape: tuple[int, ...], field: str,
             keep_scalar: bool = False) -> np.ndarray:
    """``value`` as a float array broadcast to ``shape`` (with ``keep_scalar``, a scalar stays a
    0-d array, for callers that only assign it); raises :class:`SceneError` naming
    ``field`` for anything that is not finite numbers (NaN, inf, strings, booleans, objects)."""
    if keep_scalar and type(value) in (float, int):  # the common case, cheaply (bool excluded)
        if not math.isfinite(value):
            raise SceneError(f"{field}: must be finite numbers (got {value})")
        return value
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        raise SceneError(f"{field}: must be numbers (got {_show(value)} of type "
                         f"{type(value).__name__}, dtype {arr.dtype})")
    if arr.dtype != np.float64:
        arr = arr.astype(np.float64)
    if not np.isfinite(arr).all():
        raise SceneError(f"{field}: must be finite numbers (got NaN or inf)")
    if arr.shape != shape and not (keep_scalar and arr.ndim == 0):
        try:
            arr = np.broadcast_to(arr, shape)
        except ValueError:
            raise SceneError(f"{field}: expected shape {shape} or broadcastable, got "
                             f"{arr.shape}") from None
    return arr


def _invertible(arr: np.ndarray, field: str) -> None:
    """Raise unless every value is :func:`~physics.scene.invertible` (a mass or moment of
    inertia the impulses divide by: 1e-320 kg has an infinite inverse)."""
    if not invertible(arr).all():
        raise SceneError(f"{field}: too small or large for float64 (got {arr.min():g}.."
                         f"{arr.max():g}): its inverse, which the impulses use, is not a finite "
                         f"nonzero number")


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def batch_rows(env: Any, batch_size: int) -> np.ndarray:
    """Element indices selected by ``env``: None (all), an index, indices or a boolean mask."""
    if env is None:
        return np.arange(batch_size)
    idx = np.asarray(env)
    if idx.dtype == bool:
        if idx.shape != (batch_size,):
            raise SceneError(f"env: a boolean mask must have shape ({batch_size},) "
                             f"(got {idx.shape})")
        return np.flatnonzero(idx)
    if idx.dtype.kind not in "iu":
        raise SceneError(f"env: element indices must be integers (got {_show(env)})")
    if idx.ndim != 1:
        idx = idx.reshape(-1)
    if idx.size == 1:
        ok = 0 <= int(idx[0]) < batch_size
    else:
        ok = idx.size == 0 or (idx.min() >= 0 and idx.max() < batch_size)
    if not ok:
        raise SceneError(f"env: indices must lie in [0, {batch_size}) (got {_show(env)})")
    # (rows an env passes are sorted, checked in O(n); two values for one element were taken
    # silently, the last one winning)
    if idx.size > 1 and not np.all(idx[1:] > idx[:-1]) and np.unique(idx).size != idx.size:
        raise SceneError(f"env: element indices must not repeat (got {_show(env)}): each "
                         f"element takes one value")
    return idx


class WorldEdit:
    """A proposed change of some elements of a world (see the module docstring).

    The candidate values of the selected elements are readable while the edit is open:
    ``mass``, ``radius``, ``half_length``, ``inertia`` (``[n, N]``), ``table_half_size``
    (``[n, 2]``), ``state`` (``[n, N, 6]``, ``physics.layout`` columns).
    """

    def __init__(self, world: World, env: Any = None) -> None:
        self._w = world
        self.rows = batch_rows(env, world.batch_size)
        self.n = len(self.rows)
        #: the selection as an index: a slice for every element (views, no gather)
        self._sel = slice(None) if env is None else self.rows
        self._copies: dict[str, np.ndarray] = {}
        self._changed: set[str] = set()
        self._placed_all = False
        self._done = False

    # -- candidate values ---------------------------------------------------------------------
    def _copy(self, name: str) -> np.ndarray:
        """The edit's copy of the world's private array ``name`` over the selected rows."""
        copy = self._copies.get(name)
        if copy is None:
            with self._w._lock:  # of one step (the world's kernels run without the GIL)
                if not self._copies:  # the world as the edit's copies show it
                    self._version = self._w._version
                copy = self._copies[name] = getattr(self._w, name)[self._sel].copy()
        return copy

    def _rows_of(self, name: str) -> np.ndarray:
        """:meth:`_copy`, to be changed (written back at commit)."""
        self._changed.add(name)
        return self._copy(name)

    def _view(self, name: str) -> np.ndarray:
        v = self._copy(name).view()
        v.flags.writeable = False
        return v

    mass = property(lambda self: self._view("_mass"), doc="[n, N] candidate masses, kg")
    radius = property(lambda self: self._view("_radius"), doc="[n, N] candidate radii, m")
    half_length = property(lambda self: self._view("_half_length"),
                           doc="[n, N] candidate half lengths, m")
    inertia = property(lambda self: self._view("_inertia"),
                       doc="[n, N] candidate moments of inertia, kg m^2")
    table_half_size = property(lambda self: self._view("_half"),
                               doc="[n, 2] candidate table half size, m")
    state = property(lambda self: self._view("_state"),
                     doc="[n, N, 6] candidate state rows (physics.layout columns)")

    # -- changes ------------------------------------------------------------------------------
    def set_body(self, body: int | str, *, mass: Any = None, radius: Any = None,
                 length: Any = None, thickness: Any = None, inertia: Any = None) -> None:
        """Change a body's numeric parameters (scalars or arrays over the selected elements):
        kg, m, m, m, kg m^2. The inertia is re-derived from the shape unless given here (or
        fixed by a numeric ``inertia`` in the scene)."""
        w = self._w
        i = w.body_index(body)
        name, shape = w.names[i], w.shapes[i]
        if w.static[i] and mass is not None:
            raise SceneError(f"{name}.mass: a static body has no finite mass")
        if shape == "disk" and (length is not None or thickness is not None):
            raise SceneError(f"{name}: a disk has radius only (no length or thickness)")
        if shape == "rod" and radius is not None:
            raise SceneError(f"{name}.radius: a rod has length and thickness, not radius")
        if inertia is not None and not w.rotation:
            raise SceneError(f"{name}.inertia: is set but the scene does not list the "
                             "'rotation' effect")
        values = self._body_values(name, mass=mass, radius=radius, length=length,
                                   thickness=thickness, inertia=inertia)
        if not values:
            return
        m = self._rows_of("_mass")
        r = self._rows_of("_radius")
        h = self._rows_of("_half_length")
        inert = self._rows_of("_inertia")
        if "mass" in values:
            m[:, i] = values["mass"]
        if "radius" in values:
            r[:, i] = values["radius"]
        if "thickness" in values:
            r[:, i] = 0.5 * values["thickness"]
        if "length" in values:
            h[:, i] = 0.5 * values["length"]
        if "inertia" in values:
            inert[:, i] = values["inertia"]
        elif not w.static[i] and not isinstance(w.scene.bodies[i].inertia, float):
            with np.errstate(over="ignore", under="ignore"):
                inert[:, i] = body_inertia(shape, m[:, i], r[:, i], h[:, i],
                                           w.scene.bodies[i].inertia)
            _invertible(inert[:, i], f"{name}.inertia (of this mass and size)")

    def _body_values(self, name: str, **given: Any) -> dict[str, np.ndarray]:
        """The given (not None) numeric parameters of body ``name`` as ``[n]`` arrays, checked:
        > 0 (a thickness >= 0), and a mass or moment with a finite inverse."""
        values = {}
        for field, value in given.items():
            if value is None:
                continue
            arr = as_batch(value, (self.n,), f"{name}.{field}")
            strict = field != "thickness"
            if np.any(arr <= 0) if strict else np.any(arr < 0):
                raise SceneError(f"{name}.{field}: must be {'>' if strict else '>='} 0 "
                                 f"(got {arr.min()})")
            if field in ("mass", "inertia"):
                _invertible(arr, f"{name}.{field}")
            values[field] = arr
        return values

    def set_material(self, a: str, b: str, *, restitution: Any = None,
                     friction: Any = None) -> None:
        """Change the restitution e in [0, 1] and/or contact friction mu >= 0 of the pair(s)
        between ``a`` and ``b`` (``"walls"`` for every cushion)."""
        w = self._w
        pairs = w.pair_rows(a, b)
        mats = None
        if restitution is not None:
            e = as_batch(restitution, (self.n,), "restitution")
            if np.any((e < 0) | (e > 1)):
                raise SceneError(f"restitution: must lie in [0, 1] (got {e.min()}..{e.max()})")
            mats = self._rows_of("_materials")
            mats[:, pairs, RESTITUTION] = e[:, None]
        if friction is not None:
            mu = as_batch(friction, (self.n,), "friction")
            if np.any(mu < 0):
                raise SceneError(f"friction: must be >= 0 (got {mu.min()})")
            if np.any(mu > 0) and not w.contact_friction:
                raise SceneError("friction: is set but the scene does not list the "
                                 "'contact_friction' effect")
            mats = self._rows_of("_materials")
            mats[:, pairs, FRICTION] = mu[:, None]

    def set_table(self, *, friction: Any = None, size: Any = None) -> None:
        """Change the cloth friction coefficient (>= 0) and/or the table size ([w, h], m)."""
        if friction is not None:
            mu = as_batch(friction, (self.n,), "table.friction")
            if np.any(mu < 0):
                raise SceneError(f"table.friction: must be >= 0 (got {mu.min()})")
            g = self._w.gravity
            with np.errstate(over="ignore"):
                deceleration = mu * g
            if not np.all(np.isfinite(deceleration)):
                raise SceneError(f"table.friction: times gravity ({g:g} m/s^2), the cloth's "
                                 f"deceleration, must be a finite number (got {mu.max():g})")
            if np.any(mu > 0) and not self._w.table_friction:
                raise SceneError("table.friction: is set but the scene does not list the "
                                 "'table_friction' effect")
            self._rows_of("_table_mu")[:] = mu
        if size is not None:
            s = as_batch(size, (self.n, 2), "table.size")
            if np.any(s <= 0):
                raise SceneError("table.size: must be positive lengths (m)")
            if not self._w.walls:  # as the scene's rule: no cushions, an unbounded table
                raise SceneError("table.size: is set but the scene does not list the 'walls' "
                                 "effect")
            self._rows_of("_half")[:] = 0.5 * s

    def set_state(self, *, positions: Any = None, angles: Any = None, velocities: Any = None,
                  omegas: Any = None, body: int | str | None = None) -> None:
        """Set (part of) the state of the selected elements, all bodies or ``body``: arrays
        broadcast to ``[n, k, 2]`` / ``[n, k]`` (m, rad CCW from +x, m/s, rad/s CCW > 0)."""
        w = self._w
        if body is None:
            cols: Any = slice(None)
            k = w.n_bodies
            static, fixed = w.static, w._fixed
            any_static, any_fixed = w._any_static, w._any_fixed
        else:
            cols = [w.body_index(body)]
            k = 1
            static, fixed = w.static[cols], w._fixed[cols]
            any_static, any_fixed = bool(static.any()), bool(fixed.any())
        s = self._rows_of("_state")
        if positions is not None:
            pos = as_batch(positions, (self.n, k, 2), "positions", keep_scalar=True)
            if any_fixed:  # they stay where the scene put them
                moved = np.any(pos != w._initial[cols, X:Y + 1], axis=(0, 2))
                if np.any(moved & fixed):
                    names = np.array(w.names[:w.n_bodies])[cols][moved & fixed]
                    raise SceneError(f"positions: static bodies and pivots cannot move "
                                     f"({[str(n) for n in names]})")
            s[:, cols, X:Y + 1] = pos
            self._placed_all |= body is None
        if angles is not None:
            ang = as_batch(angles, (self.n, k), "angles", keep_scalar=True)
            if any_static and np.any((ang != w._initial[cols, ANGLE]) & static):
                raise SceneError("angles: a static body cannot turn")
            s[:, cols, ANGLE] = ang
        if velocities is not None:
            vel = as_batch(velocities, (self.n, k, 2), "velocities", keep_scalar=True)
            if any_fixed and np.any((np.abs(np.broadcast_to(vel, (self.n, k, 2))).sum(
                    axis=(0, 2)) > 0) & fixed):
                raise SceneError("velocities: static bodies and pivots must have zero velocity")
            s[:, cols, VX:VY + 1] = vel
        if omegas is not None:
            om = as_batch(omegas, (self.n, k), "omegas", keep_scalar=True)
            if not w.rotation and np.any(om != 0):
                raise SceneError("omegas: nonzero spin but the scene does not list the "
                                 "'rotation' effect")
            if any_static and np.any((np.broadcast_to(om, (self.n, k)) != 0).any(axis=0)
                                     & static):
                raise SceneError("omegas: a static body cannot spin")
            s[:, cols, OMEGA] = om

    def set_force(self, body: int | str, force: Any) -> None:
        """Apply a constant force (N, ``[n, 2]`` or broadcastable) to a ``driven`` body."""
        w = self._w
        i = w.body_index(body)
        if not w.driven[i]:
            raise SceneError(f"{w.names[i]}: forces can only be applied to bodies marked "
                             "'driven: true' in the scene")
        self._rows_of("_forces")[:, i] = as_batch(force, (self.n, 2), f"{w.names[i]}.force",
                                                  keep_scalar=True)

    def set_time(self, time: Any) -> None:
        """Set the selected elements' clocks, s."""
        self._rows_of("_time")[:] = as_batch(time, (self.n,), "time", keep_scalar=True)

    # -- validation and commit ----------------------------------------------------------------
    def __enter__(self) -> WorldEdit:
        """The world is the block's until it ends: another thread's step or edit waits, so the
        block's copies stay those of the world it commits to (walk W26b F1)."""
        self._w._lock.acquire()
        self._held = True
        return self

    def __exit__(self, kind, value, traceback) -> None:
        try:
            if kind is None:
                self.commit()
            else:  # the block raised: nothing is written, on purpose
                self._done = True
        finally:
            if self.__dict__.pop("_held", False):
                self._w._lock.release()

    def __del__(self) -> None:
        """Warn about changes never written: ``world.edit(env).set_body(...)`` (no ``with``,
        no ``commit()``) silently did nothing (walk W24a F4)."""
        if not self.__dict__.get("_done", True) and self.__dict__.get("_changed"):
            # (no list of fields: the arrays a change touches are more than the user named)
            warnings.warn("world.edit(): an edit's changes were never written: use `with "
                          "world.edit(env) as e: e.set_...(...)`, or call e.commit() before "
                          "the world steps", RuntimeWarning, stacklevel=2)

    def commit(self) -> None:
        """Check the whole change once and write it (the world is unchanged if it raises)."""
        with self._w._lock:  # the check against the world's version, then the write
            self._commit()

    def _commit(self) -> None:
        if self._done:
            raise SceneError("this edit was committed already")
        self._done = True
        if self._copies and self._version != self._w._version:
            # its copies are of the world before: writing them back rewound what the world
            # did since, bodies the edit did not name too (walk W25 F5)
            raise SceneError("this edit's copies were taken before the world stepped or "
                             "changed since: committing them would put that back; open the "
                             "edit after stepping (with world.edit(env) as e: ...), nothing "
                             "was written")
        w, sel, changed = self._w, self._sel, self._changed
        if not changed or self.n == 0:
            return
        new = {name: self._copies[name] for name in changed}
        params = None
        if changed & {"_mass", "_radius", "_half_length", "_inertia", "_table_mu"}:
            params = w._derive_params(self._copy("_mass"), self._copy("_inertia"),
                                      self._copy("_radius"), self._copy("_half_length"),
                                      self._copy("_table_mu"))
        if changed & {"_state", "_radius", "_half_length", "_half"}:
            self._check_geometry(params)
        if "_radius" in changed:
            warn_tolerance_above_radii(w, self._copy("_radius"))
        for name, value in new.items():
            getattr(w, name)[sel] = value
        if params is not None:
            w._params[sel] = params
        w._version += 1
        w._sync_backend(params=params is not None or bool(changed & {"_materials", "_half"}),
                        state="_state" in changed)

    def _check_geometry(self, params: np.ndarray | None) -> None:
        """Raise if the change leaves a body overlapping another or a cushion (see the overlap
        rule in the module docstring)."""
        w, sel = self._w, self._sel
        if len(w.pair_a) == 0:
            return
        state = self._copy("_state") if "_state" in self._changed else w._state[sel]
        pm = params if params is not None else w._params[sel]
        half = self._copy("_half") if "_half" in self._changed else w._half[sel]
        tol = w.tolerance
        e, p, g = first_overlap(state, pm, half, w._pair_a, w._pair_b, tol)
        if e < 0:
            return
        new = w._gaps_of(state, pm, half)
        before = w._gaps_of(w._state[sel], w._params[sel], w._half[sel])
        bad = (new < -tol) & (new < before - tol)  # created or deepened
        if self._placed_all:  # and an overlap kept by a pair the placement moves
            old = w._state[sel]
            moved = np.any(state[..., X:ANGLE + 1] != old[..., X:ANGLE + 1], axis=2)
            moved = np.concatenate([moved, np.zeros((len(moved), 4), bool)], axis=1)  # cushions
            bad |= (new < -tol) & (moved[:, w._pair_a] | moved[:, w._pair_b])
        if not bad.any():
            return
        e, p = np.argwhere(bad)[0]
        g = new[e, p]
        a, b = w.names[w.pair_a[p]], w.names[w.pair_b[p]]
        where = f"in element {self.rows[e]} (tolerance {tol:g} m)"
        if w.pair_b[p] >= w.n_bodies:
            raise SceneError(f"bodies: {a!r} would lie outside the table, {-g:.3g} m past "
                             f"the cushion {b!r}, {where}")
        kept = ""
        if before[e, p] < -tol:
            kept = (f" (they overlapped by {-before[e, p]:.3g} m already: a change that places "
                    f"every body must separate them; set_state(body=...) may move one alone "
                    f"and keep the overlap)")
        raise SceneError(f"bodies: {a!r} and {b!r} overlap by {-g:.3g} m {where}; "
                         f"touching is allowed, overlap beyond the tolerance is not{kept}")


def check_snapshot(w: World, a: dict[str, np.ndarray]) -> None:
    """Raise :class:`SceneError` naming the field and body if the rows of a snapshot that
    ``restore`` is about to write (``a``: private array name -> rows; the parameters too, if it
    has them) hold what no edit of this world could make: fixed bodies off their pins or moving,
    spin without ``rotation``, forces on bodies that are not driven, parameters out of range or
    of another shape of body, friction of an effect the scene does not list. (Geometry is
    ``restore``'s to check, on the exact solver only, whose states never overlap; a fixed or
    pymunk snapshot may hold the overlap an impact left.)"""
    s = a.get("_state")
    if s is not None:
        fixed, static = np.asarray(w._fixed), np.asarray(w.static)
        off = _any_element(np.any(s[..., X:Y + 1] != w._initial[:, X:Y + 1], axis=-1)) & fixed
        if off.any():
            _snapshot_error(w, "state", off, "static bodies and pivots stay at their pins (the "
                                              "scene's positions)")
        moving = _any_element(np.any(s[..., VX:VY + 1] != 0, axis=-1)) & fixed
        if moving.any():
            _snapshot_error(w, "state", moving, "static bodies and pivots have zero velocity")
        turned = _any_element((s[..., ANGLE] != w._initial[:, ANGLE]) | (s[..., OMEGA] != 0))
        if (turned & static).any():
            _snapshot_error(w, "state", turned & static, "a static body neither turns nor spins")
        if not w.rotation and np.any(s[..., OMEGA] != 0):
            _snapshot_error(w, "state", _any_element(s[..., OMEGA] != 0),
                            "spin, but the scene does not list the 'rotation' effect")
    t = a.get("_time")
    if t is not None and np.any(t < 0):
        _snapshot_error(w, "time", None, "must be >= 0 s (a world's clock starts at 0)")
    f = a.get("_forces")
    if f is not None:
        pushed = _any_element(np.any(f != 0, axis=-1)) & ~np.asarray(w.driven)
        if pushed.any():
            _snapshot_error(w, "forces", pushed, "only bodies marked 'driven: true' take forces")
    if "_mass" in a:
        _check_snapshot_parameters(w, a)


def _check_snapshot_parameters(w: World, a: dict[str, np.ndarray]) -> None:
    """:func:`check_snapshot`'s parameters."""
    dynamic = ~np.asarray(w.static)
    disk = np.array([shape == "disk" for shape in w.shapes[:w.n_bodies]])
    checks = [
        ("mass", _any_element(~invertible(a["_mass"])) & dynamic,
         "must be a finite number > 0 kg, with a finite inverse (inf: make the body static)"),
        ("inertia", _any_element(~invertible(a["_inertia"])) & dynamic,
         "must be a finite number > 0 kg m^2, with a finite inverse"),
        ("radius", _any_element(~(a["_radius"] > 0)) & disk,
         "a disk's radius must be > 0 m"),
        ("radius", _any_element(~(a["_radius"] >= 0)) & ~disk,
         "a rod's half thickness must be >= 0 m"),
        ("half_length", _any_element(a["_half_length"] != 0) & disk,
         "a disk has no length (is this another scene's snapshot?)"),
        ("half_length", _any_element(~(a["_half_length"] > 0)) & ~disk,
         "a rod's half length must be > 0 m (is this another scene's snapshot?)"),
    ]
    for field, bad, what in checks:
        if bad.any():
            _snapshot_error(w, field, bad, what)
    mu = a["_table_mu"]
    if np.any(mu < 0) or (not w.table_friction and np.any(mu != 0)):
        _snapshot_error(w, "table_friction", None, "must be >= 0, and 0 unless the scene lists "
                                                   "the 'table_friction' effect")
    half = a["_half"]
    if w.walls and np.any(~((half > 0) & np.isfinite(half))):
        _snapshot_error(w, "table_half_size", None, "must be finite and > 0 m: the scene lists "
                                                    "the 'walls' effect, cushions at +-size/2")
    if not w.walls and np.any(half != np.inf):
        _snapshot_error(w, "table_half_size", None, "must be inf: the scene does not list the "
                                                    "'walls' effect (an unbounded table)")
    m = a["_materials"]
    if np.any((m[..., RESTITUTION] < 0) | (m[..., RESTITUTION] > 1)):
        _snapshot_error(w, "materials", None, "restitution must lie in [0, 1]")
    if np.any(m[..., FRICTION] < 0) or (not w.contact_friction and np.any(m[..., FRICTION] != 0)):
        _snapshot_error(w, "materials", None, "friction must be >= 0, and 0 unless the scene "
                                              "lists the 'contact_friction' effect")


def _any_element(bad: np.ndarray) -> np.ndarray:
    """``[n, N]`` -> ``[N]``: the bodies for which any selected element is ``bad``."""
    return bad.reshape(-1, bad.shape[-1]).any(axis=0)


def _snapshot_error(w: World, field: str, bodies: np.ndarray | None, what: str) -> None:
    where = "" if bodies is None else f" ({[str(w.names[i]) for i in np.flatnonzero(bodies)]})"
    raise SceneError(f"snapshot.{field}{where}: {what}")


def warn_tolerance_above_radii(w: World, radius: np.ndarray) -> None:
    """Warn (naming ``solver.tolerance`` and the bodies) where the exact solver's tolerance is
    larger than the radii together of a disk and a body it can meet (another disk, or a rod:
    its half-thickness), the length over which their contact normal turns (at a disk, or a
    rod's end cap). Contacts are resolved up to the tolerance apart, so there the impulses act
    at a distance: two disks of 0.1 mm at a tolerance of 1 mm collided 8 radii apart, 33 % off,
    and a 0.1 mm disk on a 0.2 mm rod's end cap 0.39 m/s off at 1 m/s, without a word (the
    error goes as tolerance / radii: 2e-4 at 1, 2e-7 at 0.1). Two rods meet where one's side,
    flat, gives the normal: a 1 µm rod's tip on another's side keeps the closed form at a
    tolerance of 1 mm, so they are not warned of, nor cushions. ``radius``: ``[n, N]``."""
    from spinstrike.physics.scene import ExactSolver
    from spinstrike.physics.world import _caller_level

    if not isinstance(w.solver, ExactSolver):  # (the others have no tolerance to set)
        return
    a, b = np.asarray(w._pair_a), np.asarray(w._pair_b)
    disks = np.array([shape == "disk" for shape in w.shapes] + [False] * (len(w.names)
                                                                          - w.n_bodies))
    pairs = (disks[a] | disks[b]) & (b < w.n_bodies)
    a, b = a[pairs], b[pairs]
    together = radius[:, a] + radius[:, b]  # [n, P]
    small = (together > 0) & (together < w._tolerance)
    if not small.any():
        return
    k = int(np.flatnonzero(small.any(axis=0))[0])
    least = float(together[:, k][small[:, k]].min())
    warnings.warn(
        f"solver.tolerance: {w._tolerance:g} m is larger than the radii of bodies "
        f"{w.names[a[k]]!r} and {w.names[b[k]]!r} together ({least:g} m): the exact solver "
        f"resolves contacts up to the tolerance apart, so their impulses act at a distance "
        f"(the error goes as tolerance / radii); give a tolerance well below them",
        RuntimeWarning, stacklevel=_caller_level())


@jit
def first_overlap(S, Pm, HW, PA, PB, tol):
    """(element, pair, gap) of the first pair overlapping by more than ``tol`` in state rows
    ``S [n, N, 6]``, or (-1, -1, 0.0) if none does."""
    for b in range(S.shape[0]):
        p, g = element_overlap(S[b], Pm[b], HW[b], PA, PB, tol)
        if p >= 0:
            return b, p, g
    return -1, -1, 0.0
