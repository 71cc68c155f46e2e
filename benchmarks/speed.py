"""Throughput, measured side by side with its peers in one run.

    python -m spinstrike.benchmarks.speed          # everything (minutes): docs/speed.md + plots
    python -m spinstrike.benchmarks.speed --quick  # smaller batches and fewer repetitions

What is measured (env-steps per second unless said otherwise; fastest of the repetitions):

* the native vector env of ``RodSpinControl-v0`` (exact solver) at 4096 envs, random actions and a
  batched chase-and-hit policy that makes contact, beside a ``SyncVectorEnv`` of the same env on
  the pymunk backend and Gymnasium's own ``CartPole-v1`` vector env (1024 envs, no collisions);
* the single env through ``gym.make`` (all default wrappers), exact and pymunk, and Chipmunk
  alone on the pymunk env's own space under the same forces (no SpinStrike code in the loop);
* the one-strike envs: strikes per second, single and vector;
* the share of SB3 PPO's wall time spent in the env (native ``VecEnv`` adapter);
* how the cost grows with the batch size (1..65536) and with the number of bodies (2..256
  pucks, one world, beside raw pymunk at 1 and 10 substeps: ``--section bodies`` runs that part
  alone).

Contacts per step are reported beside every figure, since free flight is cheap and contacts are
not.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import platform
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

from spinstrike import (
    envs,  # noqa: F401
    physics,
)
from spinstrike.benchmarks import cpu_model, out_dir
from spinstrike.benchmarks import startup as startup_study

__all__ = ["main"]

CONTROL = "SpinStrike/RodSpinControl-v0"


def _best(fn, repeats: int) -> float:
    """Fastest wall time of ``repeats`` calls of ``fn`` (s)."""
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def _best_uncounted(run, repeats: int) -> float:
    """Fastest of ``repeats`` calls of ``run()`` after one untimed ``run(count=True)``, the only
    one that counts contacts: the first read of ``world.last_step`` after a step builds its
    stats (~5-10 us), which the timed loops charged to the env, half of a single exact env's
    step (walk W28b F2: 47.5 k steps/s timed so, 98.6 k without)."""
    run(count=True)
    return _best(run, repeats)


def chase_and_hit_batch(task, max_speed: float) -> np.ndarray:
    """The scripted chase-and-hit policy of ``agents.oracle.ChaseAndHit``, vectorised over a
    control task's batch (aim at 0.8 of the rod's half length, drive through it)."""
    w = task.world
    pm = w.state.positions[:, task.im]
    vm = w.state.velocities[:, task.im]
    pt = w.state.positions[:, task.it]
    phi = w.state.angles[:, task.it]
    u = np.stack([np.cos(phi), np.sin(phi)], 1)
    n = np.stack([-u[:, 1], u[:, 0]], 1)
    flip = ((pm - pt) * n).sum(1) < 0
    n[flip] *= -1
    aim = pt + 0.8 * w.half_length[:, task.it, None] * u
    contact = aim + n * (w.radius[:, task.it] + w.radius[:, task.im])[:, None]
    waypoint = contact + n * 0.06
    behind = ((pm - contact) * -n).sum(1) < -0.03
    near = np.sqrt(((pm - waypoint) ** 2).sum(1)) < 0.03
    force = (12.0 * (waypoint - pm) - vm) / max_speed
    norm = np.maximum(np.sqrt((force**2).sum(1, keepdims=True)), 1.0)
    force = force / norm
    force[behind & near] = -n[behind & near]
    return np.clip(force, -1, 1).astype(np.float32)


def _vector_rate(env_id: str, n: int, steps: int, repeats: int, policy: str = "random",
                 **kwargs) -> tuple[float, float]:
    """(env-steps/s, contacts per env-step) of the native vector env (SAME_STEP autoreset: one
    physics call per step, so the figures compare with earlier ones and with SB3's loop)."""
    kwargs.setdefault("autoreset_mode", gym.vector.AutoresetMode.SAME_STEP)
    vec = gym.make_vec(env_id, num_envs=n, **kwargs)
    vec.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, n, vec.single_action_space.shape[0])).astype(np.float32)
    contacts = [0]

    def run(count=False):
        for k in range(steps):
            if policy == "chase":
                a = chase_and_hit_batch(vec.task, vec.cfg.max_speed)
            else:
                a = actions[k]
            vec.step(a)
            if count:
                contacts[0] += int(vec.world.last_step.contacts.sum())

    best = _best_uncounted(run, repeats)  # its warm-up also compiles
    vec.close()
    return steps * n / best, contacts[0] / (steps * n)


