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
