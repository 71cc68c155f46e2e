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
