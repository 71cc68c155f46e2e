"""Write ``docs/stability.md`` and the README's stability table from the suite's measurements.

    python -m tests.stability.report                 # catalogue + long runs (10^6 element-steps)
    python -m tests.stability.report --full          # also the 10^6-step single-world run
    python -m tests.stability.report --out /tmp/s.md # (the README is left alone unless --readme)

Every number in the document comes from ``tests.stability.catalogue`` (each case measured on
every solver that claims it) and ``tests.stability.longrun``; the same measurements (taken once)
also fill the compact table between ``<!-- stability:begin -->`` and ``<!-- stability:end -->``
in ``README.md`` (the rest of the README is left byte for byte). ``tests/stability/test_docs.py``
checks that the document lists exactly the catalogue's cases, solvers and claims, and that the
README's table lists the same cases with the document's numbers.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import platform
import re
import textwrap
import time
from pathlib import Path

import numpy as np

from tests.stability import longrun
from tests.stability import test_fuzz as fuzz
from tests.stability.catalogue import CASES, SOLVERS, Claim

__all__ = ["README_BEGIN", "README_END", "TABLE_HEADER", "claim_text", "main",
           "parse_long_runs", "parse_measurements", "parse_readme", "parse_rows",
           "readme_section", "render", "render_readme", "replace_readme_section", "rows"]

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "stability.md"
README = ROOT / "README.md"
README_BEGIN = "<!-- stability:begin -->"
README_END = "<!-- stability:end -->"
README_HEADER = "| case | what is checked | " + " | ".join(SOLVERS) + " |"
#: a README cell of a solver that does not run the case
NOT_RUN = "–"
TABLE_HEADER = "| case | what is checked | solver | claim | measured worst | notes |"
_ROW = re.compile(r"^\| `(?P<case>[a-z0-9_]+)` \|.*?\| (?P<solver>exact|fixed|pymunk) \| "
                  r"(?P<claim>[^|]+) \| (?P<worst>[^|]+) \|")


def claim_text(claim: Claim) -> str:
    text = (">= " if claim.at_least else "<= ") + f"{claim.bound:g}"
    return f"{text} ({claim.meaning})" if claim.meaning else text


def rows() -> list[tuple[str, str, str]]:
    """(case, solver, claim text) of every catalogue entry, in document order."""
    return [(c.name, s, claim_text(c.claims[s])) for c in CASES for s in SOLVERS
            if s in c.claims]


def parse_rows(text: str) -> list[tuple[str, str, str]]:
    """(case, solver, claim text) of the table rows of a written document."""
    out = []
    for line in text.splitlines():
        m = _ROW.match(line)
        if m:
            out.append((m["case"], m["solver"], m["claim"].strip()))
    return out


def parse_measurements(text: str) -> dict[tuple[str, str], tuple[str, str]]:
    """{(case, solver): (claim text, measured worst as written)} of a written document."""
    out = {}
    for line in text.splitlines():
        m = _ROW.match(line)
        if m:
            out[(m["case"], m["solver"])] = (m["claim"].strip(), m["worst"].strip())
    return out


_LONG_ROW = re.compile(r"^\| (?P<label>[^|`]+?) \| (?P<steps>[\d,]+) \| [^|]+ \| [\d,]+ \| "
                       r"(?P<drift>[^|]+) \| (?P<escapes>\d+) \| (?P<nan>\d+) \|")


def parse_long_runs(text: str) -> list[tuple[str, str, str, str, str]]:
    """(label, element-steps, energy drift, escapes, NaN), as written, of the document's long
    runs."""
    part = text.split("## Long runs", 1)[-1].split("\n## ", 1)[0]
    out = []
    for line in part.splitlines():
        m = _LONG_ROW.match(line)
        if m:
            out.append((m["label"], m["steps"], m["drift"].strip(), m["escapes"], m["nan"]))
    return out


def _fmt(x: float) -> str:
    if x == 0:
        return "0"
    if 0.01 <= abs(x) < 1000:
        return f"{x:.3g}"
    return f"{x:.1e}"


def _cell(text: str) -> str:
    """Text safe inside a markdown table cell (a bare | would split it)."""
    return text.replace("|", "\\|")


def _solver_text(name: str) -> str:
    block = SOLVERS[name]
    if block is None:
        return "exact (tolerance 1e-9 m)"
    knobs = ", ".join(f"{k} {v}" for k, v in block.items() if k != "mode")
    return f"{name} ({knobs})"


def measure_all() -> dict[tuple[str, str], tuple[float, str, float]]:
    out = {}
    for case in CASES:
        for solver in SOLVERS:
            if solver in case.claims:
                start = time.perf_counter()
                m = case.measure(solver)
                out[(case.name, solver)] = (m.worst, m.notes, time.perf_counter() - start)
    return out


LONG_RUNS = (("short (default suite)", dict(steps=20_000, batch=1, check_every=10)),
             ("batched, 10^6 element-steps (slow)", dict(steps=2_000, batch=500,
                                                         check_every=10)))
FULL_RUN = ("10^6 steps of one world (slow)", dict(steps=1_000_000, batch=1, check_every=100))


def render(results: dict, long_results: list[tuple[str, dict]]) -> str:
    lines = [
        "# Stability: hard cases, long runs, fuzzing, bad input",
        "",
        "<!-- generated by `python -m tests.stability.report`; do not edit by hand -->",
        "",
        "Every number on this page is measured by the stability suite itself "
        "(`tests/stability/`), and every case is also a test: `pytest tests/stability` fails "
        "if a measured worst error breaks its claim. Regenerate with "
        "`python -m tests.stability.report` (add `--full` for the 10^6-step single-world run); "
        "`tests/stability/test_docs.py` checks that this page lists exactly the catalogue's "
        "cases, solvers and claims.",
        "",
        f"Generated {_dt.date.today().isoformat()} on {platform.machine()}, "
        f"Python {platform.python_version()}, numpy {np.__version__}. Solvers: "
        + "; ".join(_solver_text(s) for s in SOLVERS)
        + " (unless a case says otherwise).",
        "",
        "## The catalogue",
        "",
        "A claim `<= b` means the measured worst error must not exceed `b`; `>= b` marks "
        "documented behaviour the suite asserts (the fixed solver and pymunk *do* tunnel). "
        "Units per case: `rel.` = relative to the natural scale named in the check.",
        "",
        TABLE_HEADER,
        "|---|---|---|---|---|---|",
    ]
    for case in CASES:
        first = True
        for solver in SOLVERS:
            if solver not in case.claims:
                continue
            worst, notes, _ = results[(case.name, solver)]
            what = f"**{case.title}**: {case.checks} ({case.unit})" if first else "〃"
            first = False
            lines.append(
                f"| `{case.name}` | {_cell(what)} | {solver} | "
                f"{claim_text(case.claims[solver])} | {_fmt(worst)} | {_cell(notes)} |")
    lines += [
        "",
        "## Long runs",
        "",
        f"A walled {longrun.SCENE['table']['size'][0]} m x {longrun.SCENE['table']['size'][1]} m "
        "table with three pucks and a rod, e = 1, mu = 0, random velocities and spins "
        "(`tests/stability/longrun.py`), dt = 0.01 s. Cushions are static, so linear and angular "
        "momentum are not conserved here (the cushions take momentum); kinetic energy is, and "
        "it is the drift reported. An *escape* is a body whose centre leaves the table.",
        "",
        "| run | element-steps | simulated time | contacts | energy drift (rel.) | escapes | "
        "NaN | deepest overlap (m) | most events in a step | settled steps | wall time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for label, r in long_results:
        lines.append(
            f"| {label} | {r['element_steps']:,} | {r['simulated_time']:g} s x {r['batch']} | "
            f"{r['contacts']:,} | {_fmt(r['energy_drift'])} | {r['escapes']} | "
            f"{r['nonfinite']} | {_fmt(r['overlap'])} | {r['max_events']} | "
            f"{r['settled_steps']} | {r['seconds']} |")
    lines += [
        "",
        "## Fuzzing",
        "",
        "`tests/stability/test_fuzz.py` (hypothesis): random walled scenes (1-4 disks and rods, "
        "thickness 0 allowed, masses 1e-6..1e6 kg, static posts and pivots, e and mu random, "
        "exact and fixed solvers, dt 1e-4..1 s) stepped directly; and every registered env "
        "built with random keyword arguments (masses, sizes, restitution, friction, speeds, "
        "time steps, solver blocks) and driven by random actions (outside the box too). A "
        "failure is a NaN or inf, an exception other than `SceneError`, `ConfigError` or "
        "`ValueError` for a NaN action, an escape, an overlap beyond the tolerance, or a "
        "kinetic-energy gain beyond 1e-12 of the energy per contact where no force is applied. "
        "A third fuzz throws any value at any constructor argument: the env is built, or one "
        "`ConfigError` names the argument. Budget: "
        f"{fuzz.SMALL.max_examples} / {fuzz.ENV_SMALL.max_examples} / "
        f"{fuzz.SMALL.max_examples} examples in the default suite; "
        "`HYPOTHESIS_PROFILE=slow pytest -m slow tests/stability` runs the big budget (5000 "
        "examples each for scenes and envs).",
        "",
        "## Bad input",
        "",
        "`tests/stability/test_bad_input.py`: malformed YAML, empty and non-mapping scene "
        "files, wrong types, NaN, unknown fields, shapes and effects, missing masses, "
        "duplicate names, overlaps, bodies outside the table, missing files; every World API "
        "setter with NaN, wrong shapes, out-of-range values and unknown bodies (the world is "
        "left unchanged); env keyword arguments and `config` dicts (unknown, wrong type, out "
        "of range, bad scene paths and scene YAML); NaN, inf and wrong-shape actions (single "
        "and vector envs). Each raises one error of a documented type whose message names "
        "the field.",
        "",
        "## What the model does in the hard cases",
        "",
        "* **Contact** is where the gap *reaches zero*, located to within `tolerance`: a pass "
        "that misses by less than the tolerance, or grazes at exactly zero gap with the "
        "velocity along the surface, gets no impulse (two zero-thickness rods, whose gap "
        "cannot go below zero, are in contact within the tolerance). A normal speed below "
        "1e-12 of the point speeds (`physics.events.ROUNDOFF`) counts as zero: a body "
        "approaching a cushion at 1e-12 rad slides along it. Where a span is cut into steps "
        "moves a contact by up to ~`tolerance` / its normal approach speed in time, so cut "
        "otherwise the end state can differ by that much (walk W19: a rod at tolerance 1e-9 "
        "bouncing slowly off cushions ended 9e-6 apart in spin between 1 and 300 steps over "
        "0.3 s; `time_steps` above is its own scene's), and long rattles of many contacts "
        "diverge as chaotic motion does; energy and momentum stay right either way.",
        "* **Simultaneous contacts** follow the rule in `physics/solvers.py`: every pair "
        "within the tolerance and approaching at the event gets a sequential impulse, swept in "
        "pair order until none approaches (at most 64 sweeps). This reproduces Newton's "
        "cradle; a disk striking two at once gets the sequential result, which depends on the "
        "pair order (bodies in scene order, cushions last). If the sweeps do not converge (a "
        "*jam*: a light body pinned between a heavy one and a cushion, where each sweep removes "
        "only m_light / m_heavy of the approach; a long touching row struck at e = 0) all "
        "touching pairs, up to 64, are solved together (an LCP, as non-negative least squares: "
        "plastic compression then Poisson restitution with the pairs' smallest e; with "
        "contact friction, up to 5 pairs, each stuck, sliding or apart by Coulomb's law), which "
        "never adds energy and leaves nothing approaching. A larger jam is settled (below).",
        "* **Zeno bounces and resting contact.** An inelastic body pinned by the driven mallet "
        "against a cushion makes infinitely many ever-smaller bounces in finite time. The exact "
        "solver counts bounces closing slower than `zeno_speed` (1 mm/s), and searches that "
        "stall inside the tolerance; after `zeno_impacts` (8) of them, or `max_events` (10,000, "
        "or 20 per body beyond 500 bodies) events, the rest of the step is settled by fixed "
        "substeps (at most 1 ms, shorter if "
        "bodies move fast, and shorter again if a collision within the settle makes a body "
        "faster; each body flies its closed-form path through a substep, so one that meets "
        "nothing keeps it exactly) with sequential impulses and positional correction "
        "(translating and "
        "turning the bodies) repeated until no overlap deeper than the tolerance is left. "
        "Such steps are flagged in "
        "`world.last_step.fallback` (as are steps whose jam, of more than 5 pairs, was solved "
        "as a block without the contact friction of its pairs, README's known failures). "
        "Energy: exact steps never "
        "gain more than round-off beyond "
        "the applied force's work; in settled steps positional correction can move the mallet "
        "back against its force (work the kinematics did but the bookkeeping `F . dx` misses), "
        "bounded by the distance it moved into the contact; with the force released nothing "
        "gains energy at all. The mallet alone driven into a frictionless cushion needs no "
        "settling: its bounces are a geometric series with a known end, the mallet resting on "
        "the cushion and sliding along it, and the exact solver puts it there once a bounce "
        "leaves it slower than `zeno_speed` (`tests/physics/test_rest.py` checks the slide "
        "against the closed form, and the corner).",
        "* **Painlevé** (a rod pushed along a cushion with friction). The contact model is "
        "sequential: Newton's normal impulse, then a Coulomb tangential impulse bounded by "
        "mu j and by what stops the slip (never reversing it), then, if the tangential "
        "impulse's lever arm turned the contact into an approaching one, a plastic normal "
        "impulse. Each stage loses energy, so there is no inconsistency or indeterminacy to "
        "resolve: an impulse always exists and is unique, and the configuration that makes "
        "Painlevé's rigid-body problem paradoxical (a large mu, a rod sliding at a shallow "
        "angle) simply loses more energy. The sustained contact under the mallet's load is "
        "settled as above; the suite checks it stays finite, leaves no overlap, and never "
        "gains energy beyond the force's work (mu up to 2, e = 0 and 0.5).",
        "* **Tunnelling.** The exact solver's conservative advancement cannot tunnel at any "
        "speed; the fixed solver and pymunk tunnel once the distance per substep exceeds the "
        "sum of the two radii (documented, asserted in `fast_strike`).",
        "* **Touching at the start** is legal, overlap beyond the tolerance is a "
        "`SceneError` naming the pair, and a body touching a cushion is not refused for float "
        "round-off.",
        "",
        "## Failures this suite found, fixed in the engine",
        "",
        "* Settling let a light disk pass through a heavy one, unflagged: a 1e-5 kg disk "
        "driven into a cushion by a 1e4 kg one (mass ratio 1e9) at 2 m/s shuttles between "
        "them ever faster, and a step whose events run out is settled; the settle planned its "
        "substeps once, from the speeds it started with, and the light disk got ~100 times "
        "faster within it (in 0.1 s steps the third step, in the envs' 20 ms steps the 14th). "
        "The bound is now checked after every substep and the rest of the step planned again "
        "with shorter substeps where a body got faster (`tests/physics/test_extreme_inputs.py`, "
        "on both of the exact solver's loops). Found while checking the cap warnings of the big "
        "fuzz budget. Cost: ~15-30 % more per settled substep, and the substeps the bound needs.",
        "* Settling a plastic pile (four disks driven into a corner, one pushing three along a "
        "cushion, the last sliding down the side cushion) left 8.8e-9 m of overlap in the pose "
        "the step handed on, where the tolerance is 1e-9 m: a positional-correction sweep "
        "removes only ~1/6 of the overlap there, and a substep stopped at 64 sweeps. The "
        "settle's last substep now sweeps until the overlap is within the tolerance (at most "
        "4096 sweeps; ~80 here). Found by the big fuzz budget, kept as a named test "
        "(`tests/physics/test_extreme_inputs.py`) and as a fuzz example.",
        "* Settling left a contact chain overlapping (a mallet 6e-5 m deep in a puck pressed "
        "into a cushion): positional correction is now repeated until no overlap deeper than "
        "the tolerance is left.",
        "* An exact tangential pass got an impulse (~1e-4 of the speed): contact was declared "
        "where the gap first came within the tolerance instead of where it reaches zero.",
        "* A light body jammed between a heavy one and a cushion was left overlapping and kept "
        "the heavy body's speed (sequential sweeps converge only as m_light / m_heavy): the "
        "jam block solve, and equal-share positional correction on repeated sweeps.",
        "* The jam block solve added energy (4.5e-5 relative) at a mass ratio of 1e11, where "
        "its LCP is ill-conditioned: the restitution factor is now capped where the energy "
        "change computed from the solved impulses is zero.",
        "* A pivoted rod that had turned into a puck wedged in a corner stayed 5e-4 m inside it: "
        "settling's positional correction could only translate; it now turns bodies too.",
        "* A zero-thickness rod lying flat on a cushion and turning into it ended 6.7e-8 m "
        "inside: the gap of a flat contact was the middle's distance, which hid the nearer "
        "end's penetration; it is now the nearer end's (the impulse still acts at the middle).",
        "* A pivoted rod lying flat on a cushion, or on a static rod, and turning into it was "
        "left inside it: the flat contact's point was the middle, its pivot, where neither an "
        "impulse nor a positional correction can act (3e-7 m at every settled step's end on a "
        "cushion, 300x the tolerance; on a 0.2 m static rod it turned through it, cores "
        "crossed by 0.117 m). Where neither body can translate, a flat contact's point is now "
        "the nearer end (`tests/physics/test_settle_fixes.py`). Found by an adversarial walk "
        "of the engine.",
        "* A settle's substep was set by the closest pair of the scene, however far from the "
        "contact being settled: a 0.1 mm static post that no body reaches changed a nine-body "
        "settle from 7 to 23 substeps, and so the motion (1 mm in that step, 1.05 m after 3 "
        "s). Pairs that cannot meet within the rest of the step (bounding circles farther "
        "apart than their speed bound closes, with their own bound to spare) no longer "
        "shorten the substep; they are checked again after every substep, so a body that got "
        "faster brings its pairs back and the settle plans again "
        "(`tests/physics/test_settle_fixes.py`). Found by an adversarial walk of the engine.",
        "* Near-parallel rod-on-rod impacts jumped at the flat-contact threshold (cores "
        "parallel to ~1e-6 rad): a rod falling on a static one offset by 0.3 m ended spinning "
        "at -2.76 rad/s for tilts below 1e-6 rad (one impulse through the overlap's middle), "
        "+0.21 at 1.005-1.02e-6 (settled steps) and +0.46 above (event-driven, the physical "
        "value). A flat rod-rod contact is now the limit of the event-driven end impacts as "
        "the tilt goes to 0: the overlap's ends hit in turn, the nearer first; +-0.46258 for "
        "every tilt 1e-8..1e-5, none settled, p and L kept, no energy gained "
        "(`tests/physics/test_flat_contacts.py`, docs/design.md §2). Found by an adversarial "
        "walk of the engine.",
        "* A rod landing near flat on a cushion jumped at the flat-contact threshold the same "
        "way (cushions parallel to ~1e-6 rad): a 1 m rod falling at 1 m/s onto one, e = 1, "
        "ended spinning at +-0.14055 rad/s for tilts above 1e-6 rad, at 0 below (one impulse "
        "through its middle), and at 1.0-1.01e-6 its step was settled; at e = 0.5 the settled "
        "band reached 2e-6 (-0.43 rad/s, bouncing at 0.62 m/s where the end impacts give 0.34)."
        " A free rod flat on a cushion is now resolved at its core's two ends like a flat rod "
        "pair: +-0.14055 for every tilt 1e-8..1e-3, none settled. A flat pair's approach was "
        "also judged at its middle by the time of impact: a rod lying flat on a cushion or a "
        "rod and turning (its middle at rest, an end going in) went unseen until the tilt left "
        "the band, the step stalled and was settled, the end 5e-4 m deep when the settle met it"
        " (1 m rod at 1 rad/s, 1 ms step); it now approaches when either end does "
        "(`events.flat_approach`) and is met at once (`tests/physics/test_flat_contacts.py`, "
        "docs/design.md §2).",
        "* A body touching a cushion was refused at construction when `x + r` rounded past the "
        "edge.",
        "* Env `scene=` arguments (missing file, directory, malformed YAML, wrong types) "
        "escaped as raw `FileNotFoundError`, `yaml.ParserError`, `TypeError`: now one "
        "`ConfigError` naming the problem.",
        "",
    ]
    return "\n".join(lines)


def _readme_cell(case, solver: str, results: dict) -> str:
    if solver not in case.claims:
        return NOT_RUN
    return _cell(f"{_fmt(results[(case.name, solver)][0])} {claim_text(case.claims[solver])}")


def render_readme(results: dict, long_results: list[tuple[str, dict]]) -> str:
    """The README's stability section (between the markers, markers excluded): one row per
    case, the measured worst error per solver beside its claim, one line of long-run numbers."""
    lines = [
        "<!-- generated by `python -m tests.stability.report` from the suite's measurements; "
        "do not edit by hand -->",
        "",
        textwrap.fill(
            "Each cell is the worst error the suite measured on that solver, then the claim it "
            "must respect (`<=`: a bound; `>=`: documented behaviour, e.g. tunnelling); "
            f"{NOT_RUN} = the solver makes no claim there. Every cell is also a test "
            "(`pytest tests/stability`).", 99, break_on_hyphens=False),
        "",
        README_HEADER,
        "|---|---|" + "---|" * len(SOLVERS),
    ]
    for case in CASES:
        cells = " | ".join(_readme_cell(case, s, results) for s in SOLVERS)
        lines.append(f"| `{case.name}` | {_cell(case.brief or case.title)} ({case.unit}) | "
                     f"{cells} |")
    runs = "; ".join(
        f"**{label}**: {r['element_steps']:,} element-steps, energy drift "
        f"{_fmt(r['energy_drift'])}, {r['escapes']} escapes, {r['nonfinite']} NaN"
        for label, r in long_results)
    lines += [
        "",
        "Long runs (a walled table, three pucks and a rod, e = 1, mu = 0): " + runs + ".",
        "",
        textwrap.fill(
            "Details — what each case checks, per-solver notes, the long runs' contacts, "
            "overlaps and cost, fuzzing and bad input: [docs/stability.md](docs/stability.md).",
            99, break_on_hyphens=False),
    ]
    return "\n".join(lines)


def readme_section(text: str) -> str:
    """The text between the README's stability markers (ValueError if they are missing)."""
    if text.count(README_BEGIN) != 1 or text.count(README_END) != 1 or (
            text.index(README_BEGIN) > text.index(README_END)):
        raise ValueError(f"README: expected one {README_BEGIN} followed by one {README_END}")
    return text.split(README_BEGIN, 1)[1].split(README_END, 1)[0]


