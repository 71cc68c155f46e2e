"""The accuracy benchmark: its reference answers, and that each solver's knob does what it claims.

Physics only (errors against known answers), never timings.
"""

import math
import re
import time
from itertools import pairwise

import numpy as np
import pytest

from spinstrike import physics
from spinstrike.benchmarks import accuracy
from spinstrike.benchmarks.accuracy import Setting, errors
from spinstrike.benchmarks.cases import CASES, _Motion, _MpMath, _pair_gap, all_cases, get_case

ALL = [(c.name, v) for c in all_cases() for v in c.variants]
IDS = [f"{name}:{v.name}" for name, v in ALL]


# ---------------------------------------------------------------------------------------------
# the reference answers
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["seed", "rod_wall"])
def test_closed_forms_agree_with_the_independent_impulse_law(name):
    for v in get_case(name).variants:
        d = v.detail
        assert np.abs(d["velocities"] - v.velocities).max() <= 1e-13 * v.speed
        assert np.abs(d["omegas"] - v.omegas).max() * v.length <= 1e-13 * v.speed


def test_disk_disk_contact_time_matches_its_closed_form():
    for v in get_case("disk_disk").variants:
        a, b = v.scene["bodies"]
        dx = b["position"][0] - a["position"][0]
        dy = b["position"][1] - a["position"][1]
        s = a["radius"] + b["radius"]
        t = (dx - math.sqrt(s * s - dy * dy)) / a["velocity"][0]
        assert v.t_contact == pytest.approx(t, rel=1e-14)


@pytest.mark.parametrize("name, v", ALL, ids=IDS)
def test_reference_touches_at_its_contact_time_and_keeps_energy(name, v):
    from spinstrike.benchmarks.cases import Body

    bodies = []
    for b in v.scene["bodies"]:
        rho = b["radius"] if b["shape"] == "disk" else b["thickness"] / 2
        h = 0.0 if b["shape"] == "disk" else b["length"] / 2
        bodies.append(Body(b["name"], b["shape"], b["mass"], 1.0, rho, h,
                           tuple(b["position"]), b["angle"], tuple(b["velocity"]), b["omega"]))
    motions = [_Motion(*B.position, B.angle, *B.velocity, B.omega) for B in bodies]
    half = None
    if "table" in v.scene:
        half = tuple(0.5 * x for x in v.scene["table"]["size"])
    gap = _pair_gap(bodies, motions, v.detail["pair"], half, v.t_contact, _MpMath)
    assert abs(gap) < 1e-14
    assert v.duration < v.t_next
    e = v.scene["materials"]["restitution"]
    if e == 1.0:
        assert v.energy_out == pytest.approx(v.energy_in, rel=1e-13)
    else:
        assert v.energy_out < v.energy_in


# ---------------------------------------------------------------------------------------------
# exact: <= 1e-9 everywhere, round-off where the normal is fixed, error shrinking with tolerance
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name, v", ALL, ids=IDS)
def test_exact_reaches_1e9_on_every_reference_case(name, v):
    (ev, es, ee, hit), = errors(Setting("exact", tolerance=1e-12), v)
    assert hit
    assert ev <= 1e-9 and es <= 1e-9 and ee <= 1e-9


@pytest.mark.parametrize("name, v", [(n, v) for n, v in ALL if v.normal_fixed],
                         ids=[i for i, (_, v) in zip(IDS, ALL, strict=True) if v.normal_fixed])
def test_exact_is_at_round_off_on_translating_head_on_cases_at_any_tolerance(name, v):
    for tol in (1e-3, 1e-6):
        (ev, es, ee, hit), = errors(Setting("exact", tolerance=tol), v)
        assert ev <= 1e-13 and es <= 1e-13 and ee <= 1e-13


TOLERANCES = (1e-3, 1e-5, 1e-7, 1e-9, 1e-11)


@pytest.mark.parametrize("v", get_case("spinning_rod").variants, ids=lambda v: v.name)
def test_exact_error_is_bounded_by_its_tolerance_on_the_spinning_rod(v):
    """The contact is located to a gap in [0, tol]: the error is at most of order tol over the
    bodies' size (here <= 100 tol / 1 m), wherever in that window the root finder lands."""
    for tol in TOLERANCES:
        ev, es, _, hit = errors(Setting("exact", tolerance=tol), v)[0]
        assert hit and ev <= 100 * tol and es <= 100 * tol


