"""`python -m searchrl.bench {world,memory} [--json]`: benchmarks measured in one run."""

from __future__ import annotations

import argparse
import json
import sys

from searchrl.bench import memory as memory_bench
from searchrl.bench import world as world_bench

SUITES = {"world": world_bench.run, "memory": memory_bench.run}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m searchrl.bench", description=__doc__)
    parser.add_argument("suite", choices=sorted(SUITES), help="what to measure")
    parser.add_argument("--json", action="store_true", help="print one JSON object per case")
    parser.add_argument("--seconds", type=float, default=3.0, help="time budget per engine per case (> 0)")
    args = parser.parse_args(argv)
    if not args.seconds > 0:
        parser.error(f"--seconds={args.seconds} is not allowed: must be > 0")
    rows = SUITES[args.suite](seconds=args.seconds, log=None if args.json else sys.stdout)
    if args.json:
        for row in rows:
            print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
