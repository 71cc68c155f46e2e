"""A team shares variant runs between people, checkouts and Python versions (walk W24b): the
digest of the code of the user's ``mylab.py`` that a run records must say when, and only when,
that code changed, whoever runs it, wherever ``mylab`` is installed, under any Python; and
``train --resume``, ``evaluate`` and ``baselines`` must act on it. Through the CLI, in new
processes where the walk used them so."""

import ast
import glob
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml

from spinstrike.agents.cli import main
from tests.agents.test_baselines_reuse import (  # noqa: F401  (ppo_yml: a fixture)
    MODULE,
    _baselines,
    _write_module,
    ppo_yml,
)

#: the user's module: a reward weight in a task subclass, and an f-string holding a quoted
#: string (the line whose ``ast.unparse`` text differs between 3.11 and 3.12, walk W24b F3)
LAB = textwrap.dedent("""
    import gymnasium as gym
    import numpy as np
    from spinstrike.envs.strike import RodSpinEnv, RodSpinTask, RodSpinVectorEnv

    SPEED_WEIGHT = 0.5


    class SpeedTask(RodSpinTask):
        def step(self, actions, batch_info=True):
            reward, terminated, info = super().step(actions, batch_info)
            return reward + SPEED_WEIGHT * np.asarray(info["speed"]), terminated, info


    class SpeedRod(RodSpinEnv):
        TASK = SpeedTask

        def __repr__(self):
            return f"SpeedRod(weight={SPEED_WEIGHT}, id={self.spec.id if self.spec else 'none'})"


    class SpeedRodVec(RodSpinVectorEnv):
        TASK = SpeedTask


    gym.register("MyLab/SpeedRod-v0", entry_point=SpeedRod, vector_entry_point=SpeedRodVec)
""")
VARIANT = "mylab:MyLab/SpeedRod-v0"
TRAIN = ["train", "--env", VARIANT, "--timesteps", "256", "--n-envs", "2", "--no-eval",
         "--no-video", "--no-progress", "--out", "run"]


def _env() -> dict:
    return dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")


