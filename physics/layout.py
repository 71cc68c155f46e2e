"""The one declaration of every packed layout the compiled kernels read (``docs/design.md`` §3).

A world keeps all its kernel arrays as named views into one float64 and one int64 buffer, so a
kernel call takes two arguments (numba unboxes every array argument on every call: ~0.2 us
each). Each packed row (a body's state, its parameters, a contact record, the solver's
configuration, a buffer's fields...) is a :class:`Table`: its columns are declared once, here or,
for the envs' own rows, in ``envs/fast.py``, and the module-level column constants the kernels
index with are unpacked from it (``X, Y, ANGLE, VX, VY, OMEGA = STATE``). numba freezes those
globals into the compiled code as plain offsets.

``tests/physics/test_layout.py`` walks every table: column names are unique, each constant
equals its column (``PREFIX + NAME.upper()``), and no kernel addresses a packed column with a
literal number.
"""

from __future__ import annotations

from collections.abc import Iterator

__all__ = ["TABLES", "Table", "field_shapes"]

#: every table declared, by name (what the layout test walks)
TABLES: dict[str, Table] = {}


class Table:
    """Named columns of a packed row, declared once.

    Args:
        name: what a row is (unique among tables).
        columns: column names in row order; a ``(name, width)`` pair declares a block of
            ``width`` consecutive columns (e.g. an observation inside a task row).
        prefix: prefix of the module constants unpacked from the table (``"REC_"`` gives
            ``REC_TIME``, ...); the test checks each constant against its column.

    Iterating gives each column's offset in order; ``len`` is the row's width.
    """

    def __init__(self, name: str, *columns: str | tuple[str, int], prefix: str = "") -> None:
        if name in TABLES:
            raise ValueError(f"layout table {name!r} is declared twice")
        self.name = name
        self.prefix = prefix
        self.offsets: dict[str, int] = {}
        self.widths: dict[str, int] = {}
        offset = 0
        for column in columns:
            key, width = (column, 1) if isinstance(column, str) else column
            if key in self.offsets:
                raise ValueError(f"layout table {name!r}: column {key!r} is declared twice")
            if width < 1:
                raise ValueError(f"layout table {name!r}: column {key!r} has width {width}")
            self.offsets[key] = offset
            self.widths[key] = width
            offset += width
        self.size = offset
        TABLES[name] = self

    def __iter__(self) -> Iterator[int]:
        return iter(self.offsets.values())

    def __len__(self) -> int:
        return self.size

    def __getitem__(self, column: str) -> int:
        return self.offsets[column]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.offsets)

    def constant(self, column: str) -> str:
        """Name of the module constant holding ``column``'s offset."""
        return self.prefix + column.upper()

    def __repr__(self) -> str:
        return f"Table({self.name!r}, {', '.join(self.offsets)})"


# -- a body's state and parameters ---------------------------------------------------------------

#: state row of a body ``[B, N, .]``: m, m, rad (CCW from +x), m/s, m/s, rad/s (CCW > 0)
STATE = Table("state", "x", "y", "angle", "vx", "vy", "omega")
X, Y, ANGLE, VX, VY, OMEGA = STATE
STATE_COLUMNS = len(STATE)

#: parameter row of a body ``[B, N, .]``, derived from the scene's values by ``World``:
#: 1/kg, 1/(kg m^2), m, m, m/s^2 (cloth deceleration), rad/s^2 (cloth spin-down)
PARAMS = Table("params", "inv_mass", "inv_inertia", "radius", "half_length", "friction_decel",
               "spin_decel")
INV_MASS, INV_INERTIA, RADIUS, HALF_LENGTH, FRICTION_DECEL, SPIN_DECEL = PARAMS
PARAM_COLUMNS = len(PARAMS)

#: applied force on a body ``[B, N, .]``, N
FORCE = Table("force", "fx", "fy")
FX, FY = FORCE
FORCE_COLUMNS = len(FORCE)

#: a body's rest on the cushions ``[B, N, .]`` (``solvers._rest_on_cushions``), per axis: the
#: force component a cushion holds back (N), when the rest began (s), the impulse booked at
#: its start (N s: the normal velocity it zeroed, times the mass) and the body-cushion pair
#: (its index, as a float); zero between steps
REST = Table("cushion rest", "fx", "fy", "tx", "ty", "jx", "jy", "px", "py", prefix="REST_")
REST_FX, REST_FY, REST_TX, REST_TY, REST_JX, REST_JY, REST_PX, REST_PY = REST
REST_COLUMNS = len(REST)

#: table half size ``[B, .]``, m (inf when unbounded)
HALF = Table("table half size", "half_w", "half_h")
HALF_W, HALF_H = HALF
HALF_COLUMNS = len(HALF)

#: material of a contact pair ``[B, P, .]``
MATERIAL = Table("material", "restitution", "friction")
RESTITUTION, FRICTION = MATERIAL
MATERIAL_COLUMNS = len(MATERIAL)

