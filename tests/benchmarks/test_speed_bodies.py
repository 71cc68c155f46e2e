"""The speed benchmark's bodies sweep, as a user runs it alone (``--section bodies``): it writes
the bodies section of ``speed.md`` and its plot, with exact, fixed-solver and raw pymunk rows
from the same run, and a second run replaces that section instead of adding one."""

from __future__ import annotations

from spinstrike.benchmarks import speed


def test_the_bodies_section_is_written_and_replaced(tmp_path):
    (tmp_path / "speed.md").write_text("# Speed\n\nkept above\n")
    args = ["--section", "bodies", "--bodies", "8", "16", "--out", str(tmp_path), "--quick"]
    assert speed.main(args) == 0
    assert speed.main(args) == 0
    text = (tmp_path / "speed.md").read_text()
    assert text.startswith("# Speed\n\nkept above\n")
    assert text.count(speed._BODIES_BEGIN) == 1 and text.count(speed._BODIES_END) == 1
    assert f"the fastest of {speed.BODY_REPEATS} runs" in text
    assert "load average" in text
    rows = [line.split("|")[1:-1] for line in text.splitlines() if line.startswith("| 8 |")
            or line.startswith("| 16 |")]
    assert [int(r[0]) for r in rows] == [8, 16]
    for r in rows:
        exact, p10, ratio = float(r[1]), float(r[5]), float(r[6])
        assert exact > 0 and p10 > 0
        assert abs(ratio - exact / p10) <= 0.01 + 0.01 * ratio
        fixed, fixed_ratio = float(r[7]), float(r[8])  # the fixed solver's column
        assert fixed > 0 and abs(fixed_ratio - fixed / p10) <= 0.01 + 0.01 * fixed_ratio
    assert (tmp_path / "speed_bodies.png").stat().st_size > 0


def test_a_quick_run_only_prints(tmp_path, monkeypatch, capsys):
    """``spinstrike bench speed --quick`` from a clone must not replace the committed
    docs/speed.md with a quick run's table (as ``bench accuracy --quick`` does not)."""
    from spinstrike.agents import cli

    monkeypatch.chdir(tmp_path)
    assert cli.main(["bench", "speed", "--section", "bodies", "--bodies", "8", "--quick"]) == 0
    assert list(tmp_path.iterdir()) == []
    out = capsys.readouterr().out
    assert "| 8 |" in out and "printed only" in out


def test_bad_options_are_one_line_before_anything_runs(tmp_path, capsys):
    """``--bodies -4`` was a ``math domain error`` traceback and ``--bodies 0`` a scene
    validation message; an ``--out`` naming a file, a ``FileExistsError`` traceback."""
    import pytest

    from spinstrike.agents.cli import main

    (tmp_path / "f").write_text("")
    for args, words in ((["--bodies", "-4"], "--bodies: each must be >= 1"),
                        (["--bodies", "0"], "--bodies: each must be >= 1"),
                        (["--out", str(tmp_path / "f")], "is a file; give a directory")):
        with pytest.raises(SystemExit) as exit_:
            main(["bench", "speed", "--quick", "--section", "bodies", *args])
        assert exit_.value.code == 2 and words in capsys.readouterr().err


def test_a_loaded_machine_is_named_before_the_rates(monkeypatch, capsys):
    import os

    for load, warned in ((0.1, False), (64.0, True)):
        monkeypatch.setattr(os, "getloadavg", lambda x=load: (x, x, x))
        assert speed.main(["--section", "bodies", "--bodies", "2", "--quick"]) == 0
        assert ("other work shares them" in capsys.readouterr().err) is warned