def _spinstrike(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """``spinstrike ARGS`` in a new process, run from ``cwd`` (the user's folder)."""
    script = Path(sys.executable).with_name("spinstrike")
    return subprocess.run([str(script), *args], cwd=cwd, env=_env(), capture_output=True,
                          text=True, timeout=900)


def test_resume_refuses_a_run_whose_code_changed_and_evaluate_writes_it_down(tmp_path):
    """F1: ``train --resume`` of a run whose ``mylab.py`` changed since it trained went on
    training on the new reward with no word, and its ``config.yml`` kept the old digest. It
    is refused like an option contradicting the record, naming the module and how to go on;
    the code put back (a comment added) resumes. F6: ``evaluate RUN`` with the changed code
    rewrote the run's summary with the new code's scores, the note on stderr only: the summary
    says it now."""
    (tmp_path / "mylab.py").write_text(LAB)
    done = _spinstrike(tmp_path, *TRAIN)
    assert done.returncode == 0, done.stderr[-3000:]
    record = (tmp_path / "run" / "config.yml").read_text()
    assert list(yaml.safe_load(record)["code"]) == ["mylab"]

    (tmp_path / "mylab.py").write_text(LAB.replace("SPEED_WEIGHT = 0.5", "SPEED_WEIGHT = 0.7"))
    refused = _spinstrike(tmp_path, "train", "--resume", "--out", "run", "--timesteps", "512",
                          "--no-progress")
    message = " ".join(refused.stderr.split())
    assert refused.returncode == 2, refused.stderr[-3000:]
    assert "resume: the code of mylab (mylab:MyLab/SpeedRod-v0's classes and the modules of " \
           "yours they import) changed since run trained" in message, message
    assert "spinstrike train --config run/config.yml --out NEW_RUN" in message, message
    assert (tmp_path / "run" / "config.yml").read_text() == record  # nothing trained

    # F6: evaluate RUN saves the changed code's scores, and says so in the summary
    evaluated = _spinstrike(tmp_path, "evaluate", "run", "--episodes", "2")
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    assert "note: the code of mylab" in evaluated.stderr
    summary = " ".join((tmp_path / "run" / "summary.md").read_text().split())
    assert "The code of `mylab` changed since the run trained: these scores are of the code " \
           "as it is now." in summary, summary
    rows = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [row["policy"] for row in rows] == ["agent", "random", "oracle"]
    assert all(row["code_changed"] == ["mylab"] for row in rows), rows

    # the code as it was (a comment is no change): the run goes on, its digest still true
    (tmp_path / "mylab.py").write_text(LAB.replace("SPEED_WEIGHT = 0.5",
                                                   "SPEED_WEIGHT = 0.5  # as trained"))
    resumed = _spinstrike(tmp_path, "train", "--resume", "--out", "run", "--timesteps", "512",
                          "--no-progress")
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert "note:" not in resumed.stderr, resumed.stderr
    assert yaml.safe_load((tmp_path / "run" / "config.yml").read_text())["code"] == \
        yaml.safe_load(record)["code"]
    evaluated = _spinstrike(tmp_path, "evaluate", "run", "--episodes", "2")
    assert evaluated.returncode == 0 and "note:" not in evaluated.stderr, evaluated.stderr
    assert "code_changed" not in (tmp_path / "run" / "summary.json").read_text()


def _venv_with(tmp_path: Path, package: Path) -> tuple[Path, Path]:
    """A Python environment whose site-packages has ``package`` installed by pip, the dev
    environment's packages (SpinStrike's editable install among them) seen through a ``.pth``
    line, as Bob's venv with ``pip install ./mylabpkg`` (walk W24b F2). Its python and its
    site-packages folder."""
    import site

    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    purelib = Path(subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True).stdout.strip())
    (purelib / "_dev_packages.pth").write_text(
        "".join(f"import site; site.addsitedir({path!r})\n" for path in site.getsitepackages()))
    subprocess.run([str(python), "-m", "pip", "install", "--no-deps", "--no-index",
                    "--no-build-isolation", "-q", str(package)], check=True, env=_env(),
                   capture_output=True, timeout=600)
    assert (purelib / "mylab.py").is_file()
    return python, purelib


def test_an_installed_module_is_digested_like_one_in_the_working_folder(tmp_path):
    """F2: a ``mylab`` installed with pip (site-packages) was not "the user's", so a run
    recorded no digest, and an edit of its reward (0.5 to 3.0) moved the agent's score from
    1.39 to 7.51 with no note. Its digest is recorded and compared wherever it is installed,
    and equals a folder copy's."""
    package = tmp_path / "mylabpkg"
    package.mkdir()
    (package / "mylab.py").write_text(LAB)
    (package / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "mylab"\nversion = "0.1"\n'
        '[tool.setuptools]\npy-modules = ["mylab"]\n')
    python, purelib = _venv_with(tmp_path, package)
    work = tmp_path / "work"  # no mylab.py here: the installed one is imported
    work.mkdir()

    def spinstrike(cwd: Path, *args: str) -> subprocess.CompletedProcess:
        return subprocess.run([str(python), "-c", "import sys; from spinstrike.agents.cli "
                               "import main; sys.exit(main(sys.argv[1:]))", *args], cwd=cwd,
                              env=_env(), capture_output=True, text=True, timeout=900)

    done = spinstrike(work, *TRAIN)
    assert done.returncode == 0, done.stderr[-3000:]
    code = yaml.safe_load((work / "run" / "config.yml").read_text()).get("code")
    assert code is not None and list(code) == ["mylab"] and code["mylab"].startswith("ast-3:"), \
        code
    # the same code in a folder (Alice's copy, imported first from there): no note
    (tmp_path / "alice").mkdir()
    (tmp_path / "alice" / "mylab.py").write_text(LAB)
    same = spinstrike(tmp_path / "alice", "evaluate", str(work / "run"), "--episodes", "2",
                      "--no-save")
    assert same.returncode == 0 and "note:" not in same.stderr, same.stderr[-3000:]
    # the installed module edited: said
    (purelib / "mylab.py").write_text(LAB.replace("SPEED_WEIGHT = 0.5", "SPEED_WEIGHT = 3.0"))
    edited = spinstrike(work, "evaluate", "run", "--episodes", "2", "--no-save")
    assert edited.returncode == 0, edited.stderr[-3000:]
    assert "note: the code of mylab (mylab:MyLab/SpeedRod-v0's classes" in \
        " ".join(edited.stderr.split()), edited.stderr


