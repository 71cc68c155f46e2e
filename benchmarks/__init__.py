"""SpinStrike benchmarks: accuracy against time (``python -m spinstrike.benchmarks.accuracy``)."""