def _sync_pymunk_rate(n: int, steps: int, repeats: int) -> tuple[float, float]:
    vec = gym.vector.SyncVectorEnv([lambda: gym.make(CONTROL, solver={"mode": "pymunk"})
                                    for _ in range(n)],
                                   autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    vec.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    contacts = [0]

    def run(count=False):
        for k in range(steps):
            vec.step(actions[k])
            if count:
                contacts[0] += sum(int(e.unwrapped.world.last_step.contacts.sum())
                                   for e in vec.envs)

    best = _best_uncounted(run, repeats)
    vec.close()
    return steps * n / best, contacts[0] / (steps * n)


def _chipmunk_alone_rate(steps: int, repeats: int) -> float:
    """Env-steps/s of Chipmunk alone on the scene of the pymunk backend's single env: the
    env's own ``Space`` (its bodies, thick cushions, cloth joints and per-pair callbacks, which
    fire at its ~0.2 contacts a step), stepped ``substeps`` times per env step under the mallet
    forces random actions set in the env, with no SpinStrike code in the loop: no observation,
    reward, write-back or checks. The floor of a pymunk user's own env of this scene (walk
    W29a F4: the 8x against the backend times mostly SpinStrike's Python around Chipmunk)."""
    env = gym.make(CONTROL, solver={"mode": "pymunk"})
    world = env.unwrapped.world
    forces = _recorded_forces(env, steps)
    best = math.inf
    for _ in range(repeats):
        env.reset(seed=0)  # a fresh space at the start of the same motion, untimed
        best = min(best, _replay_forces(world, forces))
    env.close()
    return steps / best


def _recorded_forces(env, steps: int) -> list:
    """The forces ``env`` (a single control env) sets on its world's bodies in ``steps`` env
    steps of random actions from ``reset(seed=0)``: per step, [N] (fx, fy)."""
    world = env.unwrapped.world
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    forces = []
    for _ in range(steps):
        env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
        forces.append([(float(f[0]), float(f[1])) for f in world.get_state()["forces"][0]])
    return forces


def _replay_forces(world, forces: list) -> float:
    """Step element 0's pymunk space as ``world.step`` does (``substeps`` calls of
    ``Space.step``, the driven bodies' forces set before each), one env step per row of
    ``forces`` ([N] (fx, fy)), and nothing else; seconds taken."""
    driven = [i for i in range(world.n_bodies) if world.driven[i]]
    n = int(world.solver.substeps)
    h = float(world.dt) / n
    space = world.backend.space(0)
    pairs = [(next(s.body for s in space.shapes if s.collision_type == i), i) for i in driven]
    t = time.perf_counter()
    for row in forces:
        for _ in range(n):
            for body, i in pairs:
                body.force = row[i]
            space.step(h)
    return time.perf_counter() - t


def _cartpole_rate(n: int, steps: int, repeats: int) -> float:
    vec = gym.make_vec("CartPole-v1", num_envs=n, vectorization_mode="vector_entry_point")
    vec.reset(seed=0)
    actions = np.random.default_rng(0).integers(0, 2, (steps, n))

    def run():
        for k in range(steps):
            vec.step(actions[k])

    run()
    return steps * n / _best(run, repeats)


def _single_rate(env_id: str, steps: int, repeats: int, policy: str = "random",
                 **kwargs) -> tuple[float, float]:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (steps, *env.action_space.shape)).astype(np.float32)
    contacts = [0]
    if policy == "chase":
        from spinstrike.agents.oracle import ChaseAndHit

        chase = ChaseAndHit()

    def run(count=False):
        obs = None
        for k in range(steps):
            a = chase(env, obs) if policy == "chase" else actions[k]
            obs, r, term, trunc, _ = env.step(a)
            if count:
                contacts[0] += int(env.unwrapped.world.last_step.contacts.sum())
            if term or trunc:
                obs, _ = env.reset()

    best = _best_uncounted(run, repeats)
    env.close()
    return steps / best, contacts[0] / steps


