"""Accuracy against time: what each solver's knob buys, on collisions with known answers.

Run ``python -m spinstrike.benchmarks.accuracy`` (about 4 minutes on 2 cores; ``--quick`` for a
small subset in seconds). It writes ``docs/accuracy.md`` (tables, machine, library versions,
the command) and ``docs/accuracy.png`` (the Pareto chart). ``main(argv)`` is the entry point a
CLI can call.

What is measured, per solver and knob setting, on every variant of every reference case of
``benchmarks.cases`` (one collision each, answer from a closed form or an independent root
finder, never from a solver):

* **velocity error**: ``max_i |v_i - v_i_ref| / V``, V the incoming speed (relative speed of the
  two contact points at impact);
* **spin error**: ``max_i |omega_i - omega_i_ref| L / V``, L the rod's half-length (a disk's radius
  in the disk-disk case);
* **energy error**: ``|E - E_ref| / E_in``;
* **time per collision**: wall time (``time.perf_counter``, fastest of repetitions, numba
  compiled beforehand) of one ``world.step`` that simulates the whole variant — approach, impact
  and a collision-free window after it — divided by the batch size (B identical copies are
  stepped together, so the world's per-call overhead is shared as in a vector env). Each variant
  holds one collision, so this is the price of one collision with the approach that leads to it;
* **cost accounting** from ``world.last_step``: events and root-finding iterations (exact),
  substeps (fixed, pymunk), solver iterations (pymunk: substeps x ``Space.iterations``), impulses
  recorded.

Knobs: ``exact`` ``tolerance`` (m); ``fixed`` and ``pymunk`` *steps per approach* S: the step is
``h = t_c / (S + phase)`` with ``t_c`` the reference time of impact, for several phases in (0, 1),
so that the impact falls at different points inside a step (a phase-locked step would land every
impact exactly at touching and flatter the fixed-step engines); ``pymunk`` also
``Space.iterations``. Errors of the fixed-step solvers are taken over all phases.

A second table prices each effect: the same scene with the effect on, on at zero strength, and
off, in time per ``world.step`` (B = 1).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import gc
import importlib.metadata
import math
import os
import platform
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from spinstrike import physics
from spinstrike.benchmarks import out_dir
from spinstrike.benchmarks.cases import CASES, Variant, get_case

__all__ = ["Setting", "errors", "main", "measure", "run", "settings"]

EXACT_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)
FIXED_STEPS = (1, 2, 4, 8, 16, 32, 64, 128, 256)
PYMUNK_STEPS = (10, 30, 100, 300, 1000)
PYMUNK_ITERATIONS = (1, 10, 100)
PHASES = (0.125, 0.375, 0.625, 0.875)

QUICK_EXACT = (1e-3, 1e-6, 1e-9, 1e-12)
QUICK_FIXED = (1, 16, 256)
QUICK_PYMUNK_STEPS = (10, 100, 1000)
QUICK_PYMUNK_ITERATIONS = (10,)
QUICK_PHASES = (0.375, 0.875)
QUICK_VARIANTS = 2

#: the pymunk setting the acceptance line compares with (steps per approach, iterations)
PYMUNK_REFERENCE = (100, 10)
#: plotted floor for errors that are exactly 0
ERROR_FLOOR = 1e-17


# ---------------------------------------------------------------------------------------------
# settings and measurement
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Setting:
    """One solver at one knob setting."""

    solver: str  # exact | fixed | pymunk
    tolerance: float | None = None
    steps: int | None = None  # steps per approach (fixed, pymunk)
    iterations: int | None = None  # pymunk Space.iterations

    @property
    def knob(self) -> str:
        if self.solver == "exact":
            return f"tolerance {self.tolerance:.0e} m"
        if self.solver == "fixed":
            return f"{self.steps} steps/approach"
        return f"{self.steps} steps/approach, {self.iterations} it"

    @property
    def label(self) -> str:
        return f"{self.solver} {self.knob}"

    def runs(self, variant: Variant, phases: Sequence[float]) -> list[tuple[dict, float]]:
        """Solver blocks and step lengths (s) that simulate ``variant``."""
        if self.solver == "exact":
            return [({"mode": "exact", "tolerance": self.tolerance}, variant.duration)]
        out = []
        for phase in phases:
            h = variant.t_contact / (self.steps + phase)
            first = math.ceil(variant.t_contact / h)  # the step that detects the impact
            n = max(first + 1, round(variant.duration / h))
            if n * h >= variant.t_next:
                n = first + 1
            block: dict[str, Any] = {"mode": self.solver, "substeps": n}
            if self.solver == "pymunk":
                block["iterations"] = self.iterations
            out.append((block, n * h))
        return out


def settings(quick: bool = False) -> list[Setting]:
    """Every (solver, knob) setting of the sweep."""
    tols, fixed = (QUICK_EXACT, QUICK_FIXED) if quick else (EXACT_TOLERANCES, FIXED_STEPS)
    steps, its = ((QUICK_PYMUNK_STEPS, QUICK_PYMUNK_ITERATIONS) if quick
                  else (PYMUNK_STEPS, PYMUNK_ITERATIONS))
    return ([Setting("exact", tolerance=t) for t in tols]
            + [Setting("fixed", steps=s) for s in fixed]
            + [Setting("pymunk", steps=s, iterations=i) for i in its for s in steps])


@dataclass
class Measurement:
    """Errors and cost of one setting on one variant (errors: one entry per run/phase)."""

    setting: Setting
    case: str
    variant: str
    offline: bool  # the answer depends on where the contact is taken (not normal_fixed)
    velocity: list[float] = field(default_factory=list)
    spin: list[float] = field(default_factory=list)
    energy: list[float] = field(default_factory=list)
    hit: list[bool] = field(default_factory=list)
    seconds: float = math.nan  # per collision
    events: float = 0.0
    iterations: float = 0.0
    substeps: float = 0.0
    contacts: float = 0.0


def _errors(world: physics.World, v: Variant) -> tuple[float, float, float]:
    vel = np.asarray(world.state.velocities[0])
    om = np.asarray(world.state.omegas[0])
    ev = float(np.linalg.norm(vel - v.velocities, axis=-1).max() / v.speed)
    es = float(np.abs(om - v.omegas).max() * v.length / v.speed)
    ee = abs(v.energy(vel, om) - v.energy_out) / v.energy_in
    return ev, es, ee


def _time_step(world: physics.World, dt: float, min_time: float, min_reps: int = 3,
               max_reps: int = 500) -> float:
    """Fastest wall time (s) of ``world.step(dt)`` from the initial state over repetitions (the
    minimum is the time least disturbed by other processes on a shared machine)."""
    times: list[float] = []
    enabled = gc.isenabled()
    gc.disable()
    try:
        while (len(times) < min_reps or sum(times) < min_time) and len(times) < max_reps:
            world.reset()
            t0 = time.perf_counter()
            world.step(dt)
            times.append(time.perf_counter() - t0)
    finally:
        if enabled:
            gc.enable()
    return float(np.min(times))


def measure(setting: Setting, case: str, variant: Variant, phases: Sequence[float] = PHASES,
            batch: int = 16, min_time: float = 0.03) -> Measurement:
    """Run one setting on one variant: errors for every phase, time for the first."""
    m = Measurement(setting, case, variant.name, not variant.normal_fixed)
    for k, (block, dt) in enumerate(setting.runs(variant, phases)):
        world = physics.World(variant.scene, batch_size=batch if k == 0 else 1, solver=block)
        world.step(dt)
        ev, es, ee = _errors(world, variant)
        m.velocity.append(ev)
        m.spin.append(es)
        m.energy.append(ee)
        last = world.last_step
        m.hit.append(bool(last.contacts[0] > 0))
        if k == 0:
            m.events = float(last.events[0])
            m.iterations = float(last.iterations[0])
            m.substeps = float(last.substeps[0])
            m.contacts = float(last.contacts[0])
            m.seconds = _time_step(world, dt, min_time) / batch
    return m


def errors(setting: Setting, variant: Variant,
           phases: Sequence[float] = PHASES) -> list[tuple[float, float, float, bool]]:
    """(velocity, spin, energy error, hit) of every run of ``setting`` on ``variant``, untimed."""
    out = []
    for block, dt in setting.runs(variant, phases):
        world = physics.World(variant.scene, solver=block)
        world.step(dt)
        out.append(_errors(world, variant) + (bool(world.last_step.contacts[0] > 0),))
    return out


def _warm_up() -> None:
    """Compile (or load) the numba kernels before anything is timed."""
    v = get_case("seed").variants[0]
    for block in ({"mode": "exact"}, {"mode": "fixed", "substeps": 4}):
        for batch in (1, 2):
            physics.World(v.scene, batch_size=batch, solver=block).step(v.duration)
    physics.World(v.scene, solver={"mode": "pymunk"}).step(v.duration)


def run(quick: bool = False, batch: int | None = None, min_time: float | None = None,
        cases: Sequence[str] | None = None, log=None) -> list[Measurement]:
    """The whole sweep: every setting on every variant of every case."""
    batch = batch or (4 if quick else 16)
    min_time = min_time if min_time is not None else (0.005 if quick else 0.1)
    phases = QUICK_PHASES if quick else PHASES
    _warm_up()
    out = []
    for name in cases or CASES:
        case = get_case(name)
        variants = case.variants[:QUICK_VARIANTS] if quick else case.variants
        for s in settings(quick):
            t0 = time.perf_counter()
            for v in variants:
                out.append(measure(s, name, v, phases, batch, min_time))
            if log:
                log(f"{name:17s} {s.label:40s} {time.perf_counter() - t0:6.2f} s")
    return out


# ---------------------------------------------------------------------------------------------
# cost per effect
# ---------------------------------------------------------------------------------------------

EFFECT_DT = 0.01
EFFECT_STEPS = 100
EFFECT_SOLVERS = (("exact", {"mode": "exact", "tolerance": 1e-9}),
                  ("fixed", {"mode": "fixed", "substeps": 10}),
                  ("pymunk", {"mode": "pymunk", "substeps": 10, "iterations": 10}))
ALL_EFFECTS = ("rotation", "walls", "contact_friction", "table_friction")


def effect_scene(effects: Sequence[str], contact_mu: float = 0.2, table_mu: float = 0.1) -> dict:
    """A walled table with a spinning rod and two pucks; parameters of absent effects dropped."""
    eff = list(effects)
    rot = "rotation" in eff
    return {
        "table": {"size": [1.2, 0.8] if "walls" in eff else None,
                  "friction": table_mu if "table_friction" in eff else 0.0},
        "effects": eff,
        "materials": {"restitution": 0.9,
                      "friction": contact_mu if "contact_friction" in eff else 0.0},
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1,
             "position": [0.0, 0.1], "angle": 0.3, "velocity": [0.5, -0.2],
             "omega": 3.0 if rot else 0.0},
            {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
             "position": [-0.4, -0.2], "velocity": [1.5, 0.8]},
            {"name": "puck2", "shape": "disk", "radius": 0.03, "mass": 0.05,
             "position": [0.4, -0.2], "velocity": [-1.2, 0.5]},
        ],
    }


def effect_configurations() -> list[tuple[str, dict]]:
    """(label, scene): all effects, then each one off (and on at zero strength where it has one)."""
    out = [("all four effects", effect_scene(ALL_EFFECTS))]
    for e in ALL_EFFECTS:
        out.append((f"without {e}", effect_scene([x for x in ALL_EFFECTS if x != e])))
        if e == "contact_friction":
            out.append(("contact_friction at mu = 0", effect_scene(ALL_EFFECTS, contact_mu=0.0)))
        if e == "table_friction":
            out.append(("table_friction at mu_t = 0", effect_scene(ALL_EFFECTS, table_mu=0.0)))
    out.append(("none (bare translation, unbounded)", effect_scene([])))
    return out


def effect_costs(min_time: float = 0.2, min_rounds: int = 3) -> list[dict]:
    """Time per step (s) and contacts per step of each configuration and solver, B = 1.

    The configurations are timed in rounds, each round one run of every (configuration,
    solver) in turn, and each keeps its fastest run: timed one configuration after another, a
    change of the machine's load between them read as a cost (the same motion timed 12.3 us
    without an effect and 8.9 us with it at zero strength, interleaved 8.77 and 8.77)."""
    configurations = effect_configurations()
    worlds = {(label, name): physics.World(scene, solver=block)
              for label, scene in configurations for name, block in EFFECT_SOLVERS}
    times: dict[tuple[str, str], list[float]] = {key: [] for key in worlds}
    contacts: dict[tuple[str, str], int] = {}
    rounds = 0
    while rounds < min_rounds or min(sum(t) for t in times.values()) < min_time:
        for key, world in worlds.items():
            world.reset()
            count = 0
            t0 = time.perf_counter()
            for _ in range(EFFECT_STEPS):
                count += len(world.step(EFFECT_DT))
            times[key].append(time.perf_counter() - t0)
            contacts[key] = count
        rounds += 1
    rows = []
    for label, _ in configurations:
        row: dict[str, Any] = {"label": label}
        for name, _ in EFFECT_SOLVERS:
            row[name] = float(np.min(times[label, name])) / EFFECT_STEPS
            row[name + "_contacts"] = contacts[label, name] / EFFECT_STEPS
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------------


def _summary(ms: list[Measurement]) -> list[dict]:
    """Per setting: worst errors over the accuracy cases (all but ``tunnel``), the median over
    their off-line variants, per-case median and worst, tunnel misses, mean cost."""
    by: dict[Setting, list[Measurement]] = {}
    for m in ms:
        by.setdefault(m.setting, []).append(m)
    rows = []
    for s, group in by.items():
        acc = [m for m in group if m.case != "tunnel"] or group
        vel = np.concatenate([m.velocity for m in acc])
        off = [x for m in acc if m.offline for x in m.velocity]
        per_case: dict[str, tuple[float, float]] = {}
        for case in dict.fromkeys(m.case for m in group):
            errs = [x for m in group if m.case == case for x in m.velocity]
            per_case[case] = (float(np.median(errs)), float(np.max(errs)))
        tunnel = [h for m in group if m.case == "tunnel" for h in m.hit]
        rows.append({
            "setting": s, "vel_max": float(vel.max()),
            "vel_offline_median": float(np.median(off)) if off else math.nan,
            "spin_max": float(max(max(m.spin) for m in acc)),
            "energy_max": float(max(max(m.energy) for m in acc)),
            "seconds": float(np.mean([m.seconds for m in group])),
            "events": float(np.mean([m.events for m in group])),
            "iterations": float(np.mean([m.iterations for m in group])),
            "substeps": float(np.mean([m.substeps for m in group])),
            "contacts": float(np.mean([m.contacts for m in group])),
            "per_case": per_case,
            "tunnel_missed": (sum(not h for h in tunnel), len(tunnel)),
        })
    return rows


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points no other point beats in both time and error (ties kept)."""
    front = []
    for i, (t, e) in enumerate(points):
        if not any((t2 <= t and e2 <= e) and (t2 < t or e2 < e) for t2, e2 in points):
            front.append(i)
    return sorted(front, key=lambda i: points[i][0])


