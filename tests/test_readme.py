"""The README's Python examples run as a user runs them: each block in a fresh interpreter,
from a folder outside the repository (an installed package has no ``configs/`` beside the
user's script), with nothing defined beforehand.

A block that reads a file by a path relative to the repository, or uses a name it never
defines, fails here (the physics example did both until 2026-11-24). The Ray RLlib block runs
where the rllib extra is installed (``pytest -m rllib``).
"""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"


def _blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", README.read_text(), flags=re.S | re.M)


def _params():
    out = []
    for i, code in enumerate(_blocks()):
        marks = []
        if "ray" in re.findall(r"^(?:from|import) (\w+)", code, flags=re.M):
            marks = [pytest.mark.rllib,
                     pytest.mark.skipif(importlib.util.find_spec("ray") is None,
                                        reason="the rllib extra is not installed")]
        first = next(line for line in code.splitlines() if line and not line.startswith(
            ("import", "from")))
        out.append(pytest.param(code, id=f"block{i}-{first[:30]}", marks=marks))
    return out


def test_readme_has_python_examples():
    assert len(_blocks()) >= 3  # environments, physics, RLlib: a broken fence would drop them


@pytest.mark.parametrize("code", _params())
def test_readme_example_runs_outside_the_repository(code, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env.update(SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=600, env=env)
    assert done.returncode == 0, done.stderr[-3000:]


def _cells(row: str) -> int:
    """The cells GitHub's Markdown finds in a table row: an unescaped ``|`` splits one, inside
    a code span too."""
    return len(re.split(r"(?<!\\)\|", row.strip().strip("|")))


@pytest.mark.parametrize("doc", ["README.md",
                                 *sorted(p.name for p in (ROOT / "docs").glob("*.md"))])
def test_every_table_row_has_the_header_s_cells(doc):
    """The README's env table lost its rewards on GitHub: ``|w*|`` inside a code span split
    the cell (8 cells in a row of 4), and the rest of the row was dropped."""
    path = ROOT / doc if doc == "README.md" else ROOT / "docs" / doc
    header = None
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.startswith("|"):
            header = None
            continue
        if header is None:
            header = _cells(line)
        assert _cells(line) == header, f"{doc}:{number}: {_cells(line)} cells, header {header}"
