"""SpinStrike physics: the seed note's rotating-body impulse model as an exact, batched 2D engine.

Public API::

    scene = physics.load_scene("rod_control")   # a packaged scene, a YAML path, a dict or text
    world = physics.World(scene, batch_size=B, solver=None)         # solver overrides the scene
    contacts = world.step(dt)                                       # flat arrays, batch index
    world.state.positions, .angles, .velocities, .omegas            # [B, N, 2] / [B, N]: live
    world.set_state(...), world.set_body(...), world.set_force(...), world.index("rod")
    with world.edit(env) as e: ...                                  # several changes, one check
    snap = world.get_state(); world.restore(snap, env=None)         # checkpoints (copies)
    world.load_element(other_world, b, env=[i])                     # one element of another
    world.kinetic_energy(), .momentum(), .angular_momentum()        # [B] / [B, 2] / [B]
    world.last_step, world.watch("mallet", "rod"), world.gaps()     # step statistics
    physics.SOLVERS, physics.EFFECTS                                # the names a scene may use

``world.state``'s arrays are live read-only views (copy them to keep a value); contacts and
snapshots are copies.

Compiled env kernels run the world's own element step through ``physics.kernels`` and
``world.run`` (see ``docs/design.md``).
"""

from spinstrike.physics.edit import WorldEdit
from spinstrike.physics.effects import EFFECTS, Effect
from spinstrike.physics.scene import (
    SOLVERS,
    WALL_NAMES,
    Body,
    ExactSolver,
    FixedSolver,
    PymunkSolver,
    Scene,
    SceneError,
    load_scene,
    packaged_scenes,
)
from spinstrike.physics.world import (
    Buffers,
    Contacts,
    SimulationError,
    State,
    StepStats,
    World,
)

__all__ = [
    "EFFECTS",
    "SOLVERS",
    "WALL_NAMES",
    "Body",
    "Buffers",
    "Contacts",
    "Effect",
    "ExactSolver",
    "FixedSolver",
    "PymunkSolver",
    "Scene",
    "SceneError",
    "SimulationError",
    "State",
    "StepStats",
    "World",
    "WorldEdit",
    "load_scene",
    "packaged_scenes",
]