def _us(seconds: float) -> str:
    us = seconds * 1e6
    return f"{us:.3g}" if us < 1000 else f"{us:,.0f}"


def _e(x: float) -> str:
    """An error as the tables show it; ``-`` where nothing was measured (NaN: no off-line
    variant among the cases run, a case a setting did not run)."""
    if math.isnan(x):
        return "-"
    return "0" if x == 0 else f"{x:.1e}"


def machine() -> dict[str, str]:
    """CPU model (``lscpu``), core count, OS and the library versions the numbers depend on."""
    model = platform.processor() or "unknown"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except (OSError, subprocess.SubprocessError):
        pass
    versions = {"python": platform.python_version()}
    for lib in ("numpy", "numba", "pymunk", "mpmath", "matplotlib", "gymnasium"):
        try:
            versions[lib] = importlib.metadata.version(lib)
        except importlib.metadata.PackageNotFoundError:
            versions[lib] = "not installed"
    return {"cpu": model, "cores": str(os.cpu_count()), "os": platform.platform(),
            "versions": ", ".join(f"{k} {v}" for k, v in versions.items())}


def raw_pymunk_step(steps: int = 5000) -> float:
    """Seconds per bare ``Space.step`` (no contact, no Python callback, no world around it).

    Steps the backend's own space of a disk-disk variant after the impact, when the two disks
    fly apart: Chipmunk's floor cost per step on this machine (pymunk is not imported here).
    """
    v = get_case("disk_disk").variants[0]
    world = physics.World(v.scene, solver={"mode": "pymunk", "substeps": 10})
    world.step(v.duration)  # past the impact
    space = world.backend.space(0)
    h = v.t_contact / 100
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(steps):
            space.step(h)
        best = min(best, (time.perf_counter() - t0) / steps)
    return best