#: code of many kinds, f-strings with quoted strings, nested format specs and ``=`` among
#: them, whose digest must be the same under every Python (its module registers a variant)
SAMPLE = LAB + textwrap.dedent('''
    """A docstring."""
    import dataclasses
    import functools
    from typing import Any, Generic, TypeVar

    T = TypeVar("T")
    d = {"a": 1, "b": [1, 2.5, 1e-3, 0x1F, 1_000_000, 3j, -0.0, ...]}
    name = "x"
    s1 = f"{name!r:>10} {d['a']}"
    s2 = f'{d["a"]:.{3}f}'
    s3 = f"{'nested'}" + f"{SPEED_WEIGHT=}" + "a" "b" + f"x{{y}}"
    s4 = f"{SPEED_WEIGHT:}" f"{name!s:}"
    s5 = f"pre {d['a']:>{4}} mid {name!a} post" "tail" f"{'a' if name else 'b'}"
    s6 = rb"\\d+" + b"bytes", f"{SPEED_WEIGHT=:.3f}" + f"{  name  = }", u"unicode"
    s7 = f"""{d['a']}
    multi"""
    s8 = f"{d['a'] + d['b'][0]:{'>'}{10}}" + f"" + f"{{}}"


    @dataclasses.dataclass(frozen=True)
    class Config(Generic[T]):
        """A docstring."""

        weight: float = 0.5
        items: list[int] = dataclasses.field(default_factory=list)

        @functools.cached_property
        def doubled(self) -> float:
            return self.weight * 2


    def helper(action, /, *args, scale: float = 1.0, **kwargs) -> tuple[Any, ...]:
        global SPEED_WEIGHT
        info, reward = kwargs, 0.0
        if (speed := info.get("speed")) is not None:
            reward += SPEED_WEIGHT * speed
        match info:
            case {"hit": True, **rest}:
                reward += 1
            case [first, *others] if first:
                pass
            case Config(weight=w) | Config(weight=w):
                reward -= w
            case str() as s:
                reward = len(s)
            case _:
                pass
        try:
            x = [i for i in range(3) if i] + list({j: j for j in range(2)}) + [*{k for k in ()}]
        except* ValueError as exc:
            raise RuntimeError(f"bad {exc!r}") from exc
        finally:
            pass
        with open("a") as a, open("b") as b:
            pass
        lam = lambda q=1, *, r=2: q + r  # noqa: E731
        while False:
            break
        else:
            reward = not (reward and action or info)
        assert -reward ** 2 <= (-reward) ** 2, f"{reward:.3f}"
        return x, lam, d["b"][1:2:3], d["b"][::-1], a, b


    async def run(things):
        async with things as s:
            async for i in s:
                await i
        return [i async for i in things]
''')


def _pythons() -> list[str]:
    """The Pythons 3.11 and newer found (pyenv's), this one first."""
    found = sorted(glob.glob("/root/.pyenv/versions/3.1[1-9]*/bin/python3"))
    return [sys.executable, *found]


