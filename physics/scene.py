"""Scene schema: plain data (YAML or a dict) validated once into typed objects.

A scene lists the bodies on the table, the effects to simulate, the materials and the solver.
Every invalid value raises :class:`SceneError` with a message that names the field and what is
allowed, e.g. ``bodies[1].mass: must be > 0 (got -1.0)``.

Units are SI throughout: metres, kilograms, seconds, radians (counter-clockwise from +x).

Example::

    table:   {size: [1.2, 0.8]}             # centred on the origin; omitted: unbounded plane
    effects: [rotation, walls]
    solver:  {mode: exact, tolerance: 1.0e-9}
    materials: {restitution: 1.0, friction: 0.0}
    bodies:
      - {name: rod, shape: rod, length: 0.4, thickness: 0.02, mass: 0.1}
      - {name: striker, shape: disk, radius: 0.04, mass: 0.2, position: [-0.3, 0]}
"""

from __future__ import annotations

import difflib
import math
import re
import typing
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    field_validator,
    model_validator,
)

from spinstrike.physics.effects import EFFECTS
from spinstrike.physics.shapes import capsule_inertia, disk_inertia

__all__ = [
    "Body",
    "ExactSolver",
    "FixedSolver",
    "Finite",
    "Flag",
    "Integer",
    "Number",
    "Materials",
    "PairMaterial",
    "PymunkSolver",
    "Scene",
    "SOLVERS",
    "SceneError",
    "SolverConfig",
    "Table",
    "WALL_NAMES",
    "load_scene",
    "packaged_scene",
    "packaged_scenes",
    "read_scene",
    "solver_over",
    "validate_solver",
]

#: Names of the four cushions created by the ``walls`` effect, in index order after the bodies.
WALL_NAMES = ("wall_left", "wall_right", "wall_bottom", "wall_top")


class SceneError(ValueError):
    """An invalid scene, solver block or body parameter. The message names the field."""