#: the case the like-for-like line times (its impacts' answers depend on the contact pose)
PLAIN_CASE = "offline_disk_rod"
#: steps per approach below PYMUNK_REFERENCE's at which the like-for-like line also times the
#: plain loop (walk W29a F5: its time is linear in them, so the ratio is the choice of 100)
PLAIN_FEWER = (10, 30)


def _plain_space(variant: Variant, iterations: int):
    """``variant``'s bodies in a pymunk ``Space`` as a pymunk user writes it: a ``Circle`` per
    disk, a ``Segment`` per rod (radius half its thickness), a thin static ``Segment`` per
    cushion, ``elasticity = sqrt(e)`` on each shape, no friction, ``collision_slop`` 0, no
    Python callback."""
    import pymunk

    space = pymunk.Space()
    space.iterations = iterations
    space.collision_slop = 0.0
    root_e = math.sqrt(variant.scene.get("materials", {}).get("restitution", 1.0))
    if "walls" in variant.scene["effects"]:  # the cushions: four thin static segments
        hw, hh = (x / 2 for x in variant.scene["table"]["size"])
        for a, b in (((-hw, -hh), (-hw, hh)), ((hw, -hh), (hw, hh)),
                     ((-hw, -hh), (hw, -hh)), ((-hw, hh), (hw, hh))):
            wall = pymunk.Segment(space.static_body, a, b, 0.0)
            wall.elasticity, wall.friction = root_e, 0.0
            space.add(wall)
    bodies = []
    for spec, m, inertia in zip(variant.scene["bodies"], variant.masses, variant.inertias,
                                strict=True):
        body = pymunk.Body(float(m), float(inertia))
        body.position = tuple(spec.get("position", (0.0, 0.0)))
        body.angle = spec.get("angle", 0.0)
        body.velocity = tuple(spec.get("velocity", (0.0, 0.0)))
        body.angular_velocity = spec.get("omega", 0.0)
        if spec["shape"] == "disk":
            shape = pymunk.Circle(body, spec["radius"])
        else:
            h = spec["length"] / 2
            shape = pymunk.Segment(body, (-h, 0.0), (h, 0.0), spec["thickness"] / 2)
        shape.elasticity, shape.friction = root_e, 0.0
        space.add(body, shape)
        bodies.append(body)
    return space, bodies


