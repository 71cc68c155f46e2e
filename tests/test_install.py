"""The package as a user imports it: one namespace, ``spinstrike.*``, and no bare top-level names.

In the repository the folders are ``physics/``, ``envs/``, ...; installed they are
``spinstrike.physics``, ``spinstrike.envs``, ... A leftover ``from envs import ...`` would pass
from the repository root (where the bare name imports as a *second* module) and fail for users,
so these tests run in fresh processes outside the repository, and one reads every source file.
"""

from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import tarfile
import textwrap
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
BARE = ("physics", "envs", "agents", "benchmarks", "configs")


def _python(code: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter in ``cwd`` (not the repository: no bare names there)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


def test_bare_names_do_not_import_outside_the_repository(tmp_path):
    code = "\n".join([
        "import importlib, spinstrike",
        f"for name in {BARE!r}:",
        "    try:",
        "        importlib.import_module(name)",
        "    except ModuleNotFoundError:",
        "        continue",
        "    raise SystemExit(f'bare name {name!r} imports')",
        "for name in " + repr(tuple(f"spinstrike.{b}" for b in BARE)) + ":",
        "    importlib.import_module(name)",
        "print('ok')",
    ])
    out = _python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_module_prefixed_id_works_in_a_fresh_process(tmp_path):
    """``gym.make("spinstrike:...")`` imports the package itself (worker processes rely on it);
    every registered entry point lives under ``spinstrike.envs``."""
    code = "\n".join([
        "import gymnasium as gym, numpy as np",
        "env = gym.make('spinstrike:SpinStrike/RodSpin-v0')",
        "obs, _ = env.reset(seed=0)",
        "obs, r, term, trunc, info = env.step(np.zeros(3, np.float32))",
        "assert term and np.isfinite(r)",
        "ids = [k for k in gym.registry if k.startswith('SpinStrike/')]",
        "assert len(ids) == 5, ids  # the four envs and PuckSpeed-v0 (kept beside v1)",
        "for k in ids:",
        "    spec = gym.registry[k]",
        "    for ep in (spec.entry_point, spec.vector_entry_point):",
        "        assert ep.startswith('spinstrike.envs.'), ep",
        "        gym.envs.registration.load_env_creator(ep)",
        "print(sorted(ids))",
    ])
    out = _python(code, tmp_path)
    assert out.returncode == 0, out.stderr
    assert "SpinStrike/RodSpinControl-v0" in out.stdout


def test_packaged_configs_load_by_their_namespaced_names(tmp_path):
    code = "\n".join([
        "from importlib import resources",
        "names = sorted(p.name for p in resources.files('spinstrike.configs.scenes').iterdir()",
        "               if p.name.endswith('.yaml'))",
        "assert names == ['break.yaml', 'puck_control.yaml', 'puck_speed.yaml',",
        "                 'rod_control.yaml', 'rod_spin.yaml'], names",
        "from spinstrike.agents.config import load_agent_config",
        "assert load_agent_config('ppo', 'SpinStrike/RodSpin-v0').n_timesteps > 0",
        "print('ok')",
    ])
    out = _python(code, tmp_path)
    assert out.returncode == 0, out.stderr


def test_console_script_and_benchmark_modules(tmp_path):
    script = Path(sys.executable).with_name("spinstrike")
    assert script.is_file(), "the console script is not installed next to the interpreter"
    out = subprocess.run([str(script), "envs"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    assert "SpinStrike/PuckSpeed-v0" in out.stdout
    for module in ("spinstrike.benchmarks.speed", "spinstrike.benchmarks.accuracy",
                   "spinstrike.benchmarks.startup"):
        out = subprocess.run([sys.executable, "-m", module, "--help"], cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, (module, out.stderr)
        assert f"python -m {module}" in out.stdout
    # `python -m spinstrike`: the command line where the scripts folder is not on PATH
    out = subprocess.run([sys.executable, "-m", "spinstrike", "envs"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "SpinStrike/PuckSpeed-v0" in out.stdout


def test_the_sdist_holds_every_tracked_file(tmp_path):
    """An unpacked sdist is the checkout: its test suite, docs and CI script are there, so the
    README's test command runs in it (an sdist with only ``tests/test_*.py`` at the top ran 12
    tests, 3 of them failing for the missing ``.ci/run``)."""
    # the working tree's tracked files, as `python -m build` would see them
    src = _tracked_copy(tmp_path / "src")
    tracked = {str(p.relative_to(src)) for p in src.rglob("*") if p.is_file()}
    out = subprocess.run(
        [sys.executable, "-c", "import sys; from setuptools import build_meta as b; "
         "print(b.build_sdist(sys.argv[1]))", str(tmp_path / "dist")],
        cwd=src, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    with tarfile.open(tmp_path / "dist" / out.stdout.split()[-1]) as tar:
        members = {m.name.split("/", 1)[1] for m in tar.getmembers()
                   if m.isfile() and "/" in m.name}
    generated = {m for m in members if m in ("PKG-INFO", "setup.cfg") or ".egg-info/" in m}
    missing = sorted(tracked - members - {".gitignore"})
    assert not missing, f"tracked files the sdist leaves out (MANIFEST.in): {missing}"
    extra = sorted(members - tracked - generated)
    assert not extra, f"files in the sdist that the checkout does not track: {extra}"


def _tracked_copy(dest: Path) -> Path:
    """The checkout's tracked files, copied to ``dest`` (skips outside a git checkout)."""
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, timeout=60)
    if listed.returncode != 0:
        pytest.skip("not a git checkout (an unpacked sdist): nothing to compare with")
    for f in listed.stdout.decode().split("\0"):
        if f and (REPO / f).is_file():
            (dest / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(REPO / f, dest / f)
    return dest


def test_a_wheel_leaves_out_modules_an_earlier_build_left(tmp_path):
    """``pip install .`` builds in the checkout's ``build/lib``, which setuptools reuses: a
    module deleted since an earlier build (a ``git pull``) was put in the next wheel, and
    installed, until ``setup.py``'s ``build_py`` started each build's package tree afresh."""
    src = _tracked_copy(tmp_path / "src")
    stale = src / "build" / "lib" / "spinstrike" / "physics" / "removed_since.py"
    stale.parent.mkdir(parents=True)
    stale.write_text("X = 1\n")
    out = subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps",
                          "--no-build-isolation", "--no-index", str(src), "-w",
                          str(tmp_path / "dist")], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    wheel, = (tmp_path / "dist").glob("spinstrike-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "spinstrike/physics/world.py" in names
    assert "spinstrike/configs/scenes/rod_spin.yaml" in names
    assert not [n for n in names if "removed_since" in n]


def _imported_modules(path: Path):
    """Modules a source file imports, including in code it carries as strings (snippets run in
    subprocesses: ``python -c``)."""
    yield from _imports(ast.parse(path.read_text(), str(path)))


def _imports(tree: ast.AST, line: int | None = None):
    """(line, module) of every absolute import in ``tree`` and in the code its strings carry
    (``line``: the line of the string a snippet came from)."""
    for node in ast.walk(tree):
        at = line if line is not None else getattr(node, "lineno", 0)
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield at, alias.name
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield at, node.module
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and "import" in node.value):
            try:
                snippet = ast.parse(textwrap.dedent(node.value))
            except SyntaxError:
                continue
            yield from _imports(snippet, at)


def _sources():
    skip = {".git", ".venv", "build", "dist", "__pycache__", ".hypothesis"}
    for path in REPO.rglob("*.py"):
        if not skip.intersection(path.relative_to(REPO).parts):
            yield path


def test_no_source_imports_a_bare_name():
    """The same rule as ruff's ``banned-api`` (pyproject), checked without ruff installed, and
    also inside code carried as strings (which ruff does not read)."""
    bad = [f"{path.relative_to(REPO)}:{line}: {mod}" for path in _sources()
           for line, mod in _imported_modules(path) if mod.split(".")[0] in BARE]
    assert not bad, "bare imports (use spinstrike.<name>):\n" + "\n".join(bad)
