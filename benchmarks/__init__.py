"""The benchmarks of phri-spring: run each from the repository root as
``python -m benchmarks.NAME`` (shared helpers: :mod:`benchmarks.common`)."""