def _integer(value: Any) -> int:
    """An integer, numpy's included; booleans, strings and floats are refused."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"must be an integer (got {value!r})")
    return int(value)


#: a number: an int or float (numpy's too), never a string or a boolean (pydantic strict mode,
#: so ``"0.5"`` or ``True`` is an error that names the field instead of 0.5 or 1.0)
Number = Annotated[float, Strict()]
#: a finite number
Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]
#: an integer
Integer = Annotated[int, BeforeValidator(_integer)]
#: a boolean (``true``/``false``, never 0, 1 or a string)
Flag = Annotated[bool, Strict()]
Vec2 = tuple[Finite, Finite]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


# ---------------------------------------------------------------------------------------------
# Solvers
# ---------------------------------------------------------------------------------------------


#: the exact solver's default ``max_events``: at least this many events a step, and at least
#: ``EVENTS_PER_BODY`` per body
MIN_EVENTS = 10_000
EVENTS_PER_BODY = 20


class ExactSolver(_Model):
    """Event-driven solver: closed-form flight, time of impact by conservative advancement and
    bracketing, the impulse applied at the true contact geometry. Cannot tunnel.

    Attributes:
        tolerance: gap (m) within which two approaching bodies are in contact. The time of impact
            is found to this gap, so it sets the accuracy. Smaller costs more root-finding
            iterations per collision. Default 1e-9 m; allowed (0, 1e-2]. One below what
            float64 resolves at the scene's coordinates (~2e-16 of them: ~1e-16 m on a 1 m
            table) cannot be met: its searches stall and the steps are settled (flagged in
            ``fallback``), with results as at the resolution.
        max_events: events (impacts and checkpoints) per batch element per ``step`` before the
            rest of the step is integrated by the fixed-step contact solver (the element is then
            flagged in ``world.last_step.fallback``). Default (None): 10,000, or
            ``EVENTS_PER_BODY`` (20) per body where that is more. Events are cheaper than the
            settle, and more exact: at 1000 a 1 g rod jammed against a cushion by a disk 1e9
            times heavier (~1,100 events a step, as the square root of the ratio) was settled,
            which gave the rod 15 % of the disk's energy; and a fixed 1000 settled every
            0.01 s step of 256 pucks in a box at e = 1, 931 events a step at 196).
        max_iterations: conservative-advancement iterations per time-of-impact search before it
            adds a second-order bound (``events.curved_step``: beside a fast-turning rod the
            first-order steps get tiny) for up to as many more, and then reports a safe
            checkpoint instead (the world advances to it and searches again). Default 64.
        zeno_speed: an impact closing slower than this (m/s) counts as a *resting* bounce.
            Default 1e-3 m/s.
        zeno_impacts: after this many resting bounces in one step (an inelastic body pinned by a
            force: infinitely many ever-smaller impacts in finite time) the rest of the step is
            settled by the fixed-step contact solver, which handles resting contact. Default 8.
        settle_substep: longest substep (s) of that settling integration; it is shortened further
            so that no pair closes by more than half of the depth at which an overlap is still
            seen (the sum of the two radii). Default 1e-3 s.
    """

    mode: Literal["exact"] = "exact"
    tolerance: Number = Field(1e-9, gt=0.0, le=1e-2)
    max_events: Integer | None = Field(None, ge=1, le=10_000_000)
    max_iterations: Integer = Field(64, ge=4, le=100_000)
    zeno_speed: Number = Field(1e-3, ge=0.0)
    zeno_impacts: Integer = Field(8, ge=1)
    settle_substep: Number = Field(1e-3, gt=0.0)

    def events_for(self, n_bodies: int) -> int:
        """The events a step of a world of ``n_bodies`` may take (``max_events``, or its
        default for that many bodies)."""
        if self.max_events is not None:
            return self.max_events
        return max(MIN_EVENTS, EVENTS_PER_BODY * n_bodies)


class FixedSolver(_Model):
    """Fixed-substep solver: symplectic Euler, discrete overlap detection, impulses from the
    overlapped pose and positional correction. Cheap; its error grows with the distance moved per
    substep and it tunnels once ``speed * dt / substeps`` exceeds the bodies' sizes.

    Attributes:
        substeps: substeps per ``world.step(dt)``. More costs proportionally more time and shrinks
            the error. Default 1; allowed 1..100000.
        iterations: sequential-impulse sweeps over the overlapping pairs per substep. Default 4.
    """

    mode: Literal["fixed"] = "fixed"
    substeps: Integer = Field(1, ge=1, le=100_000)
    iterations: Integer = Field(4, ge=1, le=1000)


class PymunkSolver(_Model):
    """The same scene on Chipmunk2D through pymunk (see ``physics.pymunk_backend``).

    Attributes:
        substeps: pymunk steps per ``world.step(dt)``. Default 10.
        iterations: pymunk's ``Space.iterations``. Default 10.
    """

    mode: Literal["pymunk"] = "pymunk"
    substeps: Integer = Field(10, ge=1, le=100_000)
    iterations: Integer = Field(10, ge=1, le=100_000)


SolverConfig = Annotated[ExactSolver | FixedSolver | PymunkSolver, Field(discriminator="mode")]


# ---------------------------------------------------------------------------------------------
# Table, materials, bodies
# ---------------------------------------------------------------------------------------------


class Table(_Model):
    """The table, centred on the origin.

    Attributes:
        size: [width, height] in m; the cushions (``walls`` effect) lie on its edges.
        friction: Coulomb coefficient between bodies and the cloth (``table_friction`` effect).
        gravity: m/s^2, presses bodies onto the cloth (only used by ``table_friction``).
    """

    size: Vec2 | None = None
    friction: Number = Field(0.0, ge=0.0, allow_inf_nan=False)
    gravity: Number = Field(9.81, gt=0.0, allow_inf_nan=False)

    @field_validator("size")
    @classmethod
    def _positive_size(cls, v: Vec2 | None) -> Vec2 | None:
        if v is not None and (v[0] <= 0 or v[1] <= 0):
            raise ValueError(f"must be two positive lengths in m (got {list(v)})")
        return v

    @model_validator(mode="after")
    def _finite_deceleration(self) -> Table:
        # (1e308 of either was taken, and their product overflowed: a bare numpy warning, and
        # an infinite deceleration)
        if not math.isfinite(self.friction * self.gravity):
            raise ValueError(f"friction x gravity, the cloth's deceleration, must be a finite "
                             f"number (got {self.friction:g} x {self.gravity:g})")
        return self


class PairMaterial(_Model):
    """Per-pair override: ``bodies`` names two bodies, or a body and ``walls`` / a wall name."""

    bodies: tuple[str, str]
    restitution: Number | None = Field(None, ge=0.0, le=1.0)
    friction: Number | None = Field(None, ge=0.0)


class Materials(_Model):
    """Contact materials.

    Attributes:
        restitution: Newton's coefficient e in [0, 1]: the normal relative velocity at the contact
            point after an impact is -e times the one before.
        friction: Coulomb coefficient mu >= 0 of the tangential contact impulse
            (``contact_friction`` effect).
        pairs: per-pair overrides.
    """

    restitution: Number = Field(1.0, ge=0.0, le=1.0)
    friction: Number = Field(0.0, ge=0.0)
    pairs: tuple[PairMaterial, ...] = ()


class Body(_Model):
    """A rigid body on the table.

    Attributes:
        name: unique name.
        shape: ``disk`` (a puck of ``radius``) or ``rod`` (a capsule: a segment of ``length`` with
            round ends of diameter ``thickness``; its overall extent is ``length + thickness``).
        mass: kg, > 0. Ignored (may be omitted) for a static body.
        inertia: kg m^2 about the centre of mass; default the exact value for the shape. The
            string ``thin_rod`` gives ``mass * length**2 / 12`` (the seed note's ``m r^2 / 3``
            with r the half-length).
        position: [x, y] of the centre of mass, m.  angle: rad, CCW from +x (the rod's axis).
        velocity: [vx, vy], m/s.  omega: rad/s, CCW positive.
        static: infinite mass and inertia (inverse mass and inertia 0); must not move.
        pivot: pinned at its centre: infinite mass, finite inertia (needs ``rotation``).
        driven: may be pushed by an applied force (``World.set_force``); a driven body is not
            slowed by table friction (its force is the net force).
    """

    name: str = Field(min_length=1)
    shape: Literal["disk", "rod"]
    mass: Number | None = Field(None, gt=0.0)
    radius: Number | None = Field(None, gt=0.0)
    length: Number | None = Field(None, gt=0.0)
    thickness: Number | None = Field(None, ge=0.0)
    inertia: Number | Literal["thin_rod"] | None = None
    position: Vec2 = (0.0, 0.0)
    angle: Finite = 0.0
    velocity: Vec2 = (0.0, 0.0)
    omega: Finite = 0.0
    static: Flag = False
    pivot: Flag = False
    driven: Flag = False

    @field_validator("inertia")
    @classmethod
    def _positive_inertia(cls, v: float | str | None) -> float | str | None:
        if isinstance(v, float) and not (math.isfinite(v) and v > 0):
            raise ValueError(f"must be a finite number > 0 in kg m^2, or 'thin_rod' (got {v})")
        return v

    @model_validator(mode="after")
    def _shape_fields(self) -> Body:
        if self.name in WALL_NAMES or self.name == "walls":
            raise ValueError(f"name: {self.name!r} is reserved for the cushions")
        if self.shape == "disk":
            _require(self.radius is not None, "radius", "a disk needs radius > 0 (m)")
            _require(self.length is None and self.thickness is None, "length",
                     "a disk has radius only; length and thickness belong to rods")
            _require(self.inertia != "thin_rod", "inertia", "'thin_rod' applies to rods only")
        else:
            _require(self.length is not None, "length", "a rod needs length > 0 (m)")
            _require(self.radius is None, "radius", "a rod has length and thickness, not radius")
        if self.static:
            _require(not self.pivot and not self.driven, "static",
                     "a static body cannot also be a pivot or driven")
            _require(self.velocity == (0.0, 0.0) and self.omega == 0.0, "velocity",
                     "a static body must have zero velocity and omega")
        else:
            _require(self.mass is not None, "mass", "required for a non-static body, > 0 (kg)")
            _require(invertible(self.mass), "mass",
                     f"{self.mass:g} kg is too small or large for float64: its inverse, which "
                     f"the impulses use, is not a finite nonzero number")
            try:
                moment = self.moment
            except OverflowError:
                moment = math.inf
            # named after what the user set: the inertia, or the size it is derived from
            size = "radius" if self.shape == "disk" else "length"
            _require(invertible(moment), "inertia" if self.inertia is not None else size,
                     f"the moment of inertia of this mass and size ({moment:g} kg m^2) is too "
                     f"small or large for float64: its inverse is not a finite nonzero number")
        if self.pivot:
            _require(not self.driven, "pivot", "a pivot cannot be driven")
            _require(self.velocity == (0.0, 0.0), "velocity",
                     "a pivot is pinned at its centre: velocity must be zero")
        return self

    @property
    def half_length(self) -> float:
        """Half the length of the capsule's core segment, m (0 for a disk)."""
        return 0.5 * self.length if self.shape == "rod" else 0.0

    @property
    def core_radius(self) -> float:
        """Radius swept around the core segment, m (disk radius, or half the rod thickness)."""
        return self.radius if self.shape == "disk" else 0.5 * (self.thickness or 0.0)

    @property
    def moment(self) -> float:
        """Moment of inertia about the centre of mass, kg m^2 (derived unless overridden)."""
        return body_inertia(self.shape, self.mass or 0.0, self.core_radius, self.half_length,
                            self.inertia)


def invertible(x: Any) -> Any:
    """Elementwise: ``x`` is a finite number > 0 whose inverse is finite and nonzero too (a
    mass or moment of inertia the impulses divide by: 1e-310 kg has an infinite inverse).
    A bool for a scalar, a boolean array for an array."""
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore", over="ignore"):
        inverse = 1.0 / x
    ok = np.isfinite(x) & (x > 0.0) & np.isfinite(inverse) & (inverse > 0.0)
    return bool(ok) if ok.ndim == 0 else ok


def body_inertia(shape: str, mass, radius, half_length, override=None):
    """Moment of inertia of a body (works on scalars and numpy arrays alike)."""
    if isinstance(override, float):
        return override
    if override == "thin_rod":
        return mass * (2.0 * half_length) ** 2 / 12.0
    if shape == "disk":
        return disk_inertia(mass, radius)
    return capsule_inertia(mass, 2.0 * half_length, radius)


def _require(ok: bool, field: str, message: str) -> None:
    if not ok:
        raise ValueError(f"{field}: {message}")


class Scene(_Model):
    """A validated scene. Build it with :func:`load_scene`."""

    table: Table = Table()
    effects: tuple[Literal[tuple(EFFECTS)], ...] = ("rotation",)  # type: ignore[valid-type]
    solver: SolverConfig = ExactSolver()
    materials: Materials = Materials()
    bodies: tuple[Body, ...] = Field(min_length=1)

    @field_validator("solver", mode="before")
    @classmethod
    def _mode_name(cls, v: Any) -> Any:
        return {"mode": v} if isinstance(v, str) else v  # `solver: fixed`, as World(solver=...)

    @model_validator(mode="after")
    def _consistency(self) -> Scene:
        effects = set(self.effects)
        _require(len(effects) == len(self.effects), "effects", "lists an effect twice")
        names = [b.name for b in self.bodies]
        for name in names:
            _require(names.count(name) == 1, "bodies", f"body name {name!r} is used twice")
        rotation = "rotation" in effects
        for i, body in enumerate(self.bodies):
            if not rotation:
                _require(body.omega == 0.0, f"bodies[{i}].omega",
                         "is set but the scene does not list the 'rotation' effect")
                _require(not body.pivot, f"bodies[{i}].pivot",
                         "a pivot needs the 'rotation' effect")
                _require(body.inertia is None, f"bodies[{i}].inertia",
                         "is set but the scene does not list the 'rotation' effect")
        if "walls" in effects:
            _require(self.table.size is not None, "table.size",
                     "the 'walls' effect needs a table size [width, height] (m)")
        else:  # a table no cushion bounds: a size would claim one (table_half_size, the view)
            _require(self.table.size is None, "table.size",
                     "is set but the scene does not list the 'walls' effect: without "
                     "cushions the table is unbounded (add 'walls', or drop size)")
        if "table_friction" not in effects:
            _require(self.table.friction == 0.0, "table.friction",
                     "is set but the scene does not list the 'table_friction' effect")
            _require("gravity" not in self.table.model_fields_set, "table.gravity",
                     "is set but the scene does not list the 'table_friction' effect (gravity "
                     "only presses bodies onto the cloth)")
        if "contact_friction" not in effects:
            _require(self.materials.friction == 0.0, "materials.friction",
                     "is set but the scene does not list the 'contact_friction' effect")
        self._check_pairs(set(names), effects)
        if self.table.size is not None and "walls" in effects:
            self._check_inside_table()
        return self

    def _check_pairs(self, names: set[str], effects: set[str]) -> None:
        """``materials.pairs``: known bodies, a pair that can touch, each property once."""
        cushions = {"walls", *WALL_NAMES}
        allowed = names | (cushions if "walls" in effects else set())
        static = {b.name for b in self.bodies if b.static} | cushions
        seen: dict[tuple[frozenset, str], int] = {}
        for k, pair in enumerate(self.materials.pairs):
            field = f"materials.pairs[{k}].bodies"
            for name in pair.bodies:
                if name in cushions and "walls" not in effects:
                    _require(False, field, f"{name!r} names the cushions, but the scene does "
                                           f"not list the 'walls' effect")
                _require(name in allowed, field,
                         f"unknown body {name!r}; allowed: {sorted(allowed)}")
            a, b = pair.bodies
            _require(a != b, field, f"names {a!r} twice: a body never touches itself")
            _require(not (a in static and b in static), field,
                     f"{a!r} and {b!r} never touch: static bodies and cushions do not move, so "
                     f"only a pair with a moving body has a contact")
            if "contact_friction" not in effects:
                _require(not pair.friction, f"materials.pairs[{k}].friction",
                         "is set but the scene does not list the 'contact_friction' effect")
            _require(pair.restitution is not None or pair.friction is not None,
                     f"materials.pairs[{k}]", "sets neither restitution nor friction")
            # one entry per property and pair: the last of two would win silently ('walls'
            # names the four cushions, so it and a cushion's own entry name the same pairs)
            for x in (WALL_NAMES if a == "walls" else (a,)):
                for y in (WALL_NAMES if b == "walls" else (b,)):
                    for prop in ("restitution", "friction"):
                        if getattr(pair, prop) is None:
                            continue
                        key = (frozenset((x, y)), prop)
                        _require(key not in seen, f"materials.pairs[{k}].{prop}",
                                 f"{x!r}-{y!r} already has a {prop} from "
                                 f"materials.pairs[{seen.get(key)}]: give each pair's {prop} "
                                 f"once")
                        seen[key] = k

    def _check_inside_table(self) -> None:
        half_w, half_h = 0.5 * self.table.size[0], 0.5 * self.table.size[1]
        for i, b in enumerate(self.bodies):  # static bodies too: one outside is a typo
            reach_x = b.half_length * abs(math.cos(b.angle)) + b.core_radius
            reach_y = b.half_length * abs(math.sin(b.angle)) + b.core_radius
            x, y = b.position
            # touching a cushion is legal: allow the round-off of adding the reach (a disk of
            # radius 0.05 at x = -0.55 reaches 0.6000000000000001 on a table 1.2 m wide)
            slack_x = 4 * _ULP * (abs(x) + reach_x)
            slack_y = 4 * _ULP * (abs(y) + reach_y)
            _require(abs(x) + reach_x <= half_w + slack_x and abs(y) + reach_y <= half_h + slack_y,
                     f"bodies[{i}].position",
                     f"{b.name!r} must lie inside the table [-{half_w}, {half_w}] x "
                     f"[-{half_h}, {half_h}] m (it reaches to x = {x:+.4g} +/- {reach_x:.4g}, "
                     f"y = {y:+.4g} +/- {reach_y:.4g})")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bodies)