def plain_pymunk(variant: Variant, steps: int = PYMUNK_REFERENCE[0],
                 iterations: int = PYMUNK_REFERENCE[1], phase: float = PHASES[0],
                 min_time: float = 0.1) -> tuple[float, float]:
    """(velocity error, fastest seconds) of ``variant`` in a plain pymunk loop
    (:func:`_plain_space`, ``space.step`` over the steps the benchmark's pymunk setting of
    ``steps`` per approach takes): the peer a pymunk user would time, without the backend's
    per-pair callbacks (per-pair restitution, contact reports) and world around it."""
    block, dt = Setting("pymunk", steps=steps, iterations=iterations).runs(variant, [phase])[0]
    n = block["substeps"]
    h = dt / n
    times: list[float] = []
    while len(times) < 3 or sum(times) < min_time:
        space, bodies = _plain_space(variant, iterations)
        t0 = time.perf_counter()
        for _ in range(n):
            space.step(h)
        times.append(time.perf_counter() - t0)
    vel = np.array([[b.velocity.x, b.velocity.y] for b in bodies])
    return float(np.linalg.norm(vel - variant.velocities, axis=-1).max() / variant.speed), \
        float(min(times))


def _one_at_a_time(v: Variant, min_time: float) -> dict[str, float]:
    """``v`` one collision at a time: the plain pymunk loop's velocity error and time at
    ``PYMUNK_REFERENCE`` beside the exact solver's at 1e-12 m, one copy per ``world.step``."""
    plain_error, plain = plain_pymunk(v, min_time=min_time)
    world = physics.World(v.scene, solver={"mode": "exact", "tolerance": 1e-12})
    world.step(v.duration)
    exact_error = _errors(world, v)[0]
    return {"plain": plain, "plain_error": plain_error, "exact_error": exact_error,
            "exact": _time_step(world, v.duration, min_time)}


def _pooled(runs: list[dict[str, float]]) -> dict[str, float]:
    """Medians of times and of the per-collision ratio, worst errors, over ``runs``."""
    ratio = np.array([r["plain"] / r["exact"] for r in runs])
    return {"plain": float(np.median([r["plain"] for r in runs])),
            "exact": float(np.median([r["exact"] for r in runs])),
            "plain_error": max(r["plain_error"] for r in runs),
            "exact_error": max(r["exact_error"] for r in runs), "variants": len(runs),
            "ratio": float(np.median(ratio)), "ratio_min": float(ratio.min()),
            "ratio_max": float(ratio.max())}


