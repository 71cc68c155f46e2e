"""``jit.static_if``: a call a literal flag rules out is never typed or compiled (promise 3, what
a scene does not call for costs nothing, also at compile time), a non-literal flag is an
ordinary run-time ``if``, and with ``otherwise`` the call returns a value either way.

Each test compiles kernels of its own (fresh dispatchers), so a callee's ``overloads`` show
exactly what the test's caller compiled."""

import numba
import pytest

from spinstrike.physics.jit import static_if


def _kernels(negate=False, level=1, otherwise=True):
    @numba.njit
    def double(x):
        return 2.0 * x, 1

    @numba.njit
    def same(x):
        return x, -1

    gate = static_if(double, negate=negate, level=level, otherwise=same if otherwise else None)

    @numba.njit
    def literal(x, flag):
        return gate(numba.literally(flag), x)

    @numba.njit
    def runtime(x, flag):
        return gate(flag, x)

    return double, same, literal, runtime


def test_a_literal_flag_compiles_only_the_call_it_allows():
    double, same, literal, _ = _kernels()
    assert literal(3.0, False) == (3.0, -1)
    assert not double.overloads, "ruled out by a literal False, yet compiled"
    assert literal(3.0, True) == (6.0, 1)
    assert double.overloads


@pytest.mark.parametrize("jam, called", [(0, True), (1, False), (2, False)])
def test_a_level_below_which_the_call_is_made(jam, called):
    """The hold's gate: called only at the ``jam`` level 0 (one pair), as
    ``static_if(_try_hold, negate=True, level=LEVEL_CAN_JAM, otherwise=_no_hold)``."""
    double, same, literal, _ = _kernels(negate=True, level=1)
    assert literal(3.0, jam) == ((6.0, 1) if called else (3.0, -1))
    assert bool(double.overloads) == called
    assert bool(same.overloads) == (not called)


def test_a_runtime_flag_is_an_ordinary_if():
    double, same, _, runtime = _kernels()
    assert runtime(3.0, True) == (6.0, 1)
    assert runtime(3.0, False) == (3.0, -1)  # the same compiled code, the other branch
    assert len(runtime.overloads) == 1


def test_without_otherwise_the_call_returns_none():
    double, _, literal, _ = _kernels(otherwise=False)
    assert literal(3.0, True) is None
    assert literal(3.0, False) is None
    assert len(double.overloads) == 1


COLD = """
import os, pathlib, sys
import gymnasium as gym
import spinstrike
env = gym.make(sys.argv[1])
env.reset(seed=0)
env.action_space.seed(0)
for _ in range(50):
    if any(env.step(env.action_space.sample())[2:4]):
        env.reset()
print(sorted(p.name.split("-")[0] for p in
             pathlib.Path(os.environ["SPINSTRIKE_CACHE_DIR"]).rglob("*.nbi")))
"""