# -- what a step reports -------------------------------------------------------------------------

#: contact record ``crec [B, M + 1, .]``: s, m, m, unit normal (a to b), N s, N s (along
#: (-ny, nx)); row M holds the sums of ``j`` and ``jt`` over the contacts beyond the M records
#: (a strike of a thousand tiny bounces: its total impulse, where the records stop)
#: (``held``: 1 for a held contact's record, a disk the exact solver held on a cushion over a
#: stretch of the step, ``solvers._end_rest``; 0 for an impact)
RECORD = Table("contact record", "time", "px", "py", "nx", "ny", "j", "jt", "held",
               prefix="REC_")
REC_TIME, REC_PX, REC_PY, REC_NX, REC_NY, REC_J, REC_JT, REC_HELD = RECORD
REC_COLUMNS = len(RECORD)
#: the column of row M (the sums row, which has no time) that holds the sum of ``j`` over every
#: contact of the watched pair in the step, stored in the records or not (``World.watch``,
#: ``last_step.watched_impulse``)
REC_WATCHED_J = REC_TIME

#: per-element statistics of the last step (``world.last_step``); ``watch`` is no statistic but
#: the pair (index, -1: none) whose contacts ``watched`` counts, every one of them, stored in
#: the contact records or not (``World.watch``), kept from step to step
STATS = Table("statistics", "events", "iterations", "fallback", "contacts", "substeps",
              "watch", "watched", prefix="STAT_")
(STAT_EVENTS, STAT_ITERATIONS, STAT_FALLBACK, STAT_CONTACTS, STAT_SUBSTEPS, STAT_WATCH,
 STAT_WATCHED) = STATS
STAT_COLUMNS = len(STATS)

#: what the ``fallback`` statistic holds (values, not columns, the worse the higher): the step
#: ran as designed; the exact solver's sweeps did not converge and the block solve of the jam,
#: which has no friction, took pairs with contact friction (their friction after it is lost);
#: the exact solver settled the rest of the step with fixed substeps; it did, but needed more
#: than its cap of substeps, so the no-tunnelling bound did not hold; the state is no longer
#: finite (checked after every step: ``World.step`` raises ``SimulationError``); the element
#: was not stepped, its travel in the step beyond what float64 resolves on its walled table
#: (``kernels.TRAVEL_LIMIT``: ``World.step`` raises ``SimulationError`` too)
FALLBACK = Table("fallback", "none", "jammed", "settled", "capped", "nonfinite", "unresolved",
                 prefix="FALLBACK_")
(FALLBACK_NONE, FALLBACK_JAMMED, FALLBACK_SETTLED, FALLBACK_CAPPED, FALLBACK_NONFINITE,
 FALLBACK_UNRESOLVED) = FALLBACK

#: outcome of a time-of-impact search (values, not columns)
SEARCH = Table("search outcome", "none", "contact", "checkpoint")
NONE, CONTACT, CHECKPOINT = SEARCH

# -- solver configuration ------------------------------------------------------------------------

#: float configuration ``fcfg``: step length (s), contact tolerance (m), resting-bounce speed
#: (m/s), longest settling substep (s), overlap beyond which a placement is refused (m)
FCFG = Table("solver floats", "dt", "tol", "zeno_speed", "settle", "overlap_tol", prefix="CF_")
CF_DT, CF_TOL, CF_ZENO_SPEED, CF_SETTLE, CF_OVERLAP_TOL = FCFG
FCFG_SIZE = len(FCFG)

#: int configuration ``icfg``: the exact solver's caps, the effects' flags (fixed when the world
#: is built), the fixed solver's substeps and sweeps, and which solver steps (``fixed`` 1: fixed)
ICFG = Table("solver ints", "max_events", "max_iterations", "zeno_impacts", "rotation",
             "contact_friction", "table_friction", "substeps", "iterations", "fixed",
             prefix="CI_")
(CI_MAX_EVENTS, CI_MAX_ITERATIONS, CI_ZENO_IMPACTS, CI_ROTATION, CI_CONTACT_FRICTION,
 CI_TABLE_FRICTION, CI_SUBSTEPS, CI_ITERATIONS, CI_FIXED) = ICFG
ICFG_SIZE = len(ICFG)

# -- the exact solver's calendar for many bodies (``physics.calendar``) ---------------------------

#: a body's swept box over the rest of a step ``[N, .]``: m, its reach and the tolerance included
BOX = Table("swept box", "xmin", "xmax", "ymin", "ymax", prefix="BOX_")
BOX_XMIN, BOX_XMAX, BOX_YMIN, BOX_YMAX = BOX
BOX_COLUMNS = len(BOX)

#: the counters that open an element's calendar int row: pairs in the heap, pairs on the watch
#: list, and a running event stamp (never reset: it marks pairs re-predicted at an event)
CALENDAR = Table("calendar counters", "heap_size", "watch_size", "stamp", prefix="CAL_")
CAL_HEAP_SIZE, CAL_WATCH_SIZE, CAL_STAMP = CALENDAR
CAL_COLUMNS = len(CALENDAR)