#: float64 machine epsilon (relative round-off)
_ULP = 2.0**-52
_FIELD = re.compile(r"[A-Za-z_][\w.\[\]]*")
#: solver modes a scene may name (``solver: {mode: ...}``), from the solver models themselves
SOLVERS: tuple[str, ...] = tuple(m.model_fields["mode"].default
                                 for m in (ExactSolver, FixedSolver, PymunkSolver))


#: a location part that names a member of a union type (``float``, ``literal['a','b']``, ...)
#: rather than a field: pydantic reports one error per member it tried
UNION_MEMBER = re.compile(r"^(?:[a-z-]+\[.*\]|(?:constrained-)?(?:float|int|str|bool|list|tuple"
                          r"|dict|none))$")


def join_by_field(errors: Iterable[tuple[str, str, str]]) -> str:
    """``(field, message, got)`` errors as ``<field>: <message><got>``, one per field: the
    messages pydantic gives for the members of a union (``inertia``: a number or ``thin_rod``)
    are joined by ", or " into one."""
    found: dict[str, tuple[list[str], str]] = {}
    for loc, msg, got in errors:
        msgs, _ = found.setdefault(loc, ([], got))
        msgs.append(msg if not msgs else msg.removeprefix("Input should be "))
    return "; ".join(f"{loc}: {', or '.join(msgs)}{got}" for loc, (msgs, got) in found.items())