def _cold_run(script, tmp_path, *args):
    """The last line ``script`` prints, run with ``args`` in a fresh process with an empty
    kernel cache (``SPINSTRIKE_CACHE_DIR`` under ``tmp_path``)."""
    import os
    import subprocess
    import sys

    env = dict(os.environ, SPINSTRIKE_CACHE_DIR=str(tmp_path / "cache"), SPINSTRIKE_QUIET="1")
    out = subprocess.run([sys.executable, "-c", script, *args], env=env, capture_output=True,
                         text=True, timeout=900, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout.strip().splitlines()[-1]


@pytest.mark.slow
@pytest.mark.parametrize("env_id, holds, flat", [("SpinStrike/RodSpinControl-v0", False, True),
                                                 ("SpinStrike/RodSpin-v0", True, False),
                                                 ("SpinStrike/PuckSpeedControl-v0", False, False)])
def test_envs_compile_only_the_code_their_scene_can_run(env_id, holds, flat, tmp_path):
    """From the user's side, in a fresh process with an empty kernel cache (~40 s each): a
    walled control env (``jam`` level can-jam) never compiles the sustained-contact hold
    (``solvers._hold``; it cost ~11 s of its first-run compile, 55 -> 44 CPU s), the one-pair
    RodSpin-v0, whose e = 0 strikes hold, does. Only a scene with a rod and a cushion or two
    rods compiles the flat-pair code (``impulse.resolve_flat``, ``events.flat_approach``):
    RodSpin-v0's rod meets only a disk, PuckSpeedControl-v0 has no rod. The cache's files name
    what was compiled."""
    import ast

    compiled = ast.literal_eval(_cold_run(COLD, tmp_path, env_id))
    assert "solvers.exact_element" in compiled  # the cache saw the solver compile
    assert ("solvers._hold" in compiled) == holds
    assert ("impulse.resolve_flat" in compiled) == flat
    assert ("events.flat_approach" in compiled) == flat


COLD_WORLD = """
import os, pathlib, sys
from spinstrike import physics
from spinstrike.benchmarks.speed import _many_pucks_scene
world = physics.World(_many_pucks_scene(9))
for _ in range(5):
    world.step(0.02)
print(world.flags.jam, sorted(p.name.split("-")[0] for p in
                              pathlib.Path(os.environ["SPINSTRIKE_CACHE_DIR"]).rglob("*.nbi")))
"""


@pytest.mark.slow
def test_a_many_body_world_compiles_the_calendar_not_the_scan(tmp_path):
    """From the user's side, a fresh process with an empty kernel cache (~60 s): nine pucks
    (the ``jam`` level ``LEVEL_MANY_BODIES``) are stepped on the calendar
    (``exact_many_element``). The scan (``exact_element``), its whole-step search and the hold
    are not compiled: a test at the scan's top did not keep numba from compiling its body (a
    named constant is not pruned; 98 -> 64 CPU s of the first run)."""
    import ast

    from spinstrike.physics.layout import LEVEL_MANY_BODIES

    jam, rest = _cold_run(COLD_WORLD, tmp_path).split(" ", 1)
    compiled = ast.literal_eval(rest)
    assert int(jam) == LEVEL_MANY_BODIES
    assert {"solvers.exact_many_element", "solvers._predict", "solvers._first"} <= set(compiled)
    assert not {"solvers.exact_element", "solvers._search_all", "solvers._hold"} & set(compiled)


COLD_FILMED = """
import os, pathlib
import gymnasium as gym
import spinstrike
env = gym.make("SpinStrike/RodSpin-v0", render_mode="rgb_array")
env.reset(seed=0)
env.action_space.seed(0)
env.step(env.action_space.sample())  # the traced strike (what a video films)
frames = env.render()
vec = gym.make_vec("SpinStrike/RodSpin-v0", num_envs=2, vectorization_mode="vector_entry_point")
vec.reset(seed=0)
vec.step(vec.action_space.sample())  # the untraced strike
print(len(frames), sorted(p.name.split("-")[0] for p in
                          pathlib.Path(os.environ["SPINSTRIKE_CACHE_DIR"]).rglob("*.nbc")))
"""


@pytest.mark.slow
def test_a_filmed_strike_runs_the_solver_an_unfilmed_one_compiled(tmp_path):
    """From the user's side, a fresh process with an empty kernel cache (~50 s): an env that
    films its strikes (``render_mode="rgb_array"``, the traced strike) and a vector env that
    does not share one compiled solver: the solver functions that take the trace hook are
    compiled once each (an untraced step passes an empty trace, ``solvers.untraced``; None was
    a second specialisation of each: the filmed env alone took 68 -> 49 CPU s to its first
    frame, ~20 s of the first video after a first training run)."""
    import ast

    n_frames, rest = _cold_run(COLD_FILMED, tmp_path).split(" ", 1)
    compiled = ast.literal_eval(rest)  # one entry per compiled signature
    assert int(n_frames) > 1
    assert compiled.count("fast.strike_body") == 2  # traced and untraced
    for name in ("kernels.step_element", "solvers.exact_element", "solvers._settle"):
        assert compiled.count(name) == 1, name


def test_a_call_numba_cannot_inline_is_refused_when_defined():
    """``g(flag, *args)`` with more than 30 arguments is compiled by CPython as a ``*args`` call,
    which numba cannot inline (the error came at the first compile, naming a closure)."""
    def taking(n):
        scope: dict = {}
        params = ", ".join(f"a{i}" for i in range(n))
        exec(f"def fn({params}):\n    return a0\n", scope)  # noqa: S102
        return scope["fn"]

    with pytest.raises(TypeError, match=r"static_if\(fn\): 30 parameters, at most 29"):
        static_if(taking(30))
    static_if(taking(29))