def replace_readme_section(text: str, section: str) -> str:
    """``text`` with the part between the markers replaced by ``section``; all else kept."""
    readme_section(text)  # checks the markers
    head, rest = text.split(README_BEGIN, 1)
    tail = rest.split(README_END, 1)[1]
    return f"{head}{README_BEGIN}\n{section.strip()}\n{README_END}{tail}"


_README_ROW = re.compile(r"^\| `(?P<case>[a-z0-9_]+)` \| (?P<what>.+?) \| "
                         + r" \| ".join(rf"(?P<{s}>[^|]+)" for s in SOLVERS) + r" \|$")
_README_CELL = re.compile(r"^(?P<worst>\S+) (?P<claim>(?:<=|>=) .+)$")
_README_RUN = re.compile(r"\*\*(?P<label>[^*]+)\*\*: (?P<steps>[\d,]+) element-steps, energy "
                         r"drift (?P<drift>[^,]+), (?P<escapes>\d+) escapes, (?P<nan>\d+) NaN")


def parse_readme(text: str) -> tuple[list[tuple[str, dict[str, tuple[str, str] | None]]],
                                     list[tuple[str, str, str, str, str]]]:
    """The README's stability section, parsed: ``[(case, {solver: (claim, worst) or None})]``
    in table order, and the long runs as :func:`parse_long_runs` gives them."""
    section = readme_section(text)
    cases = []
    for line in section.splitlines():
        m = _README_ROW.match(line)
        if not m:
            continue
        cells = {}
        for solver in SOLVERS:
            cell = m[solver].strip()
            if cell == NOT_RUN:
                cells[solver] = None
                continue
            c = _README_CELL.match(cell)
            cells[solver] = (c["claim"], c["worst"]) if c else ("?", cell)
        cases.append((m["case"], cells))
    runs = [(m["label"], m["steps"], m["drift"], m["escapes"], m["nan"])
            for m in _README_RUN.finditer(section)]
    return cases, runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DOC)
    parser.add_argument("--full", action="store_true", help="also the 10^6-step run (~30 s)")
    parser.add_argument("--readme", type=Path, default=None,
                        help="README whose stability section to rewrite (default: README.md "
                             "when --out is the default document, else none)")
    args = parser.parse_args()
    readme = args.readme or (README if args.out == DOC else None)
    if readme is not None:
        readme_section(readme.read_text())  # fail on missing markers before measuring
    results = measure_all()
    for (name, solver), (worst, _, secs) in results.items():
        print(f"{name:22s} {solver:6s} {worst:.3e}  ({secs:.1f} s)", flush=True)
    runs = list(LONG_RUNS) + ([FULL_RUN] if args.full else [])
    long_results = []
    for label, kw in runs:
        r = longrun.run(**kw)
        print(label, r, flush=True)
        long_results.append((label, r))
    doc = render(results, long_results)
    section = render_readme(results, long_results) if readme is not None else ""
    if not args.full:  # keep the last --full run's row rather than drop it: the --out
        # file's, else the shipped document's (a new --out file had none: walk W20a)
        doc = keep_full_run(doc, [args.out, DOC], _doc_row, "|---" * 11 + "|")
        if readme is not None:
            section = keep_full_run(section, [readme], _readme_run, "Long runs (")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(doc)
    print(f"wrote {args.out}")
    if readme is not None:
        readme.write_text(replace_readme_section(readme.read_text(), section))
        print(f"wrote the stability section of {readme}")


