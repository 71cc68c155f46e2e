"""Simulate only the effects a scene calls for.

1. A scene without an effect gives bit-identical results to one with it at zero strength.
2. A step never executes an unlisted effect's code: the kernels are run as plain Python
   (``NUMBA_DISABLE_JIT=1``) in a subprocess under a tracer that counts each effect's
   functions (and the fixed solver's inline cloth friction), on the exact and fixed solvers and
   the many-body event calendar. The effects' flags are not what keeps that code from running
   (it is skipped where its parameter is zero too, which an unlisted effect's always is): the
   promise is about the code, and the tracer watches the code.
"""

import copy
import json
import os
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
import pytest

from spinstrike import physics

SCENE = {  # an unbounded table: a size is the 'walls' effect's parameter (_with adds it)
    "effects": ["rotation"],
    "materials": {"restitution": 0.8},
    "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1,
         "angle": 1.2, "omega": 2.0},
        {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.05,
         "position": [-0.5, 0.1], "velocity": [3.0, 0.2]},
        {"name": "mallet", "shape": "disk", "radius": 0.04, "mass": 0.2, "driven": True,
         "position": [0.5, -0.3], "velocity": [-0.5, 0.4]},
    ],
}


def _run(scene, steps=60, dt=0.01):
    world = physics.World(scene)
    world.set_force("mallet", [0.5, 0.3])
    out = []
    for _ in range(steps):
        world.step(dt)
        out.append(world.get_state()["state"].copy())
    return np.array(out)


def _with(effect, **extra):
    s = copy.deepcopy(SCENE)
    s["effects"] = s["effects"] + [effect]
    for key, value in extra.items():
        s.setdefault(key, {}).update(value)
    return s


@pytest.mark.parametrize("effect,zero", [
    ("contact_friction", {"materials": {"friction": 0.0}}),
    ("table_friction", {"table": {"friction": 0.0}}),
    ("walls", {"table": {"size": [50.0, 50.0]}}),
])
def test_effect_off_equals_effect_on_at_zero_strength(effect, zero):
    off = _run(SCENE)
    on = _run(_with(effect, **zero))
    assert np.array_equal(off, on)


HELD = {  # e = 0: the puck stays pressed on the turning rod, a contact the exact solver holds
    "effects": ["rotation"],
    "materials": {"restitution": 0.0},
    "bodies": [
        {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.02, "mass": 0.1,
         "omega": 10.0},
        {"name": "puck", "shape": "disk", "radius": 0.03, "mass": 0.1,
         "position": [0.15, 0.0401], "velocity": [0.0, -0.5]},
    ],
}


@pytest.mark.parametrize("effect,zero", [
    ("contact_friction", {"materials": {"friction": 0.0}}),
    ("table_friction", {"table": {"friction": 0.0}}),
])
def test_a_held_contact_is_held_with_an_effect_at_zero_strength(effect, zero):
    """A one-pair world holds a sustained e = 0 contact as a constraint; listing
    ``contact_friction`` (at mu = 0) compiled that hold out, so 15 of 100 steps were settled by
    fixed substeps instead and the rod's spin differed by 2.5e-3 rad/s. In the envs: RodSpin at
    e = 0 with ``contact_friction`` at mu = 0 gave other rewards in 132 of 300 random strikes."""
    listed = copy.deepcopy(HELD)
    listed["effects"].append(effect)
    for key, value in zero.items():
        listed.setdefault(key, {}).update(value)
    runs = []
    for scene in (HELD, listed):
        world = physics.World(scene)
        states, settled = [], 0
        for _ in range(100):
            world.step(0.01)
            states.append(world.get_state()["state"].copy())
            settled += int(world.last_step.fallback[0])
        runs.append((np.array(states), settled))
    (off, off_settled), (on, on_settled) = runs
    assert off_settled == on_settled == 0
    assert np.array_equal(off, on)


def test_effects_change_results_when_on():
    base = _run(SCENE)
    assert not np.array_equal(base, _run(_with("contact_friction", materials={"friction": 0.5})))
    assert not np.array_equal(base, _run(_with("table_friction", table={"friction": 0.2})))
    assert not np.array_equal(base, _run(_with("walls", table={"size": [1.6, 1.0]})))


