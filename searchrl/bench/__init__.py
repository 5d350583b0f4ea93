"""Benchmarks: `python -m searchrl.bench {world,memory} [--json]`."""
