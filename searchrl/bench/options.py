"""The options of `python -m searchrl.bench`: its parser and the checks of what it was given, each refusal one line
(argparse's `parser.error`) before any measurement."""

from __future__ import annotations

import argparse
import math

from searchrl.controllers.registry import HEURISTICS
from searchrl.shared_schema import CONF_DIR, recipes
from searchrl.world.config import ConfigError

SUITES = {
    "world": "engine throughput, batched against the oracle, at numba thread counts (--threads 1,2, --seconds)",
    "memory": "bytes of world state per configuration",
    "train": "agent-steps/s of RL and the shares of its wall time (--updates, --experiment, --machine, --device)",
    "eval": "evaluation throughput on the grid (--controller or --checkpoint, --maps, --repeats, --cells, --threads, "
    "--device)",
    "policy": "inference of a checkpoint: SB3 predict against the traced actor (--checkpoint, --threads, --seconds, "
    "--device)",
}


def parser() -> argparse.ArgumentParser:
    """The bench's command line: one subcommand per suite, each with its own options only."""
    parser = argparse.ArgumentParser(prog="python -m searchrl.bench", description=__doc__)
    suites = parser.add_subparsers(dest="suite", required=True, metavar="{" + ",".join(SUITES) + "}")
    sub = {name: suites.add_parser(name, help=text, description=text) for name, text in SUITES.items()}
    for name, p in sub.items():
        p.add_argument("--json", action="store_true", help="print one JSON object per case")
        if name in ("world", "policy"):
            p.add_argument("--seconds", type=float, default=3.0, help="time budget per engine or case (0, 3600]")
        if name in ("train", "eval", "policy"):
            p.add_argument(
                "--threads",
                type=int,
                default=None if name == "train" else 2,
                help="torch threads (1 to 256)" + (": the machine's, else 2" if name == "train" else ""),
            )
    sub["world"].add_argument(
        "--threads",
        dest="world_threads",
        action="append",
        metavar="N[,N...]",
        help="numba threads, each measured in the same run: 2, 1,2 or repeated (default: all)",
    )
    sub["train"].add_argument("--updates", type=int, default=4, help="timed rollouts + updates (1 to 1000)")
    sub["train"].add_argument("--network", choices=["paper", "small"], default="paper", help="network config")
    sub["train"].add_argument("--experiment", help="a recipe of conf/experiment/ instead of model B with --network")
    sub["train"].add_argument("--device", help="torch device (cpu, cuda, cuda:1): the machine's, else cpu")
    sub["train"].add_argument(
        "overrides",
        nargs="*",
        metavar="KEY=VALUE",
        help="the training app's overrides on the recipe, e.g. critic=true_state network.extractor=own_map_cnn",
    )
    sub["train"].add_argument(
        "--machine",
        choices=sorted(p.stem for p in (CONF_DIR / "machine").glob("*.yaml")),
        help="settings for a machine (conf/machine/): slots per step, minibatch, threads, device",
    )
    sub["eval"].add_argument(
        "--controller", choices=list(HEURISTICS), help="a heuristic (default surfing); not with --checkpoint"
    )
    sub["eval"].add_argument("--maps", type=int, default=10, help="maps per cell (1 to 1000)")
    sub["eval"].add_argument("--repeats", type=int, default=1, help="episodes per map (1 to 100; the grid's 5)")
    sub["eval"].add_argument(
        "--cells", metavar="KEY[,KEY...]", help="only these Table 2 cells, e.g. n160_N256,n80_N128 (default: all 30)"
    )
    sub["eval"].add_argument("--checkpoint", help="a policy model.zip instead of --controller")
    sub["eval"].add_argument(
        "--settings", default="{}", help="the controller's settings as a JSON object, e.g. '{\"reach\": 2}'"
    )
    sub["eval"].add_argument(
        "--extensions",
        metavar="MODULE[,MODULE...]",
        help="modules that register controllers, imported first (as the apps' extensions=)",
    )
    sub["eval"].add_argument(
        "--inference",
        choices=["torch", "onnx"],
        default="torch",
        help="a policy's path on the CPU (docs/performance.md)",
    )
    sub["policy"].add_argument("--checkpoint", required=True, help="a model.zip, e.g. runs/reference/b/model.zip")
    for name in ("eval", "policy"):  # of a checkpoint's network: a heuristic runs on the CPU
        sub[name].add_argument("--device", default="cpu", help="torch device: cpu, cuda, cuda:<index>, mps or auto")
    return parser


def _device(parser: argparse.ArgumentParser, device: str, checkpoint: str | None) -> str:
    """eval's and policy's --device (`policy_device`; parser.error, one line). torch is imported only where a
    policy runs or a device is named."""
    if not checkpoint and device == "cpu":
        return device
    from searchrl.policies.device import policy_device

    try:
        return policy_device(device, bool(checkpoint))
    except ConfigError as err:
        parser.error(str(err))