def test_the_digest_is_the_same_under_every_python(user_module, tmp_path):
    """F3: the digest read the tree back as code (``ast.unparse``), whose text of an f-string
    holding a quoted string differs between 3.11 and 3.12: the same ``mylab.py`` read as
    changed under 3.12 and 3.13 against a run trained under 3.11. The digest of a canonical
    form of the tree is the same under each Python found (run on the digest's own module,
    ``envs/_digest.py``, which needs no third-party package)."""
    from spinstrike.envs import code_fingerprint

    path = user_module("spinstrike_digest_sample", SAMPLE) / "spinstrike_digest_sample.py"
    here = code_fingerprint("spinstrike_digest_sample:MyLab/SpeedRod-v0")
    assert list(here) == ["spinstrike_digest_sample"]
    digest_py = Path(__file__).parents[2] / "envs" / "_digest.py"
    script = ("import ast, importlib.util, sys; "
              "spec = importlib.util.spec_from_file_location('_digest', sys.argv[1]); "
              "module = importlib.util.module_from_spec(spec); spec.loader.exec_module(module); "
              "print(module.digest(ast.parse(open(sys.argv[2]).read())))")
    pythons = _pythons()
    if len(pythons) < 2:
        pytest.skip("no other Python 3.11+ found under /root/.pyenv/versions")
    digests = {}
    for python in pythons:
        out = subprocess.run([python, "-c", script, str(digest_py), str(path)],
                             capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, (python, out.stderr)
        digests[python] = out.stdout.strip()
    assert set(digests.values()) == {here["spinstrike_digest_sample"]}, digests


def _train_in_process(user_module, name: str) -> str:
    """A variant run, ``run``, of the user's module ``name`` (``LAB``); its variant's id."""
    user_module(name, LAB.replace("MyLab/SpeedRod-v0", f"{name}/SpeedRod-v0"))
    variant = f"{name}:{name}/SpeedRod-v0"
    assert main(["train", "--env", variant, *TRAIN[3:]]) == 0
    return variant


def _record_code(code: dict) -> None:
    path = Path("run/config.yml")
    record = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**record, "code": code}, sort_keys=False))


def test_a_digest_of_an_older_scheme_or_of_no_source_is_not_compared_but_said(user_module,
                                                                             capsys):
    """F4: runs recorded with the older digests (``ast.dump``'s, then ``ast.unparse``'s, a
    bare sha256) and with this one read as "changed" against each other, identical code
    scoring identically. A digest records its scheme, and one of another scheme is said to be
    not compared. F2: a class of the user's whose source is not readable was skipped without
    a word; it is recorded as ``unknown``, and ``evaluate`` says it cannot check it."""
    import hashlib

    from spinstrike.envs import code_check, code_fingerprint

    name = "spinstrike_digest_older"
    variant = _train_in_process(user_module, name)
    now = code_fingerprint(variant)
    assert now[name].startswith("ast-3:")
    capsys.readouterr()
    # Carol's run (at 749abc0, ast.dump) or Alice's (at f9f22c9, ast.unparse): a bare sha256
    tree = ast.parse(Path(f"{name}.py").read_text())
    for older in (hashlib.sha256(ast.dump(tree).encode()).hexdigest(),
                  hashlib.sha256(ast.unparse(tree).encode()).hexdigest()):
        assert code_check(variant, {name: older}) == (
            [], {name: "recorded with an older digest; not compared"})
        _record_code({name: older})
        assert main(["evaluate", "run", "--episodes", "2"]) == 0
        note = " ".join(capsys.readouterr().err.split())
        assert f"note: cannot check the code of {name} (recorded with an older digest; not " \
               f"compared) against what run trained with" in note, note
        assert "changed since" not in note, note
        rows = json.loads(Path("run/summary.json").read_text())
        assert all("code_changed" not in row and row["code_unchecked"] == {
            name: "recorded with an older digest; not compared"} for row in rows), rows
    # a source not readable when the run trained: recorded as such, said
    _record_code({name: "unknown"})
    assert main(["evaluate", "run", "--episodes", "2", "--no-save"]) == 0
    note = " ".join(capsys.readouterr().err.split())
    assert f"note: cannot check the code of {name} (its source was not readable when the run " \
           f"trained)" in note, note


