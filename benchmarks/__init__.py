"""SpinStrike benchmarks: accuracy against time (``python -m spinstrike.benchmarks.accuracy``)."""

import platform
from pathlib import Path


def cpu_model() -> str:
    """The CPU's model name (Linux's ``/proc/cpuinfo``; elsewhere ``platform.processor()``),
    for the machine line of a generated report."""
    try:
        return next(line.split(":", 1)[1].strip() for line in
                    Path("/proc/cpuinfo").read_text().splitlines()
                    if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor()


def out_dir(parser, out: Path | None, contents: str) -> Path | None:
    """Make a report's output folder ``out`` before the benchmark runs (a folder named by a
    file is one ``--out`` error line, not a traceback after minutes of measuring)."""
    if out is not None:
        if out.exists() and not out.is_dir():
            parser.error(f"--out: {out} is a file; give a directory ({contents} go there)")
        out.mkdir(parents=True, exist_ok=True)
    return out