def _format_error(err: ValidationError) -> str:
    """One line per field: ``<field path>: <what is wrong and what is allowed> (got <input>)``
    (:func:`join_by_field`)."""
    return join_by_field(_field_errors(err))


def _field_errors(err: ValidationError) -> Iterator[tuple[str, str, str]]:
    errors = err.errors()
    for e in errors:
        if e["type"] == "too_short" and any(
                len(o["loc"]) > len(e["loc"]) and o["loc"][:len(e["loc"])] == e["loc"]
                for o in errors):
            continue  # "bodies: at least 1 item": only because an item inside failed
        loc = ""
        for part in e["loc"]:
            if isinstance(part, int):
                loc += f"[{part}]"
            elif part not in SOLVERS and not UNION_MEMBER.match(str(part)):
                loc += ("." if loc else "") + str(part)
        msg = e["msg"].removeprefix("Value error, ")
        got = ""
        if e["type"] == "union_tag_invalid":  # pydantic's words for an unknown solver mode
            ctx = e["ctx"]
            key = ctx["discriminator"].strip("'")
            msg = f"unknown {key} {ctx['tag']!r}; allowed: {ctx['expected_tags']}"
        elif e["type"] == "union_tag_not_found":  # a solver block without its mode
            key = e["ctx"]["discriminator"].strip("'")
            msg = f"needs {key!r}, one of {', '.join(map(repr, SOLVERS))}"
        elif e["type"] == "value_error":
            field, sep, rest = msg.partition(": ")
            if sep and _FIELD.fullmatch(field):  # our validators say "<field>: <message>"
                loc, msg = (f"{loc}.{field}" if loc else field), rest
        elif e["type"] == "extra_forbidden":
            msg = _unknown_field(e["loc"])
        elif e["type"] == "tuple_type":  # a tuple field is a list in YAML and JSON
            msg = "Input should be a list"
        if (e["type"] not in ("union_tag_invalid", "union_tag_not_found", "value_error")
                and "input" in e and not isinstance(e["input"], dict)):
            got = f" (got {e['input']!r})"
        yield loc or "scene", msg, got