def like_for_like(min_time: float = 0.1, quick: bool = False,
                  cases: Sequence[str] | None = None) -> dict[str, Any]:
    """One collision at a time, the plain pymunk loop (:func:`plain_pymunk`) beside the exact
    solver at 1e-12 m with one copy per ``world.step`` (its Python per call not spread over
    copies), on every variant of ``cases`` (default: all). Returns the headline, pooled over
    the off-line disk-rod impacts whose answer depends on the contact pose (the ones a
    fixed-step engine gets wrong by its step), and ``"cases"``: one pooled row per case over
    all its variants."""
    names = list(CASES if cases is None else cases)
    runs: dict[str, list[tuple[Variant, dict[str, float]]]] = {}
    for name in names:
        variants = get_case(name).variants
        if name == PLAIN_CASE:  # the headline's variants first, so a quick run has them
            variants = sorted(variants, key=lambda v: v.normal_fixed)
        variants = variants[:QUICK_VARIANTS] if quick else variants
        runs[name] = [(v, _one_at_a_time(v, min_time)) for v in variants]
    head = [(v, r) for v, r in runs.get(PLAIN_CASE, []) if not v.normal_fixed]
    out: dict[str, Any] = _pooled([r for _, r in head]) if head else {}
    if head:  # the plain loop's cost is linear in its steps: what fewer of them buy
        out["fewer"] = {}
        for steps in PLAIN_FEWER:
            errs, times = zip(*(plain_pymunk(v, steps=steps, min_time=min_time)
                                for v, _ in head), strict=True)
            out["fewer"][steps] = {"plain": float(np.median(times)),
                                   "median_error": float(np.median(errs)),
                                   "plain_error": max(errs)}
    out["cases"] = {name: _pooled([r for _, r in rows]) for name, rows in runs.items()}
    return out