def checked(parser: argparse.ArgumentParser, args: argparse.Namespace) -> tuple[str, list[int]]:
    """(device, world threads) of parsed `args`, every option checked: ranges, the recipe, --controller against
    --checkpoint, the device, the checkpoint read (a corrupt file or run config named), the world's thread counts."""
    checks = [  # (name, value, ok, allowed) for the options this suite has
        ("--seconds", "seconds", lambda v: 0 < v <= 3600, "0 < seconds <= 3600"),
        ("--threads", "threads", lambda v: 1 <= v <= 256, "1 <= threads <= 256"),
        ("--updates", "updates", lambda v: 1 <= v <= 1000, "1 <= updates <= 1000"),
        ("--maps", "maps", lambda v: 1 <= v <= 1000, "1 <= maps <= 1000"),
        ("--repeats", "repeats", lambda v: 1 <= v <= 100, "1 <= repeats <= 100"),
    ]
    for flag, attr, ok, allowed in checks:
        value = getattr(args, attr, None)
        if value is not None and not (ok(value) and math.isfinite(value)):
            parser.error(f"{flag}={value} is not allowed: {allowed}")
    cells = getattr(args, "cells", None)
    if cells is not None:
        from searchrl.bench.evaluate import GRID

        known = [cell.key for cell in GRID]
        unknown = [key for key in cells.split(",") if key not in known]
        if unknown or not cells:
            parser.error(f"--cells={cells} is not allowed: a comma-separated list of {', '.join(known)}")
    experiment = getattr(args, "experiment", None)
    if experiment is not None and experiment not in recipes():
        known = ", ".join(recipes())
        parser.error(f"--experiment={experiment} is not allowed: one of {known}")
    if getattr(args, "overrides", None):  # each composes onto the recipe, or one line names it (as the app's would)
        from searchrl.bench.train import composed_overrides
        from searchrl.command_line import check_group_choices, check_jobs_compose
        from searchrl.train.schema import register_configs

        register_configs()
        try:
            check_group_choices(args.overrides)
            check_jobs_compose(composed_overrides(args.network, experiment, args.machine, args.overrides), "train")
        except ConfigError as refusal:
            parser.error(refusal.message)
    checkpoint = getattr(args, "checkpoint", None)
    if getattr(args, "inference", "torch") != "torch" and not (checkpoint and args.device == "cpu"):
        parser.error(f"--inference={args.inference} is for --checkpoint on --device cpu")
    if checkpoint and getattr(args, "controller", None):
        parser.error("--controller cannot apply with --checkpoint: give one of them")
    device, threads = "cpu", []
    if args.suite in ("eval", "policy"):
        device = _device(parser, args.device, checkpoint)
    if checkpoint:  # read it now: a corrupt file or run config is named before any measurement
        from searchrl.policies.checkpoint import load_checkpoint
        from searchrl.threads import use_threads

        # torch's threads set before its first work (building the policy): a pool started on every core and cut to
        # fewer afterwards ran the network 2.5 times slower beside a busy core (searchrl/threads.py)
        use_threads(args.threads or 2, network_on_cpu=device == "cpu")

        try:
            load_checkpoint(checkpoint, device="cpu")
        except ConfigError as err:
            parser.error(str(err))
    if args.suite == "world":
        from searchrl.bench import world

        try:  # "1,2" and repeated flags alike; each count within what numba can run here
            threads = list(dict.fromkeys(t for text in args.world_threads or [] for t in world.thread_counts(text)))
        except ConfigError as err:
            parser.error(str(err))
        for t in (t for t in threads if not 1 <= t <= world.max_threads()):
            parser.error(f"--threads={t} is not allowed: 1 <= threads <= {world.max_threads()} (numba's threads here)")
    return device, threads


def settings(parser: argparse.ArgumentParser, args: argparse.Namespace) -> dict:
    """eval's --settings: a JSON object of the controller's settings, checked by building the controller once."""
    import json

    from searchrl.controllers.factory import heuristic_factory
    from searchrl.world.config import ConfigError, WorldConfig

    try:
        values = json.loads(args.settings)
    except ValueError:
        values = None
    if not isinstance(values, dict):
        parser.error(f"--settings={args.settings} is not allowed: a JSON object, e.g. '{{\"reach\": 2}}'")
    if values and args.checkpoint:
        parser.error("--settings is not allowed with --checkpoint: a policy takes its run's settings")
    if values:
        try:
            heuristic_factory(args.controller or "surfing", values, check=WorldConfig())
        except ConfigError as err:
            parser.error(f"--settings={args.settings} is not allowed: {err}")
    return values


def import_extensions(argv: list[str]) -> str | None:
    """Import the modules of `--extensions A,B` (or `--extensions=A,B`) in `argv`, as the apps' `extensions=` does;
    the one-line refusal of a module that cannot be imported, else None."""
    from searchrl.command_line import import_modules

    modules: list[str] = []
    for i, arg in enumerate(argv):
        if arg == "--extensions" and i + 1 < len(argv):
            modules = [m for m in argv[i + 1].split(",") if m]
        elif arg.startswith("--extensions="):
            modules = [m for m in arg.partition("=")[2].split(",") if m]
    try:
        import_modules(modules)
    except ConfigError as err:
        return str(err)
    return None
