"""`python -m searchrl.bench {world,memory,train,eval,policy} [--json]`: figures measured in one run."""

from __future__ import annotations

import os

# Sleep rather than spin when torch's OpenMP threads wait: with parallel sweeps or any other busy process on the
# cores, spinning threads slowed a tiny run 20x here. Set OMP_WAIT_POLICY yourself to override.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import argparse
import json
import sys


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m searchrl.bench", description=__doc__)
    parser.add_argument("suite", choices=["world", "memory", "train", "eval", "policy"], help="what to measure")
    parser.add_argument("--json", action="store_true", help="print one JSON object per case")
    parser.add_argument("--seconds", type=float, default=3.0, help="world: time budget per engine per case (> 0)")
    parser.add_argument("--updates", type=int, default=4, help="train: timed rollouts+updates (>= 1)")
    parser.add_argument("--threads", type=int, default=2, help="train, eval, policy: torch threads (>= 1)")
    parser.add_argument("--network", choices=["paper", "small"], default="paper", help="train: network config")
    parser.add_argument(
        "--controller", choices=["surfing", "greedy", "coverage", "random"], default="surfing", help="eval"
    )
    parser.add_argument("--maps", type=int, default=10, help="eval: maps per cell (>= 1)")
    parser.add_argument("--checkpoint", help="eval: a policy model.zip instead of --controller; policy: required")
    args = parser.parse_args(argv)
    if not 0 < args.seconds <= 3600:
        parser.error(f"--seconds={args.seconds} is not allowed: 0 < seconds <= 3600")
    if args.maps < 1:
        parser.error(f"--maps={args.maps} is not allowed: must be >= 1")
    if args.updates < 1 or args.threads < 1:
        parser.error(f"--updates={args.updates}, --threads={args.threads} are not allowed: both must be >= 1")
    if args.suite == "policy" and not args.checkpoint:
        parser.error("policy needs --checkpoint=<model.zip>, e.g. runs/reference/b/model.zip")
    if args.checkpoint:  # read it now: a corrupt file or run config is named before any measurement
        from searchrl.controllers.policy import checkpoint_config, load_checkpoint

        try:
            load_checkpoint(args.checkpoint, checkpoint_config(args.checkpoint)[1], device="cpu")
        except (ValueError, FileNotFoundError) as err:
            parser.error(str(err))
    log = None if args.json else sys.stdout
    if args.suite == "world":
        from searchrl.bench import world

        rows = world.run(seconds=args.seconds, log=log)
    elif args.suite == "memory":
        from searchrl.bench import memory

        rows = memory.run(log=log)
    elif args.suite == "eval":
        from searchrl.bench import evaluate

        rows = evaluate.run(args.controller, args.maps, args.checkpoint, args.threads, log=log)
    elif args.suite == "policy":
        from searchrl.bench import policy

        rows = policy.run(args.checkpoint, threads=args.threads, seconds=args.seconds, log=log)
    else:
        from searchrl.bench import train

        rows = train.run(updates=args.updates, threads=args.threads, network=args.network, log=log)
    if args.json:
        for row in rows:
            print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
