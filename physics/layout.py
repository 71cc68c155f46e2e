"""Column layout of the packed per-element arrays the kernels work on.

The world keeps its state in one float64 array ``[B, N, 6]`` and exposes named views of it
(``positions[B, N, 2]``, ``angles[B, N]``, ``velocities[B, N, 2]``, ``omegas[B, N]``); the kernels
read the packed rows. Per-body parameters live in ``[B, N, 6]`` the same way.
"""

# state columns
X, Y, ANGLE, VX, VY, OMEGA = 0, 1, 2, 3, 4, 5
STATE_COLUMNS = 6

# parameter columns
INV_MASS, INV_INERTIA, RADIUS, HALF_LENGTH, FRICTION_DECEL, SPIN_DECEL = 0, 1, 2, 3, 4, 5
PARAM_COLUMNS = 6

# pair material columns
RESTITUTION, FRICTION = 0, 1

# time-of-impact outcomes
NONE, CONTACT, CHECKPOINT = 0, 1, 2

# per-element statistics columns (world.last_step.stats)
STAT_EVENTS, STAT_ITERATIONS, STAT_FALLBACK, STAT_CONTACTS, STAT_SUBSTEPS = 0, 1, 2, 3, 4
STAT_COLUMNS = 5

# ---------------------------------------------------------------------------------------------
# Packed buffers. A world keeps all its kernel arrays as named views into one float64 and one
# int64 buffer, so a step calls its kernel with two arguments (numba unboxes every array
# argument on every call: ~0.2 us each). The int buffer starts with a header: sizes, then the
# offset of each field in its buffer; ``solvers.unpack`` rebuilds the views inside the kernel.
# ---------------------------------------------------------------------------------------------

#: header slots: batch size, bodies, pairs, stored contacts per element, stat columns
H_B, H_N, H_P, H_M, H_C = 0, 1, 2, 3, 4
#: float fields, in buffer order, and their shapes in terms of (B, N, P, M)
FLOAT_FIELDS = ("state", "params", "forces", "hw", "materials", "crec", "toi", "fcfg", "time")
#: int fields
INT_FIELDS = ("pair_a", "pair_b", "cpair", "stats", "kind", "changed", "icfg")
#: header slot of the first float field's offset (the rest follow), and of the int fields'
H_FLOAT = 8
H_INT = H_FLOAT + len(FLOAT_FIELDS)
HEADER = H_INT + len(INT_FIELDS) + 1

#: contact record columns (``crec``): time, point x, y, normal x, y, impulse, tangent impulse
REC_TIME, REC_PX, REC_PY, REC_NX, REC_NY, REC_J, REC_JT = 0, 1, 2, 3, 4, 5, 6
REC_COLUMNS = 7

#: solver configuration slots (``fcfg`` floats, ``icfg`` ints)
CF_DT, CF_TOL, CF_ZENO_SPEED, CF_SETTLE = 0, 1, 2, 3
FCFG_SIZE = 4
CI_MAX_EVENTS, CI_MAX_ITERATIONS, CI_ZENO_IMPACTS, CI_ROTATION = 0, 1, 2, 3
CI_CONTACT_FRICTION, CI_TABLE_FRICTION, CI_SUBSTEPS, CI_ITERATIONS = 4, 5, 6, 7
ICFG_SIZE = 8


def field_shapes(B: int, N: int, P: int, M: int) -> dict[str, tuple[int, ...]]:
    """Shape of every packed field."""
    return {"state": (B, N, STATE_COLUMNS), "params": (B, N, PARAM_COLUMNS), "forces": (B, N, 2),
            "hw": (B, 2), "materials": (B, P, 2), "crec": (B, M, REC_COLUMNS), "toi": (B, P),
            "fcfg": (FCFG_SIZE,), "pair_a": (P,), "pair_b": (P,), "cpair": (B, M),
            "stats": (B, STAT_COLUMNS), "kind": (B, P), "changed": (B, N),
            "icfg": (ICFG_SIZE,), "time": (B,)}
