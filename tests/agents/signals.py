"""Stopping ``spinstrike train`` by a signal once it has written a checkpoint (the tests of
Ctrl-C and of a scheduler's SIGTERM)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path


def signal_after_checkpoint(args: list[str], cwd: Path, signum: int, run: Path) -> str:
    """Run ``spinstrike train ARGS`` in a subprocess, send ``signum`` once ``run.partial`` holds
    a checkpoint, check the exit code is 128 + ``signum``; return what it wrote to stderr."""
    proc = subprocess.Popen([sys.executable, "-m", "spinstrike.agents.cli", *args],
                            cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    checkpoints = run.with_name(run.name + ".partial") / "checkpoints"
    try:
        deadline = time.time() + 240
        while not (checkpoints.exists() and any(checkpoints.glob("model_*_steps.zip"))):
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.time() < deadline, "no checkpoint in 240 s"
            time.sleep(0.2)
        proc.send_signal(signum)
        assert proc.wait(timeout=60) == 128 + signum
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.stderr.read().decode()
