"""Benchmarks: `python -m searchrl.bench {world,memory,train,eval} [--json]`."""
