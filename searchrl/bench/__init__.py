"""Benchmarks: `python -m searchrl.bench world [--json]`."""
