"""Fuzzing (hypothesis): random scenes stepped directly, and the registered envs built with random
constructor arguments and driven by random actions.

A failure is: a NaN or inf anywhere (state, observation, reward, info), an exception other than a
documented validation error (``physics.SceneError``, ``envs.ConfigError``, ``ValueError`` for a
NaN action), a body leaving a walled table, an overlap beyond the tolerance, or a kinetic-energy
gain beyond round-off (1e-12 of the energy per contact) in a scene without applied force.

The default suite runs a small budget; ``-m slow`` runs the big one (its example count comes
from the hypothesis profile: ``HYPOTHESIS_PROFILE=slow`` selects 5000).
"""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from spinstrike import envs, physics
from spinstrike.envs import ConfigError
from spinstrike.envs.strike import PuckSpeedVelocityTask
from spinstrike.physics import SceneError

SMALL = settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
ENV_SMALL = settings(max_examples=12, deadline=None, suppress_health_check=list(HealthCheck))
BIG = settings(deadline=None, suppress_health_check=list(HealthCheck))  # profile's count

#: relative kinetic-energy gain allowed per contact
ROUNDOFF = 1e-12

# ---------------------------------------------------------------------------------------------
# scenes, stepped directly
# ---------------------------------------------------------------------------------------------

body = st.fixed_dictionaries({
    "shape": st.sampled_from(["disk", "rod"]),
    "size": st.floats(0.005, 0.12),
    "thickness": st.one_of(st.just(0.0), st.floats(0.0, 0.04)),
    "log_mass": st.floats(-6, 6),
    "angle": st.floats(-math.pi, math.pi),
    "velocity": st.tuples(st.floats(-20, 20), st.floats(-20, 20)),
    "omega": st.floats(-100, 100),
    "kind": st.sampled_from(["free"] * 6 + ["static", "pivot"]),
})

scene_case = st.fixed_dictionaries({
    "bodies": st.lists(body, min_size=1, max_size=4),
    "e": st.one_of(st.just(1.0), st.just(0.0), st.floats(0.0, 1.0)),
    "mu": st.one_of(st.just(0.0), st.floats(0.0, 3.0)),
    "solver": st.sampled_from(["exact", "exact", "fixed"]),
    "dt": st.sampled_from([1e-4, 0.01, 0.1, 1.0]),
    "steps": st.integers(1, 6),
})

TABLE = (1.2, 0.8)
CELLS = [(-0.45, 0.2), (-0.15, -0.2), (0.15, 0.2), (0.45, -0.2)]  # 0.3 m apart: no overlap


def _scene(s):
    bodies = []
    for i, b in enumerate(s["bodies"]):
        spec = {"name": f"b{i}", "shape": b["shape"], "position": list(CELLS[i]),
                "angle": b["angle"]}
        if b["shape"] == "disk":
            spec["radius"] = b["size"]
        else:
            spec.update(length=2 * b["size"], thickness=b["thickness"])
        if b["kind"] == "static":
            spec["static"] = True
        else:
            spec["mass"] = 10.0 ** b["log_mass"]
            spec["omega"] = b["omega"]
            if b["kind"] == "pivot":
                spec["pivot"] = True
            else:
                spec["velocity"] = list(b["velocity"])
        bodies.append(spec)
    effects = ["rotation", "walls"] + (["contact_friction"] if s["mu"] > 0 else [])
    return {"table": {"size": list(TABLE)}, "effects": effects,
            "materials": {"restitution": s["e"], "friction": s["mu"]}, "bodies": bodies}