TRACE = textwrap.dedent("""
    import inspect, json, sys
    import spinstrike.physics.contacts, spinstrike.physics.impulse, spinstrike.physics.motion
    import spinstrike.physics.solvers
    from spinstrike import physics
    watched = {"contact_friction": physics.impulse._friction.__code__,
               "table_friction": physics.motion.slide.__code__,
               "table_friction_spin": physics.motion.spin_down.__code__,
               "walls": physics.contacts.capsule_wall.__code__,
               "impulse": physics.impulse.resolve.__code__,
               "calendar": physics.solvers._many_events.__code__}
    codes = {v: k for k, v in watched.items()}
    counts = dict.fromkeys(watched, 0)
    # the fixed solver's cloth friction is inline in its kick: count the lines that read the
    # friction's decelerations
    kick = physics.solvers._kick
    lines, first = inspect.getsourcelines(kick)
    friction_lines = {first + i for i, text in enumerate(lines)
                      if "FRICTION_DECEL" in text or "SPIN_DECEL" in text}
    assert len(friction_lines) == 2, friction_lines
    counts["table_friction_kick"] = 0
    def in_kick(frame, event, arg):
        if event == "line" and frame.f_lineno in friction_lines:
            counts["table_friction_kick"] += 1
        return in_kick
    def tracer(frame, event, arg):
        if event == "call":
            name = codes.get(frame.f_code)
            if name is not None:
                counts[name] += 1
            if frame.f_code is kick.__code__:
                return in_kick
        return None
    scene, solver = json.loads(sys.argv[1]), json.loads(sys.argv[2])
    world = physics.World(scene, solver=solver)
    if "mallet" in world.names:
        world.set_force("mallet", [0.5, 0.3])
    sys.settrace(tracer)
    for _ in range(40):
        world.step(0.01)
    sys.settrace(None)
    print(json.dumps(counts))
""")

#: the exact solver's many-body event calendar runs from 8 bodies: a row of pucks and the rod
MANY = copy.deepcopy(SCENE)
MANY["bodies"] += [{"name": f"p{i}", "shape": "disk", "radius": 0.03, "mass": 0.05,
                    "position": [-0.45 + 0.1 * i, 0.4], "velocity": [(-1) ** i * 1.5, -0.3]}
                   for i in range(8)]
SOLVERS = [{"mode": "exact"}, {"mode": "fixed", "substeps": 20}]


def _trace(scene, solver):
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    # outside the repository, where only the installed names import
    out = subprocess.run([sys.executable, "-c", TRACE, json.dumps(scene), json.dumps(solver)],
                         env=env, capture_output=True, text=True, check=True, timeout=600,
                         cwd=tempfile.gettempdir())
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("scene", [SCENE, MANY], ids=["three bodies", "eleven bodies"])
@pytest.mark.parametrize("solver", SOLVERS, ids=["exact", "fixed"])
def test_unlisted_effects_never_run(scene, solver):
    counts = _trace(scene, solver)
    assert counts["impulse"] > 0  # the strike happens, so the tracer sees the kernels run
    assert (counts["calendar"] > 0) == (scene is MANY and solver["mode"] == "exact")
    assert counts["contact_friction"] == 0
    assert counts["table_friction"] == 0 and counts["table_friction_spin"] == 0
    assert counts["table_friction_kick"] == 0
    assert counts["walls"] == 0


@pytest.mark.parametrize("bodies", [SCENE["bodies"], MANY["bodies"]],
                         ids=["three bodies", "eleven bodies"])
@pytest.mark.parametrize("solver", SOLVERS, ids=["exact", "fixed"])
def test_listed_effects_do_run(bodies, solver):
    """The tracer's counterpart: every effect's code is seen to run where it is listed (so a
    zero above is not a tracer that sees nothing)."""
    scene = _with("contact_friction", materials={"friction": 0.4}) | {
        "effects": ["rotation", "walls", "contact_friction", "table_friction"],
        "table": {"size": [1.6, 1.0], "friction": 0.1}, "bodies": bodies}
    counts = _trace(scene, solver)
    assert counts["contact_friction"] > 0
    if solver["mode"] == "fixed":  # its kick slows the bodies itself
        assert counts["table_friction_kick"] > 0
    else:
        assert counts["table_friction"] > 0 and counts["table_friction_spin"] > 0
    assert counts["walls"] > 0