#: levels of the ``jam`` compile-time flag (``kernels.FLAGS``, values, not columns): one contact
#: pair (contacts cannot jam), one pair with contact friction (a frictional contact can jam, a
#: frictionless one is held: both compiled, the pair's friction picks at run time), contacts can
#: jam (two pairs or more), and can jam among many bodies (from ``CALENDAR_BODIES``: the exact
#: solver uses its broadphase and event calendar, and its settling and the fixed solver sweep
#: pair lists made in the calendar's rows). The hold is compiled below ``can_jam``, the jam block
#: solve from ``one_pair_friction`` on.
LEVEL = Table("contact level", "one_pair", "one_pair_friction", "can_jam", "many_bodies",
              prefix="LEVEL_")
LEVEL_ONE_PAIR, LEVEL_ONE_PAIR_FRICTION, LEVEL_CAN_JAM, LEVEL_MANY_BODIES = LEVEL

#: bodies from which an exact world uses the broadphase and the event calendar, and an exact or
#: fixed world's substeps sweep only the pairs close enough to touch
CALENDAR_BODIES = 8


def calendar_widths(N: int, P: int) -> tuple[int, int]:
    """(float, int) width of an element's calendar rows: the float row holds each pair's
    earliest time within ``tol`` (``[P]``) then the bodies' swept boxes (``[N, BOX_COLUMNS]``);
    the int row the counters (``CALENDAR``), then the heap of pairs, each pair's heap position
    plus one, the watch list, each pair's stamp, whether each pair is on the watch list
    (``[P]`` each) and the bodies' order (``[N]``)."""
    return P + N * BOX_COLUMNS, CAL_COLUMNS + 5 * P + N


# -- the two packed buffers ----------------------------------------------------------------------

#: the int buffer's header: sizes (batch, bodies, pairs, stored contacts per element), then the
#: offset of each float field in the float buffer and of each int field in the int buffer
FLOAT_FIELDS = Table("float fields", "state", "params", "forces", "half", "materials", "crec",
                     "toi", "fcfg", "time", "calf", "rest", prefix="F_")
(F_STATE, F_PARAMS, F_FORCES, F_HALF, F_MATERIALS, F_CREC, F_TOI, F_FCFG, F_TIME,
 F_CALF, F_REST) = FLOAT_FIELDS
INT_FIELDS = Table("int fields", "pair_a", "pair_b", "cpair", "stats", "kind", "changed", "icfg",
                   "cali", "pair_index", prefix="I_")
(I_PAIR_A, I_PAIR_B, I_CPAIR, I_STATS, I_KIND, I_CHANGED, I_ICFG, I_CALI,
 I_PAIR_INDEX) = INT_FIELDS
HEADER = Table("int header", "b", "n", "p", "m", "calendar", ("float", len(FLOAT_FIELDS)),
               ("int", len(INT_FIELDS)), prefix="H_")
H_B, H_N, H_P, H_M, H_CALENDAR, H_FLOAT, H_INT = HEADER
HEADER_SIZE = len(HEADER)


def field_shapes(B: int, N: int, P: int, M: int,
                 calendar: bool = False) -> dict[str, tuple[int, ...]]:
    """Shape of every packed field for B elements of N bodies, P contact pairs and M stored
    contacts per element (``solvers.unpack`` rebuilds the same views inside the kernels).

    ``calendar``: the world steps with the exact solver's calendar, or the fixed solver on its
    pair lists (many bodies), which needs
    the calendar rows ``calf``, ``cali`` (:func:`calendar_widths`) and the pair index
    ``[N, N + 4]`` (the pair of two bodies, or of a body and cushion w at column N + w; -1:
    none); otherwise they are empty. ``rest``: a body's rests on the cushions during a step
    (:data:`REST`, ``solvers._rest_on_cushions``; zero between steps)."""
    cf, ci = calendar_widths(N, P) if calendar else (0, 0)
    rows, cols = (N, N + 4) if calendar else (0, 0)
    return {"state": (B, N, STATE_COLUMNS), "params": (B, N, PARAM_COLUMNS),
            "forces": (B, N, FORCE_COLUMNS), "half": (B, HALF_COLUMNS),
            "materials": (B, P, MATERIAL_COLUMNS), "crec": (B, M + 1, REC_COLUMNS),
            "toi": (B, P),
            "fcfg": (FCFG_SIZE,), "time": (B,), "calf": (B, cf), "rest": (B, N, REST_COLUMNS),
            "pair_a": (P,), "pair_b": (P,), "cpair": (B, M), "stats": (B, STAT_COLUMNS),
            "kind": (B, P), "changed": (B, N), "icfg": (ICFG_SIZE,), "cali": (B, ci),
            "pair_index": (rows, cols)}