def test_exact_error_shrinks_with_tolerance_on_the_spinning_rod():
    worst = [max(errors(Setting("exact", tolerance=t), v)[0][0]
                 for v in get_case("spinning_rod").variants) for t in TOLERANCES]
    assert worst[0] > 1e4 * worst[-1]  # eight decades of tolerance buy at least four of error
    assert worst[-1] < 1e-9


# ---------------------------------------------------------------------------------------------
# fixed and pymunk: more steps, less error (off-line impacts)
# ---------------------------------------------------------------------------------------------

OFFLINE = [v for v in get_case("offline_disk_rod").variants if not v.normal_fixed]


def _median_error(setting):
    return float(np.median([r[0] for v in OFFLINE for r in errors(setting, v)]))


def test_fixed_error_falls_as_it_buys_substeps():
    errs = [_median_error(Setting("fixed", steps=s)) for s in (16, 64, 256)]
    assert errs[0] > 1e-3
    for coarse, fine in pairwise(errs):
        assert fine < coarse / 2  # four times the substeps: at least half the error


def test_pymunk_error_falls_as_it_buys_steps():
    errs = [_median_error(Setting("pymunk", steps=s, iterations=10)) for s in (10, 100, 1000)]
    assert errs[0] > 1e-2  # ~24% worst, a few % median at 10 steps per approach
    for coarse, fine in pairwise(errs):
        assert fine < coarse / 5  # ten times the steps: at least five times less error
    assert errs[-1] > 1e-5  # and still far from the exact solver's 1e-9


def test_fixed_step_solvers_are_exact_on_head_on_impacts():
    """Where the overlapped pose has the true normal and lever arm (seed head-on), the overlap
    costs nothing: the error is round-off for fixed and pymunk alike."""
    v = get_case("seed").variants[1]  # theta = 0, m1/m2 = 1
    for s in (Setting("fixed", steps=16), Setting("pymunk", steps=10, iterations=10)):
        assert max(r[0] for r in errors(s, v)) <= 1e-13


# ---------------------------------------------------------------------------------------------
# (c) tunnelling: exact always hits; fixed and pymunk miss exactly where the step says
# ---------------------------------------------------------------------------------------------

REACH = 0.005 + 0.0005  # puck radius + rod half-thickness, m
H = 1e-3  # step, s
M = 10  # whole steps before the puck reaches the rod's reach


def _tunnel_scene(f, phase):
    """The puck moves f * REACH per step; M steps in, it stops phase * (its step) short of the
    rod's reach, so its next step lands (1 - phase) * step deep into it."""
    d = f * REACH
    x0 = -REACH - phase * d - M * d
    return {
        "effects": ["rotation"],
        "bodies": [
            {"name": "rod", "shape": "rod", "length": 0.4, "thickness": 0.001, "mass": 0.1,
             "angle": math.pi / 2},
            {"name": "puck", "shape": "disk", "radius": 0.005, "mass": 0.05,
             "position": [x0, 0.05], "velocity": [d / H, 0.0]},
        ],
    }, (M + 3) * H


def _predicted_hit(f, phase):
    """A fixed-step engine sees the contact iff a step lands with the centre short of the core
    line (else the normal, taken from the overlapped pose, points through): (1 - phase) f < 1."""
    return (1.0 - phase) * f < 1.0


FACTORS = (0.5, 0.95, 1.3, 1.6, 2.2, 3.0, 4.5, 6.0, 20.0)


@pytest.mark.parametrize("phase", [0.3, 0.8])
@pytest.mark.parametrize("solver", ["fixed", "pymunk"])
def test_fixed_step_solvers_miss_exactly_where_the_step_jumps_the_core(solver, phase):
    hits = []
    for f in FACTORS:
        scene, T = _tunnel_scene(f, phase)
        block = {"mode": solver, "substeps": M + 3}
        world = physics.World(scene, solver=block)
        contacts = world.step(T)
        hits.append(len(contacts) > 0)
        # a miss leaves the puck flying on through the rod, untouched
        if not hits[-1]:
            assert world.state.velocities[0, 1, 0] == pytest.approx(f * REACH / H)
            assert world.state.positions[0, 1, 0] > 0.0
    assert hits == [_predicted_hit(f, phase) for f in FACTORS]
    # every speed below one reach per step hits; the first miss is pinned at 1 / (1 - phase)
    first_miss = next(f for f, h in zip(FACTORS, hits, strict=True) if not h)
    assert first_miss > 1.0 / (1.0 - phase) > max(f for f, h in zip(FACTORS, hits, strict=True) if h
                                                  and f < first_miss)