def test_a_class_whose_source_is_not_readable_is_recorded_as_unknown(user_module, tmp_path):
    """F2: a module of the user's installed without its source (a ``.pyc`` alone) got no
    digest and no word: the run's record looked like one of a shipped class's variant."""
    import compileall
    import importlib

    from spinstrike.envs import code_check, code_fingerprint

    name = "spinstrike_digest_sourceless"
    here = user_module(name, LAB.replace("MyLab/SpeedRod-v0", "Sourceless/SpeedRod-v0"))
    assert compileall.compile_file(str(here / f"{name}.py"), legacy=True, quiet=1)
    (here / f"{name}.py").unlink()
    importlib.invalidate_caches()
    variant = f"{name}:Sourceless/SpeedRod-v0"
    assert code_fingerprint(variant) == {name: "unknown"}
    assert code_check(variant, {name: "unknown"}) == (
        [], {name: "its source was not readable when the run trained"})
    assert code_check(variant, {name: "ast-3:" + "0" * 64}) == (
        [], {name: "its source is not readable now"})


@pytest.mark.usefixtures("ppo_yml")
def test_baselines_reuses_a_run_whose_digest_is_of_an_older_scheme(user_module, capsys):
    """F4: ``baselines --reuse-only`` refused a run of identical code recorded a commit before
    ("trained with the code of mylab as it was then (it changed since)"). A digest of another
    scheme cannot be compared: the run is reused, as a run recorded before digests is, with a
    note; a digest of this scheme that differs is still refused."""
    module = MODULE  # (the reuse tests' _write_module writes it)
    source = LAB.replace("MyLab/SpeedRod-v0", "ReuseLab/SpeedRod-v0")
    here = _write_module(user_module, "ReuseLab/SpeedRod-v0", source)
    variant, run = f"{module}:ReuseLab/SpeedRod-v0", "ppo-ReuseLab-SpeedRod-v0-s0"
    root, doc = here / "runs", here / "baselines.md"
    assert _baselines(variant, root, doc) == 0
    config = root / run / "config.yml"
    record = yaml.safe_load(config.read_text())
    assert record["code"][module].startswith("ast-3:")
    older = {module: record["code"][module].partition(":")[2]}  # a bare sha256, as before
    config.write_text(yaml.safe_dump({**record, "code": older}, sort_keys=False))
    capsys.readouterr()
    assert _baselines(variant, root, doc, "--reuse-only") == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"note: {root / run}: cannot check the code of {module} (recorded with an older " \
           f"digest; not compared); reused if nothing else changed" in out, out
    config.write_text(yaml.safe_dump(record, sort_keys=False))
    _write_module(user_module, "ReuseLab/SpeedRod-v0",
                  source.replace("SPEED_WEIGHT = 0.5", "SPEED_WEIGHT = 5.0"))
    with pytest.raises(SystemExit) as refused:
        _baselines(variant, root, doc, "--reuse-only")
    assert "trained with the code of" in str(refused.value.code), refused.value.code


@pytest.mark.parametrize("before, after, same", [
    # Gymnasium's register: the run records its arguments, so the digest leaves it out
    ("import gymnasium as gym\ngym.register('L/A-v0', entry_point='m:E', kwargs={'a': 1})\n",
     "import gymnasium as gym\ngym.register('L/A-v0', entry_point='m:E', kwargs={'a': 2})\n",
     True),
    ("from gymnasium import register as reg\nreg('L/A-v0', entry_point='m:E')\n",
     "from gymnasium import register as reg\nreg('L/A-v0', entry_point='m:F')\n", True),
    ("import gymnasium.envs.registration\ngymnasium.envs.registration.register('L/A-v0')\n",
     "import gymnasium.envs.registration\ngymnasium.envs.registration.register('L/B-v0')\n",
     True),
    # any other register call is the user's code (walk W25 F1: a reward hook went unnoticed)
    ("HOOKS.register(lambda r: r * 1.0)\n", "HOOKS.register(lambda r: r * 100.0 + 7)\n", False),
    ("def register(f):\n    return f\nregister(1)\n", "def register(f):\n    return f\n"
     "register(2)\n", False),
    ("import atexit\natexit.register(print, 1)\n", "import atexit\natexit.register(print, 2)\n",
     False),
])
def test_only_gymnasiums_register_is_left_out_of_the_digest(before, after, same):
    from spinstrike.envs._digest import digest

    assert (digest(ast.parse(before)) == digest(ast.parse(after))) is same
