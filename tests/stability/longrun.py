"""Long runs: a walled table with several bodies at e = 1, mu = 0, stepped for a long time.

Kinetic energy is the conserved quantity (cushions are static: they exchange momentum with the
bodies, so linear and angular momentum are *not* conserved and are not reported as drift). The
run reports, over every element and every step: the worst relative energy drift, escapes (a body
whose centre leaves the table), the deepest overlap, NaN/inf, and the cost (events, settled
steps). ``B`` copies with randomised velocities are stepped at once (``World(batch_size=B)``), so
``steps x B`` element-steps are cheap.

    python -m tests.stability.longrun --steps 1000000 --batch 1
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from spinstrike import physics

__all__ = ["SCENE", "run"]

#: three pucks and a rod on a walled table, elastic and frictionless
SCENE = {
    "table": {"size": [1.2, 0.8]},
    "effects": ["rotation", "walls"],
    "materials": {"restitution": 1.0, "friction": 0.0},
    "bodies": [
        {"name": "p0", "shape": "disk", "radius": 0.04, "mass": 0.05, "position": [-0.4, 0.2]},
        {"name": "p1", "shape": "disk", "radius": 0.03, "mass": 0.02, "position": [0.0, -0.25]},
        {"name": "p2", "shape": "disk", "radius": 0.05, "mass": 0.3, "position": [0.4, 0.15]},
        {"name": "rod", "shape": "rod", "length": 0.3, "thickness": 0.02, "mass": 0.1,
         "position": [0.0, 0.1], "angle": 0.3},
    ],
}


def run(steps: int, batch: int = 1, dt: float = 0.01, seed: int = 0,
        check_every: int = 1) -> dict:
    """Step ``batch`` copies ``steps`` times; return the worst numbers (see module docstring)."""
    world = physics.World(SCENE, batch_size=batch)
    rng = np.random.default_rng(seed)
    n = world.n_bodies
    world.set_state(velocities=rng.uniform(-2.0, 2.0, (batch, n, 2)),
                    omegas=rng.uniform(-10.0, 10.0, (batch, n)))
    e0 = world.kinetic_energy().copy()
    hw = world.table_half_size[:, None, :]
    worst = dict(energy_drift=0.0, escapes=0, overlap=0.0, nonfinite=0, contacts=0,
                 max_events=0, settled_steps=0)
    escaped = np.zeros(batch, dtype=bool)
    start = time.perf_counter()
    for k in range(steps):
        c = world.step(dt)
        ls = world.last_step
        worst["contacts"] += int(ls.contacts.sum())
        worst["max_events"] = max(worst["max_events"], int(ls.events.max()))
        worst["settled_steps"] += int(ls.fallback.sum())
        del c
        if (k + 1) % check_every and k + 1 != steps:
            continue
        state = world.get_state()["state"]
        finite = np.isfinite(state).all(axis=(1, 2))
        worst["nonfinite"] = int((~finite).sum())
        if not finite.all():
            break
        drift = np.abs(world.kinetic_energy() - e0) / e0
        worst["energy_drift"] = max(worst["energy_drift"], float(drift.max()))
        outside = (np.abs(world.state.positions) > hw).any(axis=(1, 2))
        escaped |= outside
        worst["escapes"] = int(escaped.sum())
        worst["overlap"] = max(worst["overlap"], float(-min(world.gaps().min(), 0.0)))
    worst.update(steps=steps, batch=batch, element_steps=steps * batch, dt=dt,
                 simulated_time=steps * dt,
                 seconds=round(time.perf_counter() - start, 2))
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--batch", type=int, default=1)
    parser.add_argument("--dt", type=float, default=0.01)
    parser.add_argument("--check-every", type=int, default=1)
    args = parser.parse_args()
    out = run(args.steps, args.batch, args.dt, check_every=args.check_every)
    print(json.dumps(out, indent=1))
    if out["nonfinite"] or out["escapes"] or not math.isfinite(out["energy_drift"]):
        raise SystemExit(1)


if __name__ == "__main__":
    main()
