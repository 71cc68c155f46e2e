"""Running from the repository root with the package installed as a wheel (the README's quick
start, `pip install ".[train]"` from a clone): Python puts the current folder first on sys.path,
so the checkout's ``spinstrike/`` folder, which holds only ``__init__.py``, is what ``import
spinstrike`` finds. Its subpackages must still be found (they are the checkout's top-level
folders). The wheel case is simulated by dropping the editable install's finder, which is what
maps the subpackages for an editable install; the real wheel is in tests/test_install_paths.py.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import spinstrike

REPO = Path(spinstrike.__file__).resolve().parent.parent

AS_A_WHEEL_USER = """
import json, sys
sys.meta_path[:] = [f for f in sys.meta_path if "editable" not in getattr(f, "__module__", "")]
import gymnasium as gym, numpy as np
import spinstrike, spinstrike.physics
from spinstrike.benchmarks import accuracy  # python -m spinstrike.benchmarks.accuracy
env = gym.make("SpinStrike/RodSpin-v0")
obs, _ = env.reset(seed=0)
world = spinstrike.physics.World("rod_control")
print(json.dumps({"envs": spinstrike.envs.__file__, "obs": obs.shape[0],
                  "scenes": len(spinstrike.physics.packaged_scenes())}))
"""


def test_the_checkout_imports_whole_from_its_root():
    env = dict(os.environ, SPINSTRIKE_QUIET="1")
    env.pop("PYTHONPATH", None)
    out = subprocess.run([sys.executable, "-c", AS_A_WHEEL_USER], cwd=REPO, env=env,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert Path(got["envs"]).resolve() == REPO / "envs" / "__init__.py"
    assert got["scenes"] >= 1 and got["obs"] > 0