def report(ms: list[Measurement], effects: list[dict] | None, argv: Sequence[str],
           seconds: float, plot_name: str | None, raw_step: float | None = None,
           load: tuple[float, float] | None = None, plain: dict | None = None) -> str:
    """The markdown page."""
    rows = _summary(ms)
    mach = machine()
    cases = list(dict.fromkeys(m.case for m in ms))
    cmd = "python -m spinstrike.benchmarks.accuracy" + "".join(f" {a}" for a in argv)
    phases = ", ".join(f"{p:g}" for p in _phases(ms))
    lines = [
        "# Accuracy against time",
        "",
        f"Generated by `{cmd}` on {_dt.date.today().isoformat()} in {seconds:.0f} s "
        "(regenerate with `python -m spinstrike.benchmarks.accuracy`; `--quick` for a small "
        "subset).",
        "",
        f"- Machine: {mach['cpu']}, {mach['cores']} cores (`lscpu`), {mach['os']}",
        f"- Libraries: {mach['versions']}",
        *([f"- Load average (1 min) at start / end: {load[0]:.2f} / {load[1]:.2f} — other "
           "processes share the 2 cores, so times carry their noise; errors are exact."]
          if load else []),
        "",
        "Every reference case (`benchmarks/cases.py`) is one collision whose answer comes from a "
        "closed form or from an independent root finder (mpmath) plus the impulse law, never from "
        "a solver. Errors are relative: velocity `max_i |v_i - v_i,ref| / V`, spin "
        "`max_i |w_i - w_i,ref| L / V` (V the incoming contact-point speed, L the rod "
        "half-length), energy `|E - E_ref| / E_in`. *Time per collision* is the wall time of one "
        "`world.step` that simulates the approach, the impact and a short collision-free window "
        "after it (a quarter of the approach), per batch element (B copies stepped together, "
        "fastest of repetitions, numba compiled first). The fixed-step solvers run at *steps per "
        "approach* S, i.e. step `h = t_c / (S + phase)` with `t_c` the reference time of impact, "
        f"for phases {phases}; errors are taken over all phases. Cost columns are per collision "
        "from `world.last_step` (pymunk's sweeps = steps x `Space.iterations`).",
        "",
    ]
    lines += _acceptance(rows, raw_step, plain)
    lines += [
        "## Summary",
        "",
        "*Worst*: over every variant and phase of the accuracy cases (all but `tunnel`, which is "
        "reported by its misses). *Median off-line*: over the variants whose answer depends on "
        "where the contact is taken (oblique and off-centre impacts, the spinning rod) — head-on "
        "impacts are exact for every solver and would only pull the median to round-off "
        "(`-`: the cases run have no such variant, e.g. a `--quick` or `--cases` subset of "
        "head-on ones).",
        "",
        "The exact solver's tolerance is a bound on the gap at which it takes the contact, not "
        "the error: on these bodies (0.5 mm to 0.2 m across) its worst error stays within ~20x "
        "the tolerance, and where the time of impact lands closer than it must, a looser "
        "setting can come out more exact than a tighter one (the per-case table below shows "
        "where). The error grows as the tolerance over the bodies' size: two 0.1 mm disks "
        "meeting at a grazing angle (impact parameter 0.9) err by ~3,500x the tolerance at "
        "1e-12 m, 0.5 m disks by round-off; size the tolerance to the smallest body. pymunk's "
        "`iterations` barely change the error of one collision; its steps do.",
        "",
        _energy_note(ms),
        "",
        "| solver | knob | velocity err, worst | velocity err, median off-line | spin err, worst "
        "| energy err, worst | tunnel misses | time/collision (µs) | events | TOI iterations / "
        "solver sweeps | substeps | impulses |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r["setting"]
        missed, total = r["tunnel_missed"]
        lines.append(
            f"| {s.solver} | {s.knob} | {_e(r['vel_max'])} | {_e(r['vel_offline_median'])} | "
            f"{_e(r['spin_max'])} | {_e(r['energy_max'])} | {missed}/{total} | "
            f"{_us(r['seconds'])} | {r['events']:.3g} | {r['iterations']:.3g} | "
            f"{r['substeps']:.3g} | {r['contacts']:.3g} |")
    if plot_name:
        lines += ["", f"![error against time per collision]({plot_name})", "",
                  "Pareto chart (log-log): error against time per collision; the dashed line "
                  "joins the settings that no other setting beats in both; the dotted line is "
                  "1e-9. Labels: exact tolerance (m), fixed and pymunk steps per approach."]
    lines += ["", "## Velocity error per case (median / worst over variants and phases)", "",
              "| solver | knob | " + " | ".join(f"`{c}`" for c in cases) + " |",
              "|---|---|" + "---|" * len(cases)]
    for r in rows:
        s = r["setting"]
        cells = []
        for c in cases:
            med, worst = r["per_case"].get(c, (math.nan, math.nan))
            cells.append(f"{_e(med)} / {_e(worst)}")
        lines.append(f"| {s.solver} | {s.knob} | " + " | ".join(cells) + " |")
    lines += ["", "A tunnel run that misses leaves the puck flying on through the 1 mm rod: "
              "its velocity error is then of order 1. A fixed-step engine (fixed or pymunk) sees a "
              "contact only if a step ends with the puck's centre still short of the rod's core "
              "line (past it, the normal taken from the overlapped pose points through the rod): "
              "every speed with `speed h` below the sum of the radii hits, and with the impact a "
              "fraction `phase` into a step the first miss is at `speed h = (sum of radii) / "
              "(1 - phase)` — pinned in `tests/benchmarks/test_accuracy.py`. The exact solver "
              "hits at any speed.", ""]
    if effects:
        lines += _effects_table(effects)
    lines += ["## Reference cases", ""]
    for name in cases:
        case = get_case(name)
        variants = _measured(ms, name)
        srcs = sorted({v.source for v in variants})
        names = "; ".join(v.name for v in variants)
        of = "" if len(variants) == len(case.variants) else f" of {len(case.variants)}"
        lines.append(f"- `{name}` ({len(variants)}{of} variants: {names}): {case.title}. "
                     f"Answer: {'; '.join(srcs)}.")
    lines.append("")
    return "\n".join(lines)


def _phases(ms: list[Measurement]) -> list[float]:
    n = max((len(m.velocity) for m in ms if m.setting.solver != "exact"), default=0)
    return list(QUICK_PHASES if n == len(QUICK_PHASES) else PHASES)


def _measured(ms: list[Measurement], name: str) -> list[Variant]:
    """The variants of case ``name`` this run measured (a --quick run measures some)."""
    measured = {m.variant for m in ms if m.case == name}
    return [v for v in get_case(name).variants if v.name in measured]


def _energy_note(ms: list[Measurement]) -> str:
    """What the energy column rests on: how many of the accuracy variants run lose energy."""
    run = [v for name in dict.fromkeys(m.case for m in ms) if name != "tunnel"
           for v in _measured(ms, name)]
    lossy = [v for v in run if v.scene["materials"]["restitution"] < 1.0]
    return (f"*Energy*: {len(lossy)} of the {len(run)} accuracy variants run have e < 1 "
            "(named `e=...`), so their reference energy is below the incoming; the others keep "
            "it. Every case is frictionless: friction's loss has no closed form here, and is "
            "checked by the property tests instead (`tests/physics/test_impulse.py`: never above "
            "mu j, never reversing the slip, never a gain). The e = 0 variants leave the pair "
            "touching at no normal speed, separating only at second order: there the exact "
            "solver's search takes its second-order bound at once (its first-order one stalled "
            "them into extra events, held or settled substeps until 2026-11-29).")


def _acceptance(rows: list[dict], raw_step: float | None, plain: dict | None = None) -> list[str]:
    exact = [r for r in rows if r["setting"].solver == "exact"]
    ref = [r for r in rows if r["setting"].solver == "pymunk"
           and (r["setting"].steps, r["setting"].iterations) == PYMUNK_REFERENCE]
    if not exact:
        return []
    best = min(exact, key=lambda r: r["setting"].tolerance)
    cases = list(best["per_case"])
    worst = max(max(w for _, w in best["per_case"].values()), best["spin_max"])
    out = ["## Acceptance", "",
           f"- **exact**, tolerance {best['setting'].tolerance:.0e} m: worst relative error in "
           f"velocity and spin over every case ({', '.join(cases)}) = **{_e(worst)}** "
           f"({'<=' if worst <= 1e-9 else 'NOT <='} 1e-9), no tunnel miss, "
           f"**{_us(best['seconds'])} µs** per collision."]
    if ref:
        r = ref[0]
        missed, total = r["tunnel_missed"]
        med, worst_off = r["per_case"].get("offline_disk_rod", (math.nan, math.nan))
        offline = (f"velocity error on the off-line disk-rod impacts {_e(med)} median, "
                   f"{_e(worst_off)} worst; " if "offline_disk_rod" in r["per_case"] else "")
        out.append(f"- **pymunk**, {PYMUNK_REFERENCE[0]} steps per approach, "
                   f"{PYMUNK_REFERENCE[1]} iterations: {offline}worst over the accuracy "
                   f"cases {_e(r['vel_max'])}; tunnel misses {missed}/{total}; "
                   f"**{_us(r['seconds'])} µs** per collision.")
    if raw_step is not None:
        out.append(f"- For scale: one bare pymunk `Space.step` (no contact, no Python callback, "
                   f"no world around it) costs {raw_step * 1e6:.2f} µs here, so "
                   f"{PYMUNK_REFERENCE[0]} steps of approach alone are "
                   f"{raw_step * 1e6 * PYMUNK_REFERENCE[0]:.0f} µs; the rest of pymunk's time "
                   "per collision is the window after the impact, the per-contact Python callbacks "
                   "(per-pair materials, contact reports) and the world's bookkeeping.")
    if plain is not None and "ratio" in plain:
        out.append(f"- **Like for like**, one collision at a time on the {plain['variants']} "
                   f"off-line disk-rod impacts (medians): a plain pymunk loop (a `Space` with a "
                   f"`Circle` and a `Segment`, `elasticity = sqrt(e)`, slop 0, "
                   f"{PYMUNK_REFERENCE[1]} iterations, no Python callback: as a pymunk user "
                   f"writes it) at {PYMUNK_REFERENCE[0]} steps per approach takes "
                   f"**{_us(plain['plain'])} µs** per collision (worst velocity error "
                   f"{_e(plain['plain_error'])}, the backend's); the exact solver at 1e-12 m, "
                   f"one copy per `world.step` (its ~25 µs of Python per call not spread over "
                   f"copies), **{_us(plain['exact'])} µs**: **{plain['ratio']:.1f}x** faster. "
                   "The table's pymunk times are the backend's, whose per-pair callbacks add to "
                   "Chipmunk's, and its exact times are per copy of 16 stepped at once; "
                   "every case like for like is in the table below."
                   + _fewer_steps(plain))
    out.append("")
    if plain is not None and plain.get("cases"):
        out += _like_for_like_table(plain["cases"])
    return out


def _fewer_steps(plain: dict) -> str:
    """The like-for-like line's tail: the plain loop at fewer steps per approach."""
    fewer = plain.get("fewer")
    if not fewer:
        return ""
    parts = [f"{steps}: {_us(r['plain'])} µs, error {_e(r['median_error'])} median, "
             f"{_e(r['plain_error'])} worst ({r['plain'] / plain['exact']:.2f}x the exact "
             "solver's time)" for steps, r in sorted(fewer.items())]
    return (" The ratio is the choice of steps: the plain loop's time is linear in them (each "
            "`Space.step` about the same, the collision itself a small part), so the honest "
            "comparison is error at equal time. Fewer steps per approach: "
            + "; ".join(parts) + f"; {PYMUNK_REFERENCE[0]}: {_us(plain['plain'])} µs, worst "
            f"{_e(plain['plain_error'])}. At the exact solver's {_us(plain['exact'])} µs "
            f"(error <= {_e(plain['exact_error'])}) plain pymunk affords about "
            f"{_affordable(plain)} steps per approach.")


def _affordable(plain: dict) -> str:
    """Steps per approach the plain loop takes in the exact solver's time (linear fit through
    the timed step counts), rounded."""
    pts = sorted([(s, r["plain"]) for s, r in plain["fewer"].items()]
                 + [(PYMUNK_REFERENCE[0], plain["plain"])])
    xs, ys = np.array([p[0] for p in pts], float), np.array([p[1] for p in pts])
    slope, icpt = np.polyfit(xs, ys, 1)
    return f"{max((plain['exact'] - icpt) / slope, 0.0):.0f}"


def _like_for_like_table(cases: dict[str, dict[str, float]]) -> list[str]:
    out = ["## Like for like, every case", "",
           f"One collision at a time: a plain pymunk loop as a pymunk user writes it (as in the "
           f"acceptance line; the cushions thin static `Segment`s) at {PYMUNK_REFERENCE[0]} "
           f"steps per approach and {PYMUNK_REFERENCE[1]} iterations, first phase, beside the "
           "exact solver at 1e-12 m with one copy per `world.step`. Times are medians over the "
           "case's collisions; *plain / exact* is the median of the per-collision ratios "
           "(range in brackets); errors are each side's worst velocity error. Where the "
           "contact normal does not depend on the pose (the seed's strikes and the cushions, "
           "whose normal is fixed) Chipmunk is at round-off too; an error near 1 or above is "
           "a miss (the tunnel case's fast puck through the 1 mm rod).", "",
           "| case | collisions | plain pymunk, µs | its worst error | exact, µs | its worst "
           "error | plain / exact |", "|---|---|---|---|---|---|---|"]
    for name, r in cases.items():
        out.append(f"| {name} | {r['variants']} | {_us(r['plain'])} | {_e(r['plain_error'])} | "
                   f"{_us(r['exact'])} | {_e(r['exact_error'])} | **{r['ratio']:.1f}x** "
                   f"({r['ratio_min']:.1f}-{r['ratio_max']:.1f}) |")
    out.append("")
    return out


def _effects_table(effects: list[dict]) -> list[str]:
    names = [n for n, _ in EFFECT_SOLVERS]
    blocks = ", ".join(f"{n} `{b}`" for n, b in EFFECT_SOLVERS)
    out = ["## Cost per effect", "",
           f"A walled 1.2 x 0.8 m table, a spinning rod and two pucks (e = 0.9, contact mu = 0.2, "
           f"cloth mu_t = 0.1), {EFFECT_STEPS} steps of {EFFECT_DT} s, B = 1; solvers {blocks}. "
           "Time per `world.step` in µs (impulses per step in brackets). Turning an effect off "
           "also changes the motion (fewer or more contacts); the *at zero strength* rows keep "
           "the motion of the row above them: an effect's code runs only where its parameter "
           "is above zero, so they price a listed effect that does nothing (the same as an "
           "unlisted one, within the noise). Configurations are timed in interleaved rounds, "
           "the fastest of each kept. pymunk's `table_friction` is two Chipmunk joints per "
           "sliding body (a pivot and a gear joint with capped force, as pymunk users write "
           "top-down friction), solved with the contacts in every iteration.", "",
           "| configuration | " + " | ".join(names) + " |",
           "|---|" + "---|" * len(names)]
    for r in effects:
        out.append(f"| {r['label']} | "
                   + " | ".join(f"{_us(r[n])} ({r[n + '_contacts']:.2g})" for n in names) + " |")
    out.append("")
    return out


def plot(ms: list[Measurement], path: Path) -> None:
    """The Pareto chart: worst and median off-line velocity error, and tunnel misses, against
    time per collision."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _summary(ms)
    fig, axes = plt.subplots(1, 3, figsize=(17, 5.4))
    styles = {"exact": ("tab:blue", "o"), "fixed": ("tab:orange", "s"),
              "pymunk": ("tab:green", "^")}
    groups: dict[tuple[str, Any], list[dict]] = {}
    for r in rows:
        s = r["setting"]
        groups.setdefault((s.solver, s.iterations), []).append(r)

    def value(r: dict, key: str) -> float:
        if key == "tunnel":
            missed, total = r["tunnel_missed"]
            return missed / total if total else math.nan
        return max(r[key], ERROR_FLOOR) if math.isfinite(r[key]) else math.nan

    panels = ((axes[0], "vel_max", "worst velocity error (all but tunnel)", True),
              (axes[1], "vel_offline_median", "median velocity error, off-line impacts", True),
              (axes[2], "tunnel", "fraction of tunnel runs missed", False))
    for ax, key, title, logy in panels:
        ax.set_title(title, fontsize=10)
        if not any(math.isfinite(value(r, key)) for r in rows):
            ax.text(0.5, 0.5, "no such runs in this selection", ha="center",
                    transform=ax.transAxes)
            continue
        for (solver, its), group in groups.items():
            color, marker = styles[solver]
            group = [r for r in group if math.isfinite(value(r, key))]
            xs = [r["seconds"] * 1e6 for r in group]
            ys = [value(r, key) for r in group]
            alpha = {None: 1.0, 1: 0.5, 10: 1.0, 100: 0.75}.get(its, 1.0)
            ls = {None: "-", 1: ":", 10: "-", 100: "--"}.get(its, "-")
            label = solver if its is None else f"pymunk, {its} iterations"
            ax.plot(xs, ys, ls, color=color, marker=marker, alpha=alpha, label=label)
            for r, x, y in zip(group, xs, ys, strict=True):
                s = r["setting"]
                if (solver != "pymunk" or its == 10) and (logy or solver != "exact"):
                    txt = f"{s.tolerance:.0e}" if solver == "exact" else f"{s.steps}"
                    ax.annotate(txt, (x, y), textcoords="offset points", xytext=(4, 3),
                                fontsize=7, color=color)
        if logy:
            pts = [(r["seconds"] * 1e6, value(r, key)) for r in rows
                   if math.isfinite(value(r, key))]
            front = pareto_front(pts)
            ax.step([pts[i][0] for i in front], [pts[i][1] for i in front], "k--",
                    where="post", lw=1, alpha=0.6, label="Pareto front")
            ax.axhline(1e-9, color="grey", lw=0.8, ls=":")
            ax.set_yscale("log")
            ax.set_ylabel("|v - v_ref| / V")
        else:
            ax.set_ylim(-0.05, 1.05)
        ax.set_xscale("log")
        ax.set_xlabel("time per collision (µs)")
        ax.grid(True, which="major", alpha=0.3)
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle("SpinStrike solvers: accuracy against time (labels: exact tolerance in m; "
                 "fixed and pymunk steps per approach)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------
# command line
# ---------------------------------------------------------------------------------------------


def main(argv: Sequence[str] | None = None,
         prog: str = "python -m spinstrike.benchmarks.accuracy") -> int:
    """``python -m spinstrike.benchmarks.accuracy [--quick] [--out DIR] ...``; returns an exit
    code. ``prog``: the command's name in its usage and errors (``spinstrike bench accuracy``
    from the CLI)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = argparse.ArgumentParser(prog=prog,
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true",
                        help="a small subset (fewer knobs, 2 variants per case, 2 phases)")
    parser.add_argument("--out", type=Path, default=None,
                        help="directory for accuracy.md and accuracy.png (default: docs/ for a "
                             "full run; a --quick run only prints unless --out is given)")
    parser.add_argument("--cases", nargs="+", choices=CASES, default=None,
                        help="only these cases")
    parser.add_argument("--batch", type=int, default=None, help="copies stepped together")
    parser.add_argument("--min-time", type=float, default=None,
                        help="least wall time (s) spent timing each measurement")
    parser.add_argument("--no-effects", action="store_true", help="skip the cost-per-effect table")
    parser.add_argument("-v", "--verbose", action="store_true", help="progress on stderr")
    args = parser.parse_args(argv)
    if args.batch is not None and args.batch < 1:
        parser.error(f"--batch: must be >= 1 (got {args.batch})")
    if args.min_time is not None and not args.min_time >= 0:  # 0: each timed once
        parser.error(f"--min-time: must be >= 0 s (got {args.min_time})")
    out = out_dir(parser, args.out if args.out is not None else
                  (None if args.quick else Path("docs")), "accuracy.md and accuracy.png")
    log = (lambda msg: print(msg, file=sys.stderr, flush=True)) if args.verbose else None

    load0 = os.getloadavg()[0]
    t0 = time.perf_counter()
    ms = run(quick=args.quick, batch=args.batch, min_time=args.min_time, cases=args.cases, log=log)
    effects = None if args.no_effects else effect_costs(0.05 if args.quick else 0.5)
    raw = raw_pymunk_step(500 if args.quick else 5000)
    plain = like_for_like(0.005 if args.quick else 0.1, args.quick, args.cases)
    seconds = time.perf_counter() - t0
    plot_name = "accuracy.png" if out is not None else None
    text = report(ms, effects, argv, seconds, plot_name, raw, (load0, os.getloadavg()[0]),
                  plain)
    if out is not None:
        (out / "accuracy.md").write_text(text)
        plot(ms, out / "accuracy.png")
        print(f"wrote {out / 'accuracy.md'} and {out / 'accuracy.png'}")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
