"""`python -m searchrl.bench {world,memory,train,eval,policy} [options] [--json]`: figures measured in one run.

Each suite takes only its own options (`python -m searchrl.bench <suite> --help`); an option of another suite is
refused by argparse rather than ignored.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from searchrl.controllers.registry import HEURISTICS

CONF_DIR = Path(__file__).resolve().parents[2] / "conf"

SUITES = {
    "world": "engine throughput, batched against the oracle (--seconds)",
    "memory": "bytes of world state per configuration",
    "train": "agent-steps/s of RL updates (--updates, --threads, --network)",
    "eval": "evaluation throughput on the grid (--controller or --checkpoint, --maps, --threads)",
    "policy": "inference of a checkpoint: SB3 predict against the traced actor (--checkpoint, --threads, --seconds)",
}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m searchrl.bench", description=__doc__)
    suites = parser.add_subparsers(dest="suite", required=True, metavar="{" + ",".join(SUITES) + "}")
    sub = {name: suites.add_parser(name, help=text, description=text) for name, text in SUITES.items()}
    for name, p in sub.items():
        p.add_argument("--json", action="store_true", help="print one JSON object per case")
        if name in ("world", "policy"):
            p.add_argument("--seconds", type=float, default=3.0, help="time budget per engine or case (0, 3600]")
        if name in ("train", "eval", "policy"):
            p.add_argument("--threads", type=int, default=2, help="torch threads (1 to 256)")
    sub["train"].add_argument("--updates", type=int, default=4, help="timed rollouts + updates (1 to 1000)")
    sub["train"].add_argument("--network", choices=["paper", "small"], default="paper", help="network config")
    sub["train"].add_argument("--experiment", help="a recipe of conf/experiment/ instead of model B with --network")
    sub["eval"].add_argument("--controller", choices=list(HEURISTICS),
                             help="a heuristic (default surfing); not with --checkpoint")  # fmt: skip
    sub["eval"].add_argument("--maps", type=int, default=10, help="maps per cell (1 to 1000)")
    sub["eval"].add_argument("--checkpoint", help="a policy model.zip instead of --controller")
    sub["policy"].add_argument("--checkpoint", required=True, help="a model.zip, e.g. runs/reference/b/model.zip")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    checks = [  # (name, value, ok, allowed) for the options this suite has
        ("--seconds", "seconds", lambda v: 0 < v <= 3600, "0 < seconds <= 3600"),
        ("--threads", "threads", lambda v: 1 <= v <= 256, "1 <= threads <= 256"),
        ("--updates", "updates", lambda v: 1 <= v <= 1000, "1 <= updates <= 1000"),
        ("--maps", "maps", lambda v: 1 <= v <= 1000, "1 <= maps <= 1000"),
    ]
    for flag, attr, ok, allowed in checks:
        value = getattr(args, attr, None)
        if value is not None and not (ok(value) and math.isfinite(value)):
            parser.error(f"{flag}={value} is not allowed: {allowed}")
    experiment = getattr(args, "experiment", None)
    if experiment is not None and not (CONF_DIR / "experiment" / f"{experiment}.yaml").is_file():
        known = ", ".join(sorted(p.stem for p in (CONF_DIR / "experiment").glob("*.yaml")))
        parser.error(f"--experiment={experiment} is not allowed: one of {known}")
    checkpoint = getattr(args, "checkpoint", None)
    if checkpoint and getattr(args, "controller", None):
        parser.error("--controller cannot apply with --checkpoint: give one of them")
    if checkpoint:  # read it now: a corrupt file or run config is named before any measurement
        from searchrl.policies.checkpoint import checkpoint_config, load_checkpoint

        try:
            load_checkpoint(checkpoint, checkpoint_config(checkpoint)[1], device="cpu")
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

        rows = evaluate.run(args.controller or "surfing", args.maps, checkpoint, args.threads, log=log)
    elif args.suite == "policy":
        from searchrl.bench import policy

        rows = policy.run(checkpoint, threads=args.threads, seconds=args.seconds, log=log)
    else:
        from searchrl.bench import train

        rows = train.run(args.updates, args.threads, args.network, args.experiment, log=log)
    if args.json:
        for row in rows:
            print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