def _ppo_env_share(steps: int) -> float:
    """Share of PPO's wall time spent inside the env's step (native VecEnv adapter), with torch
    on one thread as ``spinstrike train`` runs it (``--torch-threads 1``): on torch's default
    (one a core) the share on a busy 2-core host fell 10-20x (0.005-0.008 against 0.08-0.09)."""
    import torch
    from stable_baselines3 import PPO

    from spinstrike.envs.sb3 import make_sb3_vec_env

    vec = make_sb3_vec_env(CONTROL, n_envs=16, seed=0)
    spent = [0.0]
    step_wait = vec.step_wait

    def timed():
        t = time.perf_counter()
        out = step_wait()
        spent[0] += time.perf_counter() - t
        return out

    vec.step_wait = timed
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        model = PPO("MlpPolicy", vec, n_steps=256, batch_size=512, device="cpu", seed=0)
        model.learn(4096)  # warm-up
        spent[0] = 0.0
        t = time.perf_counter()
        model.learn(steps, reset_num_timesteps=False)
        return spent[0] / (time.perf_counter() - t)
    finally:
        torch.set_num_threads(threads)


_STARTUP = """
import sys, time
t = time.perf_counter()
import gymnasium as gym, numpy as np
import spinstrike
env = gym.make(sys.argv[1])
env.reset(seed=0)
for k in range(1000):
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    if k == 0:
        first = time.perf_counter() - t
    if terminated or truncated:
        env.reset()
print(first, time.perf_counter() - t)
"""


def _startup_times(env_ids: list[str]) -> dict[str, tuple[float, float, float, float]]:
    """Per env id, seconds from a fresh interpreter's ``import`` to the first and the 1000th
    step of a single env: (cold first, cold 1000th, warm first, warm 1000th); cold with an empty
    kernel cache of its own (every kernel the env needs compiles), warm with it filled."""
    import subprocess
    import tempfile

    times = {}
    for env_id in env_ids:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, SPINSTRIKE_CACHE_DIR=cache, SPINSTRIKE_QUIET="1")
            row = []
            for _ in range(2):
                out = subprocess.run([sys.executable, "-c", _STARTUP, env_id], env=env,
                                     check=True, capture_output=True, text=True,
                                     cwd=tempfile.gettempdir())
                row += [float(x) for x in out.stdout.strip().splitlines()[-1].split()]
        times[env_id] = tuple(row)
    return times


def _many_pucks_scene(n_pucks: int) -> dict:
    """The bodies sweep's scene: n pucks (r = 0.02 m, m = 0.05 kg) on a grid over a walled
    1.2 x 0.8 m table, velocities uniform in [-1, 1] m/s per axis (seeded), e = 0.95."""
    side = math.ceil(math.sqrt(n_pucks))
    rng = np.random.default_rng(1)
    bodies = []
    for k in range(n_pucks):
        i, j = divmod(k, side)
        bodies.append({"name": f"p{k}", "shape": "disk", "radius": 0.02, "mass": 0.05,
                       "position": [-0.5 + (i + 0.5) * 1.0 / side,
                                    -0.35 + (j + 0.5) * 0.7 / side],
                       "velocity": rng.uniform(-1, 1, 2).tolist()})
    return {"table": {"size": [1.2, 0.8]}, "effects": ["rotation", "walls"],
            "materials": {"restitution": 0.95}, "bodies": bodies}


def _world_step_time(scene: dict, batch: int, steps: int, repeats: int) -> tuple[float, float]:
    """(seconds per world.step, contacts per element-step)."""
    world = physics.World(scene, batch_size=batch)
    world.step(0.02)
    counts = [0]

    def run(count=False):
        for _ in range(steps):
            world.step(0.02)
            if count:
                counts[0] += int(world.last_step.contacts.sum())

    best = _best_uncounted(run, repeats)
    return best / steps, counts[0] / (steps * batch)


#: the bodies sweep: pucks per scene, simulated steps of 0.02 s (from the scene's start)
BODIES = (2, 4, 8, 16, 32, 64, 128, 256)
BODY_STEPS = 50
#: runs of each in the bodies sweep, the fastest kept
BODY_REPEATS = 3


#: the bodies sweep's fixed-solver column: substeps per 0.02 s step (pymunk's 10-substep column)
FIXED_SUBSTEPS = 10