@pytest.mark.parametrize("f", [0.5, 1.6, 20.0, 1e3, 1e5])
def test_exact_hits_at_every_speed(f):
    scene, T = _tunnel_scene(f, 0.3)
    world = physics.World(scene, solver={"mode": "exact", "tolerance": 1e-9})
    contacts = world.step(T)
    assert len(contacts) == 1
    v = f * REACH / H
    inertia = world.inertia[0, 0]
    j = 2.0 * v / (1 / 0.05 + 1 / 0.1 + 0.05**2 / inertia)  # flat side, lever 0.05 m
    assert contacts.impulse[0] == pytest.approx(j, rel=1e-12)
    assert world.state.velocities[0, 1, 0] == pytest.approx(v - j / 0.05, rel=1e-12)


def test_tunnel_case_misses_in_the_benchmark_follow_the_same_rule():
    """The benchmark's own tunnel case (1 m run-up): at S steps per approach the impact falls a
    fraction ``phase`` into a step, so the step lands (1 - phase) of a step deep: a miss iff
    that is past the core line. Fine steps and exact always hit."""
    v = get_case("tunnel").variants[-1]
    run_up = v.t_contact * v.speed  # distance to touching, m
    for steps in (20, 50, 100):
        runs = errors(Setting("fixed", steps=steps), v)
        for phase, (ev, _, _, hit) in zip(accuracy.PHASES, runs, strict=True):
            f = run_up / (steps + phase) / REACH
            assert hit == _predicted_hit(f, phase)
            assert (ev < 0.05) if hit else (ev > 0.5)
    assert all(r[3] for r in errors(Setting("fixed", steps=400), v))
    assert errors(Setting("exact", tolerance=1e-9), v)[0][3]


# ---------------------------------------------------------------------------------------------
# the benchmark itself
# ---------------------------------------------------------------------------------------------


def test_pareto_front():
    pts = [(1.0, 1.0), (2.0, 0.5), (3.0, 0.7), (0.5, 2.0), (2.0, 0.5)]
    assert accuracy.pareto_front(pts) == [3, 0, 1, 4]


def test_settings_cover_the_issue_knobs():
    s = accuracy.settings()
    tols = sorted(x.tolerance for x in s if x.solver == "exact")
    assert tols[0] == 1e-12 and tols[-1] == 1e-3
    assert sorted(x.steps for x in s if x.solver == "fixed") == [2**k for k in range(9)]
    pm = {(x.steps, x.iterations) for x in s if x.solver == "pymunk"}
    assert (10, 1) in pm and (1000, 100) in pm and (100, 10) in pm


def test_phases_put_the_impact_inside_a_step():
    v = get_case("offline_disk_rod").variants[1]
    runs = Setting("fixed", steps=10).runs(v, accuracy.PHASES)
    for phase, (block, dt) in zip(accuracy.PHASES, runs, strict=True):
        h = dt / block["substeps"]
        assert v.t_contact / h == pytest.approx(10 + phase)
        assert dt > v.t_contact and dt < v.t_next


def test_main_quick_writes_markdown_and_plot(tmp_path):
    assert accuracy.main(["--quick", "--cases", "seed", "tunnel", "--out", str(tmp_path),
                          "--no-effects", "--min-time", "0", "--batch", "1"]) == 0
    text = (tmp_path / "accuracy.md").read_text()
    assert "## Acceptance" in text and "exact" in text and "pymunk" in text
    assert "python -m spinstrike.benchmarks.accuracy" in text
    assert "cores" in text and "pymunk 7" in text
    assert (tmp_path / "accuracy.png").stat().st_size > 10_000
    # the quick seed variants are head-on: no off-line median, shown as '-' (it was 'nan')
    assert "nan" not in text
    assert re.search(r"\| exact \| tolerance 1e-03 m \| [0-9.e+-]+ \| - \|", text)
    # the reference cases list what this (quick) run measured, not every variant
    for name in ("seed", "tunnel"):
        n = len(get_case(name).variants)
        if n > accuracy.QUICK_VARIANTS:
            assert f"`{name}` ({accuracy.QUICK_VARIANTS} of {n} variants: " in text