def test_without_sb3_a_quick_run_skips_the_ppo_row_and_a_full_run_refuses_first(
        tmp_path, monkeypatch, capsys):
    """The 'bench' extra has no torch: ``spinstrike bench speed --quick`` there measured for four
    minutes and then failed on the PPO env-share row. A quick run now says up front that it skips
    that row and prints the rest; a run that writes speed.md (whose table has the row) refuses
    before it measures anything. (The rates themselves are stubbed: this is about the flow.)"""
    import sys

    import pytest

    from spinstrike.agents.cli import main

    monkeypatch.setitem(sys.modules, "stable_baselines3", None)  # as if not installed
    monkeypatch.chdir(tmp_path)
    # refused before anything is written: no output folder either (a refused run left an
    # empty docs/ in the current directory); the error names the command typed
    for out in (["--out", str(tmp_path / "out")], []):
        with pytest.raises(SystemExit) as exit_:
            main(["bench", "speed", *out])
        captured = capsys.readouterr()
        assert exit_.value.code == 2 and "spinstrike[train]" in captured.err
        assert captured.err.splitlines()[-1].startswith("spinstrike bench speed: error: ")
        assert captured.out == "" and list(tmp_path.iterdir()) == []

    def share(steps):
        raise AssertionError("the PPO row ran without stable_baselines3")

    monkeypatch.setattr(speed, "_ppo_env_share", share)
    monkeypatch.setattr(speed, "_vector_rate", lambda *a, **k: (1000.0, 0.5))
    monkeypatch.setattr(speed, "_sync_pymunk_rate", lambda *a, **k: (10.0, 0.5))
    monkeypatch.setattr(speed, "_cartpole_rate", lambda *a, **k: 2000.0)
    monkeypatch.setattr(speed, "_single_rate", lambda *a, **k: (100.0, 0.5))
    monkeypatch.setattr(speed, "_startup_times", lambda ids: {i: (1.0, 2.0, 0.1, 0.2) for i in ids})
    monkeypatch.setattr(speed, "_world_step_time", lambda scene, b, *a: (1e-6 * b, 0.5))
    monkeypatch.setattr(speed, "bodies_sweep", lambda *a: [])
    assert main(["bench", "speed", "--quick"]) == 0
    captured = capsys.readouterr()
    assert "PPO env-share row is skipped" in captured.err
    assert "native vector env (random) / SyncVectorEnv on pymunk: 100.0x" in captured.out
    assert "PPO env share" not in captured.out


def test_the_env_rates_time_no_bookkeeping(monkeypatch):
    """Walk W28b F2: the rates read ``world.last_step`` after every timed step, whose first read
    builds its stats (~10 us, half of an exact control step), so the rows charged the harness's
    own bookkeeping to the env (and to B = 1 of the batch sweep). Contacts are counted in the
    untimed warm-up alone."""
    from spinstrike.physics import World

    reads = [0]
    real = World.last_step

    def counted(self):
        reads[0] += 1
        return real.fget(self)

    monkeypatch.setattr(World, "last_step", property(counted))
    rate, per_step = speed._single_rate(speed.CONTROL, 40, 3)
    assert reads[0] == 40 and rate > 0 and per_step >= 0
    reads[0] = 0
    rate, per_step = speed._vector_rate(speed.CONTROL, 4, 10, 3)
    assert reads[0] == 10 and rate > 0 and per_step >= 0
    reads[0] = 0
    rate, per_step = speed._sync_pymunk_rate(2, 5, 2)
    assert reads[0] == 10 and rate > 0 and per_step >= 0
    reads[0] = 0
    scene = speed._many_pucks_scene(4)
    seconds, per_step = speed._world_step_time(scene, 2, 5, 3)
    assert reads[0] == 5 and seconds > 0 and per_step >= 0


def test_chipmunk_alone_replays_the_pymunk_envs_own_physics():
    """The 'Chipmunk alone' row (walk W29a F4) times the env's own space under the env's own
    forces and nothing else: replayed from reset, it ends where the env's steps ended, bit for
    bit (so the row prices the same physics, without SpinStrike's Python around it)."""
    import gymnasium as gym

    env = gym.make(speed.CONTROL, solver={"mode": "pymunk"})
    world = env.unwrapped.world
    forces = speed._recorded_forces(env, 60)
    assert any(f != (0.0, 0.0) for row in forces for f in row)
    expected = world.state.positions[0].copy()
    env.reset(seed=0)
    assert speed._replay_forces(world, forces) > 0.0
    space = world.backend.space(0)
    got = [next(s.body.position for s in space.shapes if s.collision_type == i)
           for i in range(world.n_bodies) if not world.static[i]]
    want = [tuple(expected[i]) for i in range(world.n_bodies) if not world.static[i]]
    assert [tuple(p) for p in got] == want
    assert speed._chipmunk_alone_rate(20, 1) > 0.0