def _exact_pucks(n_pucks: int, steps: int, solver: dict | None = None) -> tuple[float, float]:
    """One world (B = 1) of the sweep's scene on the exact solver (or ``solver``), ``steps``
    steps of 0.02 s from its start: (CPU seconds per step, contacts per step). The kernels are
    compiled (and the step timed) on a separate world first."""
    scene = _many_pucks_scene(n_pucks)
    if solver is not None:
        scene["solver"] = solver
    physics.World(scene).step(0.02)  # compile
    world = physics.World(scene)
    contacts = 0
    t = time.process_time()
    for _ in range(steps):
        record = world.step(0.02)
        contacts += len(record.impulse) + int(record.dropped.sum())  # stored + not stored
    return (time.process_time() - t) / steps, contacts / steps


def _pymunk_pucks(n_pucks: int, steps: int, substeps: int) -> float:
    """Raw pymunk (one ``Space``, no SpinStrike code in the loop) on the sweep's scene:
    segment cushions, circle pucks, elasticity sqrt(0.95) on every shape (pymunk multiplies a
    pair's two), no friction; each 0.02 s step is ``substeps`` calls of ``Space.step``. CPU
    seconds per step."""
    import pymunk

    scene = _many_pucks_scene(n_pucks)
    hw, hh = 0.6, 0.4
    space = pymunk.Space()
    space.collision_slop = 0.0  # in metres: pymunk's 0.1 would be five puck radii
    e = math.sqrt(scene["materials"]["restitution"])
    walls = [((-hw, -hh), (hw, -hh)), ((hw, -hh), (hw, hh)), ((hw, hh), (-hw, hh)),
             ((-hw, hh), (-hw, -hh))]
    for a, b in walls:
        seg = pymunk.Segment(space.static_body, a, b, 0.0)
        seg.elasticity = e
        seg.friction = 0.0
        space.add(seg)
    for spec in scene["bodies"]:
        r, m = spec["radius"], spec["mass"]
        body = pymunk.Body(m, pymunk.moment_for_circle(m, 0.0, r))
        body.position = tuple(spec["position"])
        body.velocity = tuple(spec["velocity"])
        shape = pymunk.Circle(body, r)
        shape.elasticity = e
        shape.friction = 0.0
        space.add(body, shape)
    h = 0.02 / substeps
    t = time.process_time()
    for _ in range(steps):
        for _ in range(substeps):
            space.step(h)
    return (time.process_time() - t) / steps


def bodies_sweep(bodies=BODIES, steps: int = BODY_STEPS, repeats: int = BODY_REPEATS
                 ) -> list[tuple[int, float, float, float, float, float]]:
    """The bodies sweep, exact beside raw pymunk in the same run: per number of pucks,
    (pucks, exact s/step, contacts/step, pymunk 1 substep s/step, pymunk 10 substeps s/step,
    the fixed solver at ``FIXED_SUBSTEPS`` substeps s/step), CPU time (``time.process_time``),
    one world; each the fastest of ``repeats`` runs from the scene's start, the four taken in
    turn (a machine busy with other work slows one run, not all of them)."""
    rows = []
    fixed = {"mode": "fixed", "substeps": FIXED_SUBSTEPS}
    for n in bodies:
        t = p1 = p10 = f10 = math.inf
        for _ in range(repeats):
            t_run, c = _exact_pucks(n, steps)
            t = min(t, t_run)
            p1 = min(p1, _pymunk_pucks(n, steps, 1))
            p10 = min(p10, _pymunk_pucks(n, steps, 10))
            f10 = min(f10, _exact_pucks(n, steps, fixed)[0])
        rows.append((n, t, c, p1, p10, f10))
        per = f"{t / c * 1e6:10.1f}" if c > 0 else "         -"
        print(f"{n:4d} pucks: exact {t * 1e6:11.1f} us/step, {c:7.2f} contacts/step, {per} us/"
              f"contact; pymunk 1 substep {p1 * 1e6:8.1f}, 10 substeps {p10 * 1e6:8.1f} us/step;"
              f" fixed {FIXED_SUBSTEPS} substeps {f10 * 1e6:8.1f} us/step", flush=True)
    return rows