@pytest.mark.parametrize("phase", [accuracy.PHASES[0], accuracy.PHASES[-1]])
def test_the_plain_pymunk_loop_gives_the_backends_answer(phase):
    """Walk W28b F1: the like-for-like peer (a pymunk Space as a pymunk user writes it, no
    callbacks) is the same physics as the backend the table times: the same velocities after
    every off-line disk-rod impact, to the printed digits and beyond."""
    setting = Setting("pymunk", steps=accuracy.PYMUNK_REFERENCE[0],
                      iterations=accuracy.PYMUNK_REFERENCE[1])
    for v in get_case(accuracy.PLAIN_CASE).variants:
        if not v.normal_fixed:
            plain, _ = accuracy.plain_pymunk(v, phase=phase, min_time=0)
            assert plain == pytest.approx(errors(setting, v, [phase])[0][0], rel=1e-9), v.name
            assert plain > 1e-4  # a fixed-step engine's error, not the exact one's


def test_the_plain_pymunk_loop_matches_the_backend_on_every_case():
    """The like-for-like table's peer on every case (cushions as thin static segments, the
    backend's are thick) gives the backend's answer, and the exact solver at 1e-12 m its
    known one."""
    setting = Setting("pymunk", steps=accuracy.PYMUNK_REFERENCE[0],
                      iterations=accuracy.PYMUNK_REFERENCE[1])
    for case in CASES:
        for v in get_case(case).variants[:3]:
            plain, _ = accuracy.plain_pymunk(v, min_time=0)
            assert plain == pytest.approx(errors(setting, v, accuracy.PHASES[:1])[0][0],
                                          rel=1e-6, abs=1e-12), (case, v.name)


def test_the_like_for_like_table_has_every_case_it_ran(tmp_path):
    """``--cases`` without the off-line case: the table (was: no like-for-like at all)."""
    assert accuracy.main(["--quick", "--cases", "disk_disk", "rod_wall", "--out", str(tmp_path),
                          "--no-effects", "--min-time", "0", "--batch", "1"]) == 0
    text = (tmp_path / "accuracy.md").read_text()
    assert "- **Like for like**" not in text  # its headline is the off-line case's
    table = text.split("## Like for like, every case")[1].split("\n## ")[0]
    rows = [x for x in table.splitlines() if x.startswith("| ") and "collisions" not in x]
    assert [r.split(" | ")[0] for r in rows] == ["| disk_disk", "| rod_wall"]
    for r in rows:
        cells = r.strip("| ").split(" | ")
        assert cells[1] == str(accuracy.QUICK_VARIANTS)
        assert float(cells[5]) <= 1e-9  # the exact solver's worst error at 1e-12 m
        assert re.fullmatch(r"\*\*[0-9.]+x\*\* \([0-9.]+-[0-9.]+\)", cells[6]), r


def test_main_quick_reports_the_like_for_like_line(tmp_path):
    assert accuracy.main(["--quick", "--cases", "offline_disk_rod", "--out", str(tmp_path),
                          "--no-effects", "--min-time", "0", "--batch", "1"]) == 0
    line = next(x for x in (tmp_path / "accuracy.md").read_text().splitlines()
                if x.startswith("- **Like for like**"))
    assert "plain pymunk loop" in line and "one copy per `world.step`" in line
    assert re.search(r"\*\*[0-9.]+x\*\* faster", line), line
    # walk W29a F5: the ratio is linear in the chosen steps per approach; the line gives the
    # plain loop at fewer steps and what it affords in the exact solver's time
    assert "error at equal time" in line
    for steps in accuracy.PLAIN_FEWER:
        assert re.search(rf"; {steps}: [0-9.]+ µs, error [0-9.e+-]+ median", line) or \
            re.search(rf"approach: {steps}: [0-9.]+ µs, error [0-9.e+-]+ median", line), line
    assert re.search(r"affords about [0-9]+ steps per approach", line), line


def test_cases_are_listed_in_report_order():
    assert CASES == ("seed", "offline_disk_rod", "disk_disk", "rod_wall", "spinning_rod", "tunnel")


@pytest.mark.parametrize("args,words", [
    (["--batch", "0"], "--batch: must be >= 1"),  # was the default, silently
    (["--min-time", "-1"], "--min-time: must be >= 0 s"),
    (["--out", "FILE"], "is a file; give a directory"),  # was a traceback after the whole run
])
def test_bench_accuracy_refuses_bad_options_before_it_runs(tmp_path, capsys, args, words):
    from spinstrike.agents.cli import main

    (tmp_path / "FILE").write_text("")
    args = [str(tmp_path / "FILE") if a == "FILE" else a for a in args]
    t = time.perf_counter()
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "accuracy", "--quick", *args])
    assert exit_.value.code == 2 and time.perf_counter() - t < 5
    assert words in capsys.readouterr().err