def _models_in(annotation: Any) -> list[type[BaseModel]]:
    """The scene models a field's type holds (``tuple[Body, ...]`` -> [Body])."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models_in(arg)]


#: each solver mode's model
_SOLVER_MODELS = {m.model_fields["mode"].default: m for m in (ExactSolver, FixedSolver,
                                                               PymunkSolver)}
#: each scene section's model, by the name a user writes it under
_SECTIONS = {"the scene's top level": Scene, "table": Table, "materials": Materials,
             "materials.pairs[]": PairMaterial, "bodies[]": Body,
             **{f"solver (mode {mode})": m for mode, m in _SOLVER_MODELS.items()}}


def _unknown_field(loc: tuple) -> str:
    """What an unknown key at ``loc`` should have been: the fields allowed there, the nearest
    spelling, or the sections that do have a field of that name (``gravity`` is the table's)."""
    models: list[type[BaseModel]] = [Scene]
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        if part in SOLVERS:  # the member of the solver union pydantic tried
            models = [_SOLVER_MODELS[part]]
            continue
        models = [m for model in models if part in model.model_fields
                  for m in _models_in(model.model_fields[part].annotation)]
    if len(models) != 1:
        return "unknown field"
    key, allowed = str(loc[-1]), list(models[0].model_fields)
    msg = f"unknown field; allowed: {allowed}"
    owners = [name for name, m in _SECTIONS.items() if key in m.model_fields]
    if owners:
        return f"{msg} ({key!r} is a field of {' and '.join(owners)})"
    near = difflib.get_close_matches(key, allowed, n=1)
    return f"{msg} (did you mean {near[0]!r}?)" if near else msg


#: the package that ships the scenes (``configs/scenes/*.yaml`` in the repository)
SCENES_PACKAGE = "spinstrike.configs.scenes"


def packaged_scenes() -> list[str]:
    """Names of the scenes shipped with the package (``configs/scenes/<name>.yaml``)."""
    from importlib import resources

    return sorted(f.name[:-len(".yaml")] for f in resources.files(SCENES_PACKAGE).iterdir()
                  if f.name.endswith(".yaml"))


def packaged_scene(name: str) -> dict[str, Any]:
    """The raw (unvalidated) dict of the packaged scene ``name`` (:func:`packaged_scenes`).

    Raises:
        SceneError: ``name`` is not a packaged scene (the names are listed).
    """
    from importlib import resources

    names = packaged_scenes()
    if name not in names:
        raise SceneError(f"scene: {name!r} is neither a file nor a packaged scene's name "
                         f"(packaged: {names})")
    return load_yaml(resources.files(SCENES_PACKAGE).joinpath(f"{name}.yaml").read_text())


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader refusing a key given twice in one mapping (PyYAML keeps the last
    silently: ``{mass: 1, mass: 2}`` read as mass 2, and a file with two ``bodies:`` blocks as
    its last one)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue  # keys merged in (<<) may be overridden, as YAML allows
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.setdefault(key, key_node.start_mark)
                except TypeError:  # an unhashable key: PyYAML's own error follows
                    continue
                if first is not key_node.start_mark:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"found the key {key!r} twice in one mapping (first at "
                        f"line {first.line + 1}); give it once", key_node.start_mark)
        return super().construct_mapping(node, deep)


