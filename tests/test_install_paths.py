"""The install paths a user takes, in a fresh virtual environment (slow: installs and compiles).

wheel -> run -> run from the repository root -> editable -> run -> uninstall: a run writes nothing
into site-packages (the compiled kernels go to ``SPINSTRIKE_CACHE_DIR``), the checkout's
``spinstrike/`` that shadows the wheel from the repository root finds its subpackages, the editable
install that replaces the wheel imports and registers the envs, and the uninstall leaves nothing
behind. Then, with the installed package made read-only, a run works, and after a kernel source
changes (``step_element`` in ``physics/kernels.py``, which the strike kernel in ``envs/fast.py``
inlines) the next run uses the changed kernel, not the cached one.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import venv
from pathlib import Path

import pytest

import spinstrike

pytestmark = pytest.mark.slow

REPO = Path(spinstrike.__file__).resolve().parent.parent
RUN = """
import json, sys
import gymnasium as gym, numpy as np
import spinstrike
env = gym.make("SpinStrike/RodSpin-v0")
env.reset(seed=0)
env.step(np.array([0.5, 0.0, 1.0], np.float32))
print(json.dumps({"file": spinstrike.__file__, "clock": float(env.unwrapped.world.time[0])}))
"""


def _sh(cmd: list[str], env: dict, cwd: Path, timeout: float = 900) -> str:
    out = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    assert out.returncode == 0, f"{cmd}\n{out.stdout[-2000:]}\n{out.stderr[-4000:]}"
    return out.stdout


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def _freeze(path: Path, on: bool) -> None:
    """Make ``path`` (recursively) read-only, for root too (``chattr +i``), or undo it."""
    if os.geteuid() == 0 and shutil.which("chattr"):
        subprocess.run(["chattr", "-R", "+i" if on else "-i", str(path)], check=True)
    else:
        subprocess.run(["chmod", "-R", "a-w" if on else "u+w", str(path)], check=True)


def test_wheel_editable_uninstall_and_a_read_only_install(tmp_path):
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / "bin" / "python"
    site = Path(_sh([str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                    {}, tmp_path).strip())
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(SPINSTRIKE_CACHE_DIR=str(tmp_path / "cache"), SPINSTRIKE_QUIET="1",
               PATH=f"{env_dir / 'bin'}:{env['PATH']}")
    pip = [str(py), "-m", "pip", "--disable-pip-version-check", "install", "--quiet"]

    # wheel, then a run: nothing new in site-packages
    _sh(pip + [str(REPO)], env, tmp_path)
    before = _files(site)
    first = _sh([str(py), "-c", RUN], env, tmp_path)
    assert str(site) in first
    assert _files(site) == before, sorted(_files(site) - before)
    assert list((tmp_path / "cache").rglob("*.nbi")), "kernels are cached outside site-packages"

    # the same wheel, run from the repository root (where the README's quick start leaves the
    # user): the checkout's spinstrike/ comes first on sys.path and its subpackages are found
    assert str(REPO) in _sh([str(py), "-c", RUN], env, REPO)

    # editable over the wheel: imports from the repository and registers the envs
    _sh(pip + ["-e", str(REPO)], env, tmp_path)
    out = _sh([str(py), "-c", RUN], env, tmp_path)
    assert str(REPO) in out
    assert "SpinStrike/PuckSpeed-v0" in _sh([str(env_dir / "bin" / "spinstrike"), "envs"], env,
                                             tmp_path)

    # uninstall: nothing of the package is left
    _sh([str(py), "-m", "pip", "uninstall", "-y", "--quiet", "spinstrike"], env, tmp_path)
    left = [f for f in _files(site) if "spinstrike" in f.lower()]
    assert not left, left

    # a read-only install runs, and a changed kernel source is not served stale from the cache
    _sh(pip + [str(REPO)], env, tmp_path)
    package = site / "spinstrike"
    env["SPINSTRIKE_CACHE_DIR"] = str(tmp_path / "cache2")
    _freeze(package, True)
    try:
        clock = json.loads(_sh([str(py), "-c", RUN], env, tmp_path))["clock"]
        assert clock > 0
        _freeze(package, False)
        kernels = package / "physics" / "kernels.py"
        text = kernels.read_text()
        assert "    v.clock[b] += dt\n" in text
        kernels.write_text(text.replace("    v.clock[b] += dt\n", "    v.clock[b] += 2.0 * dt\n"))
        _freeze(package, True)
        again = json.loads(_sh([str(py), "-c", RUN], env, tmp_path))["clock"]
        assert again == pytest.approx(2 * clock), "the strike kernel ran a stale step_element"
        assert not list(package.rglob("*.nbi"))
    finally:
        _freeze(package, False)


#: the core dependencies at the lowest versions ``pyproject.toml`` allows (checked against it)
FLOORS = {"numpy": "1.26.0", "numba": "0.62.0", "pyyaml": "6.0", "pydantic": "2.5.0",
          "gymnasium": "1.1.0", "pymunk": "6.6.0", "platformdirs": "3.0.0", "filelock": "4.2.1"}
LOWEST = """
import gymnasium as gym, numpy as np
import spinstrike
from gymnasium.utils.env_checker import check_env
for env_id in spinstrike.envs.ENV_IDS:
    env = gym.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    check_env(env.unwrapped, skip_render_check=True)
    for mode in ("next_step", "same_step"):
        vec = gym.make_vec(env_id, num_envs=4, vectorization_mode="vector_entry_point",
                           autoreset_mode=mode)
        vec.reset(seed=0)
        for _ in range(300):
            vec.step(vec.action_space.sample())
print("ok")
"""


def test_the_lowest_declared_versions_of_the_core_dependencies_work(tmp_path):
    """``gymnasium>=1.0`` and ``numba>=0.60`` were declared, but the envs import Gymnasium
    1.1's ``AutoresetMode`` and the kernel cache numba 0.62's ``UserWideCacheLocator``: an
    install that kept the older ones broke on the first ``gym.make`` (found by a docs walk).
    The core dependencies at their floors, the package without its extras: every env makes,
    steps, passes Gymnasium's checker and runs vectorised in both autoreset modes."""
    from packaging.version import Version

    tomllib = pytest.importorskip("tomllib", reason="Python 3.11+ reads pyproject.toml")

    declared = {re.split(r"[<>=!~ ]", dep)[0].lower(): dep for dep in
                tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["dependencies"]}
    assert set(declared) == set(FLOORS)
    for name, version in FLOORS.items():
        floor = re.search(r">=\s*([0-9.]+)", declared[name])
        assert floor and Version(floor.group(1)) == Version(version), (declared[name], version)
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = str(env_dir / "bin" / "python")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(SPINSTRIKE_CACHE_DIR=str(tmp_path / "kernels"), SPINSTRIKE_QUIET="1")
    _sh([py, "-m", "pip", "install", "-q", *(f"{k}=={v}" for k, v in FLOORS.items())], env,
        tmp_path)
    _sh([py, "-m", "pip", "install", "-q", "--no-deps", str(REPO)], env, tmp_path)
    _sh([py, "-m", "pip", "check"], env, tmp_path)
    assert _sh([py, "-c", LOWEST], env, tmp_path, timeout=1800).strip().endswith("ok")