def _doc_row(text: str) -> str | None:
    """The full run's table row in docs/stability.md, whole, or None."""
    for line in text.splitlines():
        if line.startswith(f"| {FULL_RUN[0]} |"):
            return line
    return None


def _readme_run(text: str) -> str | None:
    """The full run's part of the README's long-runs line (``**label**: ...``), or None."""
    m = re.search(re.escape(f"**{FULL_RUN[0]}**") + r": [^;\n]*?(?=; |\.\n|\.$)", text)
    return m.group(0) if m else None


def keep_full_run(new: str, old_files: list[Path], find, anchor: str) -> str:
    """``new`` with the full run's entry of the first of ``old_files`` that has one (as
    ``find`` finds it) put back: as the last row of the long-runs table (``anchor`` its
    separator line) or, for the README, the last entry of its long-runs line (``anchor`` that
    line's start). Unchanged when none has such an entry."""
    kept = next((entry for entry in (find(path.read_text()) for path in old_files
                                     if path.exists()) if entry is not None), None)
    if kept is None:
        return new
    lines = new.split("\n")
    i = next(k for k, line in enumerate(lines) if line.startswith(anchor))
    if anchor.startswith("|"):  # after the table's last row
        j = i + 1
        while j < len(lines) and lines[j].startswith("| "):
            j += 1
        lines.insert(j, kept)
    else:
        lines[i] = lines[i].removesuffix(".") + "; " + kept + "."
    return "\n".join(lines)


if __name__ == "__main__":
    main()
