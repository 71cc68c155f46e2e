"""Golden trajectories: the physics before an optimisation, to compare after it bit for bit.

    python -m tests.physics.golden --write    # (re)record tests/physics/data/golden.npz

Re-record only for an intended change of the physics, and say so in the commit; a speed-up must
leave every number here unchanged (``tests/physics/test_golden.py``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from spinstrike import physics
from spinstrike.envs.config import load_packaged_scene

PATH = Path(__file__).parent / "data" / "golden.npz"
STEPS = 120
DT = 0.02


def _three_bodies() -> dict:
    return {"table": {"size": [1.2, 0.8], "friction": 0.05},
            "effects": ["rotation", "walls", "contact_friction", "table_friction"],
            "materials": {"restitution": 0.8, "friction": 0.3},
            "bodies": [
                {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1},
                {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
                 "position": [-0.3, 0.2]},
                {"name": "post", "shape": "disk", "radius": 0.02, "static": True,
                 "position": [0.3, -0.2]},
                {"name": "arm", "shape": "rod", "length": 0.2, "thickness": 0.01, "mass": 0.2,
                 "pivot": True, "position": [0.35, 0.2]},
                {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.3, "driven": True,
                 "position": [-0.4, -0.2]}]}


def _cradle() -> dict:
    bodies = [{"name": f"d{k}", "shape": "disk", "radius": 0.03, "mass": 0.05,
               "position": [0.06 * k, 0.0]} for k in range(5)]
    bodies[0]["position"] = [-0.3, 0.0]
    bodies[0]["velocity"] = [2.0, 0.0]
    return {"effects": ["rotation"], "bodies": bodies}


def scenarios() -> dict[str, tuple[dict, dict | None]]:
    """name -> (scene, solver override)."""
    return {
        "rod_control": (load_packaged_scene("rod_control"), None),
        "puck_control": (load_packaged_scene("puck_control"), None),
        "three_bodies": (_three_bodies(), None),
        "three_bodies_fixed": (_three_bodies(), {"mode": "fixed", "substeps": 8}),
        "three_bodies_coarse": (_three_bodies(), {"mode": "exact", "tolerance": 1e-4}),
        "cradle": (_cradle(), None),
    }


def run(scene: dict, solver: dict | None, batch: int = 6) -> dict[str, np.ndarray]:
    world = physics.World(scene, batch_size=batch, solver=solver)
    rng = np.random.default_rng(7)
    n = world.n_bodies
    movable = ~(world.static | world.pivot)
    vel = rng.uniform(-2.5, 2.5, (batch, n, 2)) * movable[None, :, None]
    om = rng.uniform(-15, 15, (batch, n)) * (~world.static)[None, :] if world.rotation else None
    world.set_state(velocities=vel, omegas=om)
    driven = np.flatnonzero(world.driven)
    states, impulses, counts = [], [], []
    for _ in range(STEPS):
        for i in driven:
            world.set_force(int(i), rng.uniform(-6, 6, (batch, 2)))
        c = world.step(DT)
        states.append(world.get_state()["state"].copy())
        impulses.append(np.bincount(c.batch, weights=c.impulse, minlength=batch))
        counts.append(world.last_step.contacts.copy())
    return {"states": np.array(states), "impulses": np.array(impulses),
            "counts": np.array(counts)}


def record() -> dict[str, np.ndarray]:
    out = {}
    for name, (scene, solver) in scenarios().items():
        for key, value in run(scene, solver).items():
            out[f"{name}/{key}"] = value
    return out


if __name__ == "__main__":
    p = argparse.ArgumentParser()
    p.add_argument("--write", action="store_true")
    args = p.parse_args()
    data = record()
    if args.write:
        PATH.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(PATH, **data)
        print(f"wrote {PATH} ({len(data)} arrays)")
    else:
        print({k: v.shape for k, v in data.items()})