def _bodies_lines(rows, steps: int, load: float | None = None) -> list[str]:
    lines = ["## Cost against number of bodies", "",
             f"One world of N pucks (`_many_pucks_scene`: r = 0.02 m, m = 0.05 kg, e = 0.95, "
             f"|v| <= 1 m/s per axis, a grid on a walled 1.2 x 0.8 m table), {steps} steps of "
             "0.02 s from the scene's start, CPU time per step (the fastest of "
             f"{BODY_REPEATS} runs); raw pymunk (one `Space`, segment "
             "cushions, circles) on the same scene in the same run, at 1 and 10 substeps per "
             f"step, and SpinStrike's fixed solver at {FIXED_SUBSTEPS} substeps (its "
             "defaults otherwise: 4 impulse sweeps, one positional correction a substep). Run "
             "alone: `python -m spinstrike.benchmarks.speed --section bodies`"
             + (f" (this table: load average {load:.2f} at the start)" if load is not None
                else "") + ".", "",
             "| pucks | exact, µs/step | contacts/step | exact, µs per contact | pymunk 1 "
             "substep, µs/step | pymunk 10 substeps, µs/step | exact / pymunk 10 | fixed "
             f"{FIXED_SUBSTEPS} substeps, µs/step | fixed / pymunk 10 |",
             "|---|---|---|---|---|---|---|---|---|"]
    for n, t, c, p1, p10, f10 in rows:
        per = f"{t / c * 1e6:.1f}" if c > 0 else "-"
        lines.append(f"| {n} | {t * 1e6:.1f} | {c:.2f} | {per} | {p1 * 1e6:.1f} | "
                     f"{p10 * 1e6:.1f} | {t / p10:.2f} | {f10 * 1e6:.1f} | {f10 / p10:.2f} |")
    lines += ["", "![cost per step against number of bodies](speed_bodies.png)", ""]
    return lines


def _plot_bodies(path: Path, rows) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ns = [r[0] for r in rows]
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10, 3.8))
    ax.loglog(ns, [r[1] * 1e6 for r in rows], "o-", label="exact")
    ax.loglog(ns, [r[3] * 1e6 for r in rows], "s--", label="pymunk, 1 substep")
    ax.loglog(ns, [r[4] * 1e6 for r in rows], "^--", label="pymunk, 10 substeps")
    ax.loglog(ns, [r[5] * 1e6 for r in rows], "v-", label=f"fixed, {FIXED_SUBSTEPS} substeps")
    ax.set_xlabel("pucks")
    ax.set_ylabel("µs per step (CPU)")
    ax.set_title("one world, one 0.02 s step")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    with_c = [r for r in rows if r[2] > 0]
    bx.semilogx([r[0] for r in with_c], [r[1] / r[2] * 1e6 for r in with_c], "o-")
    bx.set_xlabel("pucks")
    bx.set_ylabel("exact: µs per contact")
    bx.set_title("cost per contact")
    bx.set_ylim(bottom=0)
    bx.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


_BODIES_BEGIN = "<!-- bodies section: generated by --section bodies -->"
_BODIES_END = "<!-- end of bodies section -->"


def _write_bodies(out: Path, rows, steps: int, load: float | None = None) -> None:
    """Write (or replace) the bodies section of ``speed.md`` and its plot."""
    _plot_bodies(out / "speed_bodies.png", rows)
    block = "\n".join([_BODIES_BEGIN, *_bodies_lines(rows, steps, load), _BODIES_END])
    md = out / "speed.md"
    text = md.read_text() if md.exists() else "# Speed\n"
    if _BODIES_BEGIN in text:
        head, rest = text.split(_BODIES_BEGIN, 1)
        tail = rest.split(_BODIES_END, 1)[1]
        text = head + block + tail
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    md.write_text(text)


def _machine(load: float) -> str:
    """The machine and versions, and ``load``: the load average when the run started."""
    model = cpu_model()
    import numba
    import pymunk

    return (f"{os.cpu_count()} cores ({model}); Python {platform.python_version()}, numpy "
            f"{np.__version__}, numba {numba.__version__}, gymnasium {gym.__version__}, pymunk "
            f"{pymunk.version}; load average at start {load:.2f}, at the end "
            f"{os.getloadavg()[0]:.2f}")