# Plain scalars are read by YAML 1.2's core schema, not PyYAML's YAML 1.1: a float's exponent
# needs no dot (``tolerance: 1e-9`` was refused as "not a number (got '1e-9')"), ``010`` is ten
# (1.1: eight), and ``1:30`` (1.1: ninety), ``1_0`` (ten), ``0b1``, ``on``, ``yes``, ``no`` and
# dates are strings, which the schema then refuses naming the field (1.1 read ``on`` as true,
# silently). Merge keys (``<<``) stay.
_CORE = {
    "tag:yaml.org,2002:null": (r"~|null|Null|NULL|", list("~nN") + [""]),
    "tag:yaml.org,2002:bool": (r"true|True|TRUE|false|False|FALSE", list("tTfF")),
    "tag:yaml.org,2002:int": (r"[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+", list("-+0123456789")),
    "tag:yaml.org,2002:float": (
        r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?|[-+]?\.(inf|Inf|INF)"
        r"|\.nan|\.NaN|\.NAN", list("-+.0123456789")),
}
_StrictLoader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag == "tag:yaml.org,2002:merge"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
for _tag, (_pattern, _first) in _CORE.items():
    _StrictLoader.add_implicit_resolver(_tag, re.compile(f"^(?:{_pattern})$"), _first)


