"""`python -m searchrl.bench {world,memory,train,eval,policy} [options] [--json]`: figures measured in one run.

Each suite takes only its own options (`python -m searchrl.bench <suite> --help`); an option of another suite is
refused by argparse rather than ignored.
"""

from __future__ import annotations

import json
import sys

from searchrl.bench import options


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    error = options.import_extensions(argv)  # before the parser lists the controllers
    if error:
        print(f"python -m searchrl.bench: error: {error}", file=sys.stderr)
        return 2
    parser = options.parser()
    args = parser.parse_args(argv)
    device, threads = options.checked(parser, args)
    log = None if args.json else sys.stdout
    if args.suite == "world":
        from searchrl.bench import world

        rows = world.run(seconds=args.seconds, threads=threads, log=log)
    elif args.suite == "memory":
        from searchrl.bench import memory

        rows = memory.run(log=log)
    elif args.suite == "eval":
        from searchrl.bench import evaluate

        rows = evaluate.run(
            args.controller or "surfing",
            args.maps,
            args.checkpoint,
            args.threads,
            device,
            log=log,
            repeats=args.repeats,
            cells=args.cells,
            settings=options.settings(parser, args),
            inference=args.inference,
        )
    elif args.suite == "policy":
        from searchrl.bench import policy

        rows = policy.run(args.checkpoint, threads=args.threads, seconds=args.seconds, device=device, log=log)
    else:
        from searchrl.bench import train
        from searchrl.world.config import ConfigError

        try:  # the recipe's settings (a missing device among them) are checked before any work
            rows = train.run(
                args.updates,
                args.threads,
                args.network,
                args.experiment,
                args.device,
                args.machine,
                log=log,
                overrides=args.overrides,
            )
        except ConfigError as err:
            parser.error(str(err))
    if args.json:
        for row in rows:
            print(json.dumps(row))
    return 0


if __name__ == "__main__":
    sys.exit(main())