def _plot(path: Path, xs, ys, xlabel: str, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.loglog(xs, ys, "o-")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("time per step per element (s)")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None, prog: str = "python -m spinstrike.benchmarks.speed"
         ) -> int:
    p = argparse.ArgumentParser(prog=prog,
                                description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true",
                   help="smaller batches and fewer repetitions (a few minutes); prints only, "
                        "unless --out is given")
    p.add_argument("--out", type=Path, default=None,
                   help="where speed.md and the plots go (default: docs for a full run; a "
                        "--quick run only prints unless --out is given)")
    p.add_argument("--section", choices=["all", "bodies"], default="all",
                   help="bodies: only the bodies sweep (exact beside raw pymunk), which replaces "
                        "that section of speed.md and its plot")
    p.add_argument("--bodies", type=int, nargs="+", default=list(BODIES),
                   help="pucks per scene in the bodies sweep (default: %(default)s)")
    args = p.parse_args(argv)
    if min(args.bodies) < 1:
        p.error(f"--bodies: each must be >= 1 puck (got {min(args.bodies)})")
    quick = args.quick
    target = args.out if args.out is not None else (None if quick else Path("docs"))
    # the PPO env-share row trains SB3's PPO (the 'train' extra; 'bench' does not bring torch):
    # a full run writes it into speed.md, so it needs SB3 before any work, the output folder
    # included (a refused run left an empty docs/); --quick skips it
    have_sb3 = importlib.util.find_spec("stable_baselines3") is not None
    if not have_sb3 and args.section == "all":
        if target is not None:
            p.error("the PPO env-share row of speed.md needs stable_baselines3, which comes with "
                    "the 'train' extra: pip install \"spinstrike[train]\" (or run --quick, "
                    "which prints the rest without it)")
        print("note: stable_baselines3 is not installed (the 'train' extra): the PPO env-share "
              "row is skipped", file=sys.stderr)
    out = out_dir(p, target, "speed.md and the plots")
    load, cores = os.getloadavg()[0], os.cpu_count() or 1
    if load > 0.5 * cores:  # the rates are the fastest of a few runs, not immune to sharing
        print(f"warning: load average {load:.2f} on {cores} cores: other work shares them, "
              f"and the native vector env's parallel kernel loses most (up to ~5x against "
              f"pymunk's single thread); measure on quiet cores for the ratios docs/speed.md "
              f"reports", file=sys.stderr)
    body_steps = 10 if quick else BODY_STEPS
    if args.section == "bodies":
        rows = bodies_sweep(args.bodies, body_steps)
        if out is None:
            print("\n".join(_bodies_lines(rows, body_steps, load)))
            print("(--quick: printed only; --out DIR writes the section and its plot)")
            return 0
        _write_bodies(out, rows, body_steps, load)
        print(f"wrote the bodies section of {out / 'speed.md'}")
        return 0
    big = 1024 if quick else 4096
    reps = 2 if quick else 3
    rows = []
    started = time.time()

    def row(what, rate, contacts="-", unit="env-steps/s", note=""):
        rows.append((what, rate, contacts, unit, note))
        c = f"{contacts:.3f}" if isinstance(contacts, float) else contacts
        print(f"{what:60s} {rate:14,.0f} {unit:12s} contacts/step {c} {note}", flush=True)

    vec_rand, c_rand = _vector_rate(CONTROL, big, 50, reps)
    row(f"native vector env, exact, {big} envs, random actions", vec_rand, c_rand)
    vec_chase, c_chase = _vector_rate(CONTROL, big, 50, reps, policy="chase")
    row(f"native vector env, exact, {big} envs, chase-and-hit", vec_chase, c_chase)
    sync_rate, c_sync = _sync_pymunk_rate(16 if quick else 64, 50, reps)
    row("SyncVectorEnv of single envs, pymunk backend", sync_rate, c_sync)
    cart = _cartpole_rate(1024, 200, reps)
    row("Gymnasium CartPole-v1 vector env, 1024 envs (yardstick)", cart)
    single_exact, c1 = _single_rate(CONTROL, 2000, reps)
    row("single env via gym.make, exact, random actions", single_exact, c1)
    single_chase, c2 = _single_rate(CONTROL, 2000, reps, policy="chase")
    row("single env via gym.make, exact, chase-and-hit", single_chase, c2)
    single_pymunk, c3 = _single_rate(CONTROL, 2000, reps, solver={"mode": "pymunk"})
    row("single env via gym.make, pymunk backend, random actions", single_pymunk, c3)
    chipmunk = _chipmunk_alone_rate(400 if quick else 2000, reps)
    single_chipmunk_share = single_pymunk / chipmunk
    row("Chipmunk alone on that env's space, same forces (no observation, reward or checks)",
        chipmunk)
    strike_single, c4 = _single_rate("SpinStrike/RodSpin-v0", 300, reps)
    row("RodSpin-v0 single env, random strikes", strike_single, c4, "strikes/s")
    strike_vec, c5 = _vector_rate("SpinStrike/RodSpin-v0", 1024, 10, reps)
    row("RodSpin-v0 native vector env, 1024 envs, random strikes", strike_vec, c5, "strikes/s")
    puck_vec, c6 = _vector_rate("SpinStrike/PuckSpeed-v1", 1024, 10, reps)
    row("PuckSpeed-v1 native vector env, 1024 envs, random strikes", puck_vec, c6, "strikes/s")
    startup = _startup_times(list(envs.ENV_IDS))
    for env_id, (c1, c1000, w1, w1000) in startup.items():
        print(f"start-up {env_id}: cold {c1:.1f} / {c1000:.1f} s, warm {w1:.1f} / {w1000:.1f} s")
    if have_sb3:
        share = _ppo_env_share(8192 if quick else 32768)
        rows.append(("share of SB3 PPO wall time spent in the env (16 envs, native adapter, "
                     "torch on 1 thread)", share, "-", "fraction", ""))
        print(f"PPO env share {share:.3f}")

    batches = [1, 4, 16, 64, 256, 1024, 4096] + ([] if quick else [16384, 65536])
    scene = physics.load_scene(envs.config.load_packaged_scene("rod_control"))
    per_batch = []
    for b in batches:
        t, c = _world_step_time(scene, b, max(2, 2000 // b), reps)
        per_batch.append((b, t / b, c))
        print(f"batch {b:6d}: {t / b * 1e6:9.3f} us per element-step, contacts {c:.3f}")
    body_rows = bodies_sweep(args.bodies, body_steps)
    if out is None:
        print(f"native vector env (random) / SyncVectorEnv on pymunk: {vec_rand / sync_rate:.1f}x; "
              f"/ CartPole-v1 vector env: {vec_rand / cart:.2f}x; single env exact / pymunk: "
              f"{single_exact / single_pymunk:.2f}x; / Chipmunk alone: "
              f"{single_exact / chipmunk:.2f}x")
        print("(--quick: printed only; --out DIR writes speed.md and the plots)")
        return 0
    _plot(out / "speed_batch.png", [b for b, _, _ in per_batch], [t for _, t, _ in per_batch],
          "batch size B", "world.step (RodSpinControl scene, exact): cost per element")
    _plot_bodies(out / "speed_bodies.png", body_rows)

    lines = ["# Speed", "",
             f"Generated by `python -m spinstrike.benchmarks.speed{' --quick' if quick else ''}` "
             f"in "
             f"{time.time() - started:.0f} s on {_machine(load)}. Rates are the fastest of {reps} "
             "repetitions after a warm-up (numba compiled); ratios are between figures measured "
             "in this same run.", "",
             "| what | rate | unit | contacts per env-step |", "|---|---|---|---|"]
    for what, rate, contacts, unit, _ in rows:
        c = f"{contacts:.3f}" if isinstance(contacts, float) else contacts
        value = f"{rate:.3f}" if unit == "fraction" else (
            f"{rate:.1f}" if unit == "s" else f"{rate:,.0f}")
        lines.append(f"| {what} | {value} | {unit} | {c} |")
    lines += ["", "## Start-up", "",
              "Seconds from a fresh interpreter's `import` to a single env's first and 1000th "
              "step (`gym.make`, random actions), with an empty kernel cache of its own (every "
              "kernel the env needs compiles; one line on stderr says so) and with it filled. "
              "Each env compiles only the solver and contact paths its scene uses "
              "(`docs/design.md` §5).", "",
              "| env | first step, cache empty | 1000th step, cache empty | first step, "
              "cache filled | 1000th step, cache filled |", "|---|---|---|---|---|"]
    lines += [f"| `{env_id}` | {c1:.1f} | {c1000:.1f} | {w1:.1f} | {w1000:.1f} |"
              for env_id, (c1, c1000, w1, w1000) in startup.items()]
    lines += ["", "Ratios in this run:", "",
              "* native vector env (random) / SyncVectorEnv on pymunk: "
              f"**{vec_rand / sync_rate:.1f}x**; / Chipmunk alone on one env's space (the "
              "table's row, the most a single-threaded vector env of a pymunk user's own could "
              f"reach): **{vec_rand / chipmunk:.1f}x**",
              f"* native vector env (random) / CartPole-v1 vector env: {vec_rand / cart:.2f}x",
              f"* single env exact / single env pymunk: **{single_exact / single_pymunk:.2f}x**; "
              f"/ Chipmunk alone on that env's space: **{single_exact / chipmunk:.2f}x** (the "
              f"backend's env step is {single_chipmunk_share:.0%} Chipmunk, the rest SpinStrike's "
              "Python around it: write-back, checks, observation, reward; a pymunk user's own "
              "env of this scene would land between the two)",
              f"* vector / single, RodSpin strikes: {strike_vec / strike_single:.1f}x", "",
              "## Cost against batch size", "",
              "| B | µs per element-step | contacts per element-step |", "|---|---|---|"]
    lines += [f"| {b} | {t * 1e6:.3f} | {c:.3f} |" for b, t, c in per_batch]
    lines += ["", "![cost per element against batch size](speed_batch.png)", "",
              _BODIES_BEGIN, *_bodies_lines(body_rows, body_steps), _BODIES_END, ""]
    b1 = per_batch[0][1] * 1e6
    flat = [t * 1e6 for b, t, _ in per_batch if b >= 256]
    lines += [
        "## Where the time goes", "",
        f"* **Batch size.** One call costs about {b1:.1f} µs at B = 1 (Python around the kernel "
        "and numba's dispatch); from B = 256 the kernels run on all cores and the cost per "
        f"element (a resting scene) stays between {min(flat):.2f} and {max(flat):.2f} µs up to "
        f"the largest batch ({flat[-1]:.2f} µs there).",
        "* **Bodies.** From 8 bodies the exact solver steps on a broadphase (swept boxes, "
        "re-sorted along x from the last step's order) and an event calendar "
        "(`physics/calendar.py`, `docs/design.md` §4): an event costs the searches of the "
        "pairs of the bodies it changed, heap updates and a pass over the pairs that may "
        "touch, not a scan of all N^2 pairs, and the events are the same bit for bit. Its "
        "event loop is compiled without numba's reference counting (`jit.jit_uncounted`): the "
        "atomic counts numba kept on the arrays of inlined helpers were two thirds of its "
        "time. What grows with N is the flight of every body to each event (the scan's "
        "arithmetic, kept so that the two agree bit for bit) and one test of each changed "
        "body's box against every other body per event. The settling that ends a step, and "
        "the fixed solver, sweep only the pairs close enough to touch (a sweep and prune after "
        "each substep's drift), not all N^2 pairs: the fixed column. At one world and 64 pucks, "
        "`world.step`'s contact record (numpy, in Python) costs about as much as the kernel.",
        "* **Contacts.** Free flight is cheap; each impact costs a search per affected pair. "
        "A mallet driven into a cushion rests on it (the end of its Zeno run of ever-smaller "
        "bounces, `solvers._rest_on_cushions`); until 2026-11-23 those steps, 1% under random "
        "actions and all of them under a policy that keeps pushing, were settled by fixed "
        "substeps at ~30 µs each, a third of the random rows' time (per env-step, 1 thread: "
        "random 1.34 -> 1.06 µs, chase-and-hit 2.7 -> 1.7, pushing into a cushion 33 -> 2.1). "
        "Settling is left for chains (the mallet pressing a puck into a cushion). Compare the "
        "random and chase-and-hit rows.",
        "* **Optimisations so far**, each checked bit for bit against recorded trajectories "
        "(`tests/physics/test_golden.py`): kernels read rows by index instead of slicing row "
        "views (numba counts references on every view and on every array passed to a "
        "non-inlined function: pair geometry went from 463 to 50 ns); numpy's error model "
        "(no zero-division checks); one float and one int buffer per world (a kernel call "
        "takes 2 arguments instead of 25); the control step and the whole one-strike "
        "simulation compiled (no Python per chunk, each element only as long as it needs); "
        "small array-taking kernels inlined; a cheap test that settles pairs provably apart "
        "for the whole step; the buffers unpacked once per block of 64 elements.", ""]
    # the compile-time study (python -m spinstrike.benchmarks.startup) is kept as it was
    kept = startup_study.keep_section(out / "speed.md")
    (out / "speed.md").write_text("\n".join(lines + ([kept, ""] if kept else [])) + "\n")
    print(f"wrote {out / 'speed.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