def _core_int(loader, node) -> int:
    """An int as YAML 1.2 reads it: decimal (``010`` is ten), ``0o`` octal, ``0x`` hex."""
    text = loader.construct_scalar(node)
    if text.startswith(("0o", "0x")):
        return int(text[2:], 8 if text[1] == "o" else 16)
    return int(text, 10)


def _core_float(loader, node) -> float:
    text = loader.construct_scalar(node).lower()
    return float(text.replace(".inf", "inf").replace(".nan", "nan"))


_StrictLoader.add_constructor("tag:yaml.org,2002:int", _core_int)
_StrictLoader.add_constructor("tag:yaml.org,2002:float", _core_float)


def load_yaml(text: str):
    """``yaml.safe_load``, but a key given twice in a mapping is a ``yaml.YAMLError``, and
    plain scalars are read by YAML 1.2's core schema (``1e-9`` a float, ``010`` ten, ``on`` and
    ``1:30`` strings), not PyYAML's YAML 1.1: scene files, hyperparameter files and the CLI's
    ``--env-kwargs`` are read with it."""
    return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 (a SafeLoader)


def read_scene(source: str | Path) -> Any:
    """The raw (unvalidated) data of a scene given as a string or path: a path to a YAML file, a
    packaged scene's name (``"rod_control"``: :func:`packaged_scenes`) or YAML text.

    A string without a newline is a path when it ends in ``.yaml``/``.yml`` or names an existing
    file, a packaged scene's name when it is one bare word, else YAML text.

    Raises:
        SceneError: a missing file (with where relative paths start and the packaged scenes),
            a file that holds no mapping (an empty one included), an unknown name (with the
            packaged scenes), or text that is not YAML.
    """
    text = str(source)
    if isinstance(source, str) and not text.strip():
        # (Path("") is the working directory: "'' is not a file" named no cause)
        raise SceneError(f"scene: an empty string; give a packaged scene's name "
                         f"{packaged_scenes()}, a YAML file's path, YAML text or a dict")
    path = Path(text)
    from_file = False
    if isinstance(source, Path) or names_yaml_file(text) or "\n" not in text and \
            is_path(path, "exists"):
        if not is_path(path, "is_file"):
            problem = "is not a file" if is_path(path, "exists") else "does not exist"
            raise SceneError(f"scene: {text!r} {problem} (relative paths start at "
                             f"{str(Path.cwd())!r}; a packaged scene loads by its name from "
                             f"anywhere: {packaged_scenes()})")
        text = path.read_text()
        from_file = True
    elif isinstance(source, str) and re.fullmatch(r"[A-Za-z0-9_]+", text):
        return packaged_scene(text)
    try:
        data = load_yaml(text)
    except yaml.YAMLError as exc:
        raise SceneError(f"scene: not valid YAML: {exc}") from None
    if from_file and not isinstance(data, dict):
        # an empty file (a sweep's script cut short) read as None meant "no scene given", and
        # an env then simulated its packaged scene instead
        what = "is empty" if data is None else f"holds a {type(data).__name__}"
        raise SceneError(f"scene: the file {str(path)!r} {what}: a scene file must be a mapping of "
                         f"scene fields (table, effects, solver, materials, bodies)")
    if not from_file and "\n" not in text.strip() and not isinstance(data, dict):
        # one line given as the scene, no mapping: a mistyped path or name
        raise SceneError(f"scene: {text!r} is neither a file, a packaged scene's name nor YAML "
                         f"of a scene (relative paths start at {str(Path.cwd())!r}; packaged: "
                         f"{packaged_scenes()})")
    return data


