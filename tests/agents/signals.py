"""Stopping ``spinstrike train`` by a signal once it has written a checkpoint (the tests of
Ctrl-C and of a scheduler's SIGTERM), or in-process by Ctrl-C's ``KeyboardInterrupt`` once
training has passed a given step (the tests of ``--resume`` and of checkpoints)."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def signal_after_checkpoint(args: list[str], cwd: Path, signum: int, run: Path) -> str:
    """Run ``spinstrike train ARGS`` in a subprocess, send ``signum`` once ``run.partial`` holds
    a checkpoint, check the exit code is 128 + ``signum``; return what it wrote to stderr."""
    # a background job of a non-interactive shell (`pytest &`, a CI script run so) starts with
    # SIGINT ignored, and the child inherited it: it trained on through the Ctrl-C sent below.
    # The child gets SIGINT's default (Python then turns it into KeyboardInterrupt), as a
    # terminal's Ctrl-C reaches a foreground command.
    # PYTHONFAULTHANDLER: a child that does not exit is sent SIGABRT below, and prints where
    # each of its threads was (once in CI, under Ray's venv, the child said nothing for 60 s)
    proc = subprocess.Popen([sys.executable, "-m", "spinstrike.agents.cli", *args],
                            cwd=cwd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    checkpoints = run.with_name(run.name + ".partial") / "checkpoints"
    try:
        deadline = time.time() + 240
        while not (checkpoints.exists() and any(checkpoints.glob("model_*_steps.zip"))):
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.time() < deadline, "no checkpoint in 240 s"
            time.sleep(0.2)
        proc.send_signal(signum)
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGABRT)  # faulthandler's dump of every thread's stack
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
            raise AssertionError("no exit 60 s after the signal; stderr (with the stacks at "
                                 "SIGABRT):\n" + proc.stderr.read().decode()) from None
        assert code == 128 + signum, proc.stderr.read().decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.stderr.read().decode()


@contextlib.contextmanager
def with_callback(monkeypatch, callback):
    """Within the block, ``spinstrike train`` (in this process) trains with the SB3 callback
    ``callback`` after its own."""
    from spinstrike.agents import train as train_mod

    real = train_mod._callbacks

    def callbacks(*args, **kwargs):
        eval_env, cbs = real(*args, **kwargs)
        cbs.callbacks.append(callback)
        return eval_env, cbs

    with monkeypatch.context() as m:
        m.setattr(train_mod, "_callbacks", callbacks)
        yield


@contextlib.contextmanager
def ctrl_c_after(monkeypatch, steps: int):
    """Within the block, ``spinstrike train`` (in this process) raises ``KeyboardInterrupt``
    from a callback once training has passed ``steps``, so every test stops at the same
    place."""
    from stable_baselines3.common.callbacks import BaseCallback

    class _CtrlC(BaseCallback):
        def _on_step(self) -> bool:
            if self.num_timesteps >= steps:
                raise KeyboardInterrupt
            return True

    with with_callback(monkeypatch, _CtrlC()):
        yield
