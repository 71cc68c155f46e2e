"""``.ci/run`` cleans up after itself.

Each of its fresh venvs is ~2.5 GB (torch, Ray); left in ``/tmp`` by earlier runs, they filled the
disk and a CI run died of ENOSPC in ``pip``. Here the script runs for real, with ``python3``,
``pip`` and ``pytest`` replaced by stubs on ``PATH`` (a venv is a folder with ``bin/activate``), and
``TMPDIR`` pointed at a folder that must be empty again when the script ends: after a pass, after
a failing test run, and when the run is terminated in the middle of the tests.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent

STUB_PYTHON = """#!/bin/sh
# python3 -m venv DIR: a folder with bin/activate; anything else (python -m pip ...) succeeds.
if [ "$1" = "-m" ] && [ "$2" = "venv" ]; then
    mkdir -p "$3/bin" && : > "$3/bin/activate"
    echo "$3" >> "$CI_STUB_LOG.venvs"
    ls "$(dirname "$(dirname "$3")")" | wc -l >> "$CI_STUB_LOG.siblings"
fi
exit 0
"""

STUB_PYTEST = """#!/bin/sh
echo "pytest $*" >> "$CI_STUB_LOG"
touch "$CI_STUB_LOG.running"
[ -n "$CI_STUB_SLEEP" ] && sleep "$CI_STUB_SLEEP"
exit "${CI_STUB_PYTEST_RC:-0}"
"""


def _ci_copy(tmp_path: Path) -> tuple[Path, dict[str, str], Path, Path]:
    repo = tmp_path / "repo"
    (repo / ".ci").mkdir(parents=True)
    shutil.copy2(REPO / ".ci" / "run", repo / ".ci" / "run")
    shutil.copy2(REPO / "README.md", repo / "README.md")
    stubs = tmp_path / "stubs"
    stubs.mkdir()
    for name, text in (("python3", STUB_PYTHON), ("python", STUB_PYTHON),
                       ("pip", "#!/bin/sh\nexit 0\n"), ("pytest", STUB_PYTEST)):
        (stubs / name).write_text(text)
        (stubs / name).chmod(0o755)
    scratch = tmp_path / "tmpdir"
    scratch.mkdir()
    log = tmp_path / "log"
    env = {"PATH": f"{stubs}:/usr/bin:/bin", "TMPDIR": str(scratch), "CI_STUB_LOG": str(log),
           "HOME": str(tmp_path)}
    return repo, env, scratch, log


@pytest.mark.parametrize("pytest_rc", [0, 1])
def test_ci_run_removes_its_venvs(tmp_path, pytest_rc):
    repo, env, scratch, log = _ci_copy(tmp_path)
    env["CI_STUB_PYTEST_RC"] = str(pytest_rc)
    out = subprocess.run(["bash", str(repo / ".ci" / "run")], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == pytest_rc, out.stderr
    venvs = Path(f"{log}.venvs").read_text().split()
    assert venvs and all(Path(v).is_relative_to(scratch) for v in venvs)
    if pytest_rc == 0:
        assert Path(log).read_text().splitlines() == ["pytest ", "pytest -m rllib", "pytest -x -q"]
        # stage 2's venv is made after stage 1's was removed: one venv on disk at a time
        assert Path(f"{log}.siblings").read_text().split() == ["1", "1"]
    else:
        assert len(venvs) == 1  # a failing stage 1 stops the run
    assert list(scratch.iterdir()) == [], "the CI's venvs were left behind"


def test_ci_run_cleans_up_when_terminated(tmp_path):
    repo, env, scratch, log = _ci_copy(tmp_path)
    env["CI_STUB_SLEEP"] = "30"
    proc = subprocess.Popen(["bash", str(repo / ".ci" / "run")], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 30
        while not Path(f"{log}.running").exists():
            assert time.monotonic() < deadline and proc.poll() is None, "the stub pytest never ran"
            time.sleep(0.05)
        assert any(scratch.iterdir())
        os.killpg(proc.pid, signal.SIGTERM)  # as a CI runner stops a job: the whole process group
        proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode != 0
    assert list(scratch.iterdir()) == [], "the CI's venvs were left behind"