def names_yaml_file(text: Any) -> bool:
    """Whether ``text`` is a string :func:`read_scene` reads as a YAML file's path whether the
    file exists or not: one line ending in ``.yaml``/``.yml``."""
    return isinstance(text, str) and "\n" not in text and \
        Path(text).suffix.lower() in (".yaml", ".yml")


def is_path(path: Path, test: str) -> bool:
    """``path.exists()`` / ``path.is_file()`` (``test``), False where the OS refuses the name:
    a one-line YAML scene longer than a file name may be (255 bytes) raised ENAMETOOLONG."""
    try:
        return getattr(path, test)()
    except OSError:
        return False


def load_scene(source: str | Path | dict[str, Any] | Scene) -> Scene:
    """Load and validate a scene.

    Args:
        source: a packaged scene's name (``"rod_control"``), a path to a YAML file, a YAML
            string (:func:`read_scene`), a dict, or an existing :class:`Scene`.

    Raises:
        SceneError: naming the first invalid fields and what is allowed.
    """
    if isinstance(source, Scene):
        return source
    data = read_scene(source) if isinstance(source, (str, Path)) else source
    if not isinstance(data, dict):
        raise SceneError(f"scene must be a mapping of fields, got {type(data).__name__}")
    try:
        return Scene.model_validate(data)
    except ValidationError as exc:
        raise SceneError(_format_error(exc)) from None


def solver_over(scene: Any, given: Any) -> ExactSolver | FixedSolver | PymunkSolver:
    """A ``solver`` argument over a scene's solver block (``World``'s and the envs'): a mode
    name or dict of the scene's mode overrides the keys it gives and keeps the scene's others
    (``{"mode": "exact", "tolerance": 1e-10}`` on a scene with ``settle_substep: 1e-5`` keeps
    it, where it went back to 1e-3 s); a block of another mode, or a solver model, replaces the
    scene's (whose keys belong to its own mode). ``scene``: a solver model, or a scene's block
    as written (a dict, a mode name, or None for the default exact solver)."""
    if isinstance(scene, (ExactSolver, FixedSolver, PymunkSolver)):
        scene = scene.model_dump()
    scene = {"mode": scene} if isinstance(scene, str) else dict(scene or {"mode": "exact"})
    block = {"mode": given} if isinstance(given, str) else given
    if isinstance(block, dict) and block.get("mode") == scene.get("mode"):
        block = {**scene, **block}
    return validate_solver(block)


def validate_solver(solver: Any) -> ExactSolver | FixedSolver | PymunkSolver:
    """Validate a solver block given as a dict (``{"mode": "fixed", "substeps": 8}``) or model."""
    if isinstance(solver, (ExactSolver, FixedSolver, PymunkSolver)):
        return solver
    if isinstance(solver, str):
        solver = {"mode": solver}
    try:
        return Scene.model_validate(
            {"solver": solver, "bodies": [{"name": "x", "shape": "disk", "radius": 1, "mass": 1}]}
        ).solver
    except ValidationError as exc:
        raise SceneError(_format_error(exc)) from None
