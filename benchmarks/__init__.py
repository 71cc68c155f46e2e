"""SpinStrike benchmarks: accuracy against time (``python -m benchmarks.accuracy``)."""
