"""Simulate only the effects a scene calls for.

1. A scene without an effect gives bit-identical results to one with it at zero strength.
2. A step never executes an unlisted effect's code: the kernels are run as plain Python
   (``NUMBA_DISABLE_JIT=1``) in a subprocess under a call profiler that counts each effect's
   functions.
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


def test_effects_change_results_when_on():
    base = _run(SCENE)
    assert not np.array_equal(base, _run(_with("contact_friction", materials={"friction": 0.5})))
    assert not np.array_equal(base, _run(_with("table_friction", table={"friction": 0.2})))
    assert not np.array_equal(base, _run(_with("walls", table={"size": [1.6, 1.0]})))


TRACE = textwrap.dedent("""
    import json, sys
    import spinstrike.physics.contacts, spinstrike.physics.impulse, spinstrike.physics.motion
    from spinstrike import physics
    watched = {"contact_friction": physics.impulse._friction.__code__,
               "table_friction": physics.motion.slide.__code__,
               "table_friction_spin": physics.motion.spin_down.__code__,
               "walls": physics.contacts.capsule_wall.__code__,
               "impulse": physics.impulse.resolve.__code__}
    codes = {v: k for k, v in watched.items()}
    counts = dict.fromkeys(watched, 0)
    def prof(frame, event, arg):
        if event == "call" and frame.f_code in codes:
            counts[codes[frame.f_code]] += 1
    scene = json.loads(sys.argv[1])
    world = physics.World(scene)
    world.set_force("mallet", [0.5, 0.3])
    sys.setprofile(prof)
    for _ in range(40):
        world.step(0.01)
    sys.setprofile(None)
    print(json.dumps(counts))
""")


def _trace(scene):
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    # outside the repository, where only the installed names import
    out = subprocess.run([sys.executable, "-c", TRACE, json.dumps(scene)], env=env,
                         capture_output=True, text=True, check=True, timeout=300,
                         cwd=tempfile.gettempdir())
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_unlisted_effects_never_run():
    counts = _trace(SCENE)
    assert counts["impulse"] > 0  # the strike happens, so the tracer sees the kernels run
    assert counts["contact_friction"] == 0
    assert counts["table_friction"] == 0 and counts["table_friction_spin"] == 0
    assert counts["walls"] == 0


def test_listed_effects_do_run():
    scene = _with("contact_friction", materials={"friction": 0.4}) | {
        "effects": ["rotation", "walls", "contact_friction", "table_friction"],
        "table": {"size": [1.6, 1.0], "friction": 0.1}}
    counts = _trace(scene)
    assert counts["contact_friction"] > 0
    assert counts["table_friction"] > 0 and counts["table_friction_spin"] > 0
    assert counts["walls"] > 0