def _check_scene(s):
    solver = None if s["solver"] == "exact" else {"mode": "fixed", "substeps": 50}
    world = physics.World(_scene(s), solver=solver)
    e0 = world.kinetic_energy()[0]
    contacts = 0
    hw = np.array(TABLE) / 2
    for _ in range(s["steps"]):
        e_before = world.kinetic_energy()[0]
        world.step(s["dt"])
        n = int(world.last_step.contacts[0])
        contacts += n
        state = world.get_state()["state"]
        assert np.all(np.isfinite(state)), "NaN or inf in the state"
        e1 = world.kinetic_energy()[0]
        assert e1 <= e_before * (1 + ROUNDOFF * max(n, 1)) + 1e-300, \
            f"energy gain {e1 / e_before - 1:.3e} over {n} contacts"
        # a centre past a cushion by more than the tolerance (a zero-thickness rod lying flat on
        # the cushion has its centre on it: 5.6e-17 m past it after a plastic hit, an overlap
        # within the tolerance that the gap check below judges, not an escape)
        assert np.all(np.abs(world.state.positions[0]) <= hw + world.tolerance), \
            "a body left the table"
        if s["solver"] == "exact" and world.gaps().size:
            assert world.gaps().min() >= -world.tolerance, f"overlap {-world.gaps().min():.3e} m"
    elastic = s["e"] == 1.0 and s["mu"] == 0.0
    if elastic and s["solver"] == "exact" and not world.last_step.fallback[0]:
        assert abs(world.kinetic_energy()[0] - e0) <= ROUNDOFF * max(contacts, 1) * e0


def _disk(size, log_mass, velocity):
    return {"shape": "disk", "size": size, "thickness": 0.0, "log_mass": log_mass, "angle": 0.0,
            "velocity": velocity, "omega": 0.0, "kind": "free"}


#: cases the big budget found, kept in the default suite: a zero-thickness rod driven flat onto
#: the top cushion in a corner (its centre ends 5.6e-17 m past the cushion); four plastic disks
#: piled into a corner and settled (8.8e-9 m of overlap handed on, also in
#: tests/physics/test_extreme_inputs.py)
FOUND = [
    {"bodies": [_disk(0.0625, 0.0, (0.0, 0.0)),
                {**_disk(0.0625, 0.0, (11.0, 8.0)), "shape": "rod"}],
     "e": 0.0, "mu": 0.0, "solver": "exact", "dt": 0.1, "steps": 1},
    {"bodies": [_disk(0.09375, -1.0, (9.75, 2.0)), _disk(0.0546875, 0.0, (7.0, 8.0)),
                _disk(0.0625, -1.0, (-2.0, 3.0)), _disk(0.0625, 0.0, (0.0, 8.0))],
     "e": 0.0, "mu": 0.0, "solver": "exact", "dt": 0.1, "steps": 1},
]


@SMALL
@given(scene_case)
@example(FOUND[0])
@example(FOUND[1])
def test_fuzz_scenes(s):
    _check_scene(s)


@pytest.mark.slow
@BIG
@given(scene_case)
def test_fuzz_scenes_big(s):
    _check_scene(s)


# ---------------------------------------------------------------------------------------------
# envs: random constructor arguments, random actions
# ---------------------------------------------------------------------------------------------

log_mass = st.floats(-3, 3).map(lambda x: 10.0**x)
maybe = st.none().__or__  # st.none() | strategy

solvers = st.sampled_from([None, {"mode": "exact", "tolerance": 1e-7},
                           {"mode": "fixed", "substeps": 20}])
strike_kwargs = st.fixed_dictionaries({}, optional={
    "restitution": st.floats(0.0, 1.0),
    "friction": st.floats(0.0, 2.0),
    "striker_mass": log_mass,
    "target_mass": log_mass,
    "speed_range": st.tuples(st.floats(0.01, 5.0), st.floats(0.0, 20.0)).map(
        lambda t: (t[0], t[0] + t[1])),
    "approach_max": st.floats(1.0, 89.0),
    "time_cap": st.floats(0.05, 0.5),
    "solver": solvers,
})
rod_kwargs = st.fixed_dictionaries({}, optional={
    "rod_length": st.floats(0.01, 2.0),
    "rod_thickness": st.floats(0.0, 0.1),
    "rod_inertia": st.sampled_from(["capsule", "thin_rod"]),
    "goal": st.sampled_from(["target", "max"]),
})
control_kwargs = st.fixed_dictionaries({}, optional={
    "restitution": st.floats(0.0, 1.0),
    "friction": st.floats(0.0, 2.0),
    "table_friction": st.floats(0.0, 1.0),
    "mallet_mass": log_mass,
    "target_mass": log_mass,
    "dt": st.floats(0.002, 0.1),
    "max_force": st.floats(0.1, 50.0),
    "max_speed": st.floats(0.1, 10.0),
    "solver": solvers,
})


@st.composite
def env_case(draw):
    env_id = draw(st.sampled_from(list(envs.ENV_IDS)))
    if "Control" in env_id:
        kwargs = draw(control_kwargs)
    else:
        kwargs = draw(strike_kwargs)
        if env_id == "SpinStrike/RodSpin-v0":
            kwargs.update(draw(rod_kwargs))
    n_act = 2 if "Control" in env_id else 3
    action = st.lists(st.floats(-3.0, 3.0), min_size=n_act, max_size=n_act)
    actions = draw(st.lists(action, min_size=1, max_size=6))
    return env_id, kwargs, actions


def _finite_info(info):
    for key, value in info.items():
        arr = np.asarray(value)
        if arr.dtype.kind in "fc":
            assert np.all(np.isfinite(arr)), f"info[{key!r}] is not finite: {value}"


def _check_env(env_id, kwargs, actions):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        env = gym.make(env_id, **kwargs)
    task = env.unwrapped.task
    world = task.world
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    control = "Control" in env_id
    for a in actions:
        a = np.asarray(a, dtype=np.float32)
        ke_launch = None
        if not control:
            lo, hi = task.cfg.speed_range
            if isinstance(task, PuckSpeedVelocityTask):  # v1: the velocity as a vector
                speed = float(task.velocity_of(np.clip(a[None, 1:3], -1, 1).astype(float),
                                               (lo, hi))[1][0])
            else:
                speed = lo + 0.5 * (float(np.clip(a[2], -1, 1)) + 1.0) * (hi - lo)
            ke_launch = 0.5 * world.mass[0, task.js] * speed**2 + world.kinetic_energy()[0]
        obs, reward, terminated, truncated, info = env.step(a)
        assert env.observation_space.contains(obs)
        assert math.isfinite(reward)
        _finite_info(info)
        assert np.all(np.isfinite(world.get_state()["state"]))
        if control:
            hw = world.table_half_size[0]
            assert np.all(np.abs(world.state.positions[0]) <= hw + 1e-9), "escaped the table"
        else:  # no applied force: the strike never adds energy
            n = max(int(info["n_contacts"]), 1)
            assert world.kinetic_energy()[0] <= ke_launch * (1 + ROUNDOFF * n)
        if terminated or truncated:
            env.reset()
    # a NaN action is a ValueError naming the action
    with pytest.raises(ValueError, match="action"):
        env.step(np.full(env.action_space.shape, np.nan, dtype=np.float32))
    env.close()


@ENV_SMALL
@given(env_case())
def test_fuzz_envs(case):
    _check_env(*case)


@pytest.mark.slow
@BIG
@given(env_case())
def test_fuzz_envs_big(case):
    _check_env(*case)


# any value for any argument: either the env is built, or one ConfigError names the argument
junk = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True),
                 st.text(max_size=5), st.lists(st.floats(-2, 2), max_size=3),
                 st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
ARGS = sorted({*envs.config.RodSpinConfig.model_fields, *envs.config.ControlConfig.model_fields,
               *envs.config.PuckSpeedConfig.model_fields, "bogus"})


@SMALL
@given(st.sampled_from(list(envs.ENV_IDS)), st.sampled_from(ARGS), junk)
def test_fuzz_constructor_arguments(env_id, key, value):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            env = gym.make(env_id, **{key: value})
            env.reset(seed=0)
            env.step(env.action_space.sample())
            env.close()
    except (ConfigError, SceneError) as exc:
        assert key in str(exc) or "scene" in str(exc), f"error does not name {key!r}: {exc}"
