"""`python -m searchrl.render [--controller NAME | --checkpoint model.zip [--device cuda]] [--out episode.gif]`

Writes one episode (NAME: a heuristic, docs/controllers.md) as an animated GIF in the paper's colours (Fig. 1,
Fig. 4): left, the true maps with all agents (purple), hidden (green) and found (brown) targets; right, one agent's
belief, the agent ringed in black; a caption names the controller, scenario and world, a legend the colours.
"""

from __future__ import annotations

import argparse
import sys

from searchrl.atomic import check_writable
from searchrl.controllers.registry import HEURISTICS
from searchrl.shared_schema import CONF_DIR, TRAINABLE_MODELS
from searchrl.world.config import ConfigError

SCENARIOS = CONF_DIR / "scenario"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m searchrl.render", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument(
        "--controller", choices=list(HEURISTICS), help="a heuristic (default surfing), not with --checkpoint"
    )
    p.add_argument("--checkpoint", help="a trained model.zip (its run's world settings are used)")
    p.add_argument("--model", choices=TRAINABLE_MODELS, help="world settings for heuristics (default b)")
    p.add_argument("--n", type=int, default=40, help="world side")
    p.add_argument("--agents", type=int, default=8)
    p.add_argument("--targets", type=int, default=8)
    p.add_argument("--distributions", type=int, default=16)
    scenarios = sorted(f.stem for f in SCENARIOS.glob("*.yaml"))  # conf/scenario/
    p.add_argument("--scenario", default="paper", choices=scenarios, help="what the reset draws besides the prior")
    p.add_argument("--seed", type=int, default=0, help="the episode's seed (>= 0)")
    p.add_argument("--agent", type=int, default=0, help="whose belief is drawn")
    p.add_argument("--cell", type=int, default=6, help="pixels per cell (1 to 64)")
    p.add_argument("--fps", type=float, default=10.0, help="frames per second, 0.01 to 100 (whole 1/100 s)")
    p.add_argument("--out", default="runs/render/episode.gif")
    p.add_argument("--device", default="cpu", help="a --checkpoint's torch device: cpu, cuda, cuda:<i>, mps or auto")
    args = p.parse_args(argv)
    if args.checkpoint and (args.controller or args.model):
        given = " and ".join(f"--{k}" for k in ("controller", "model") if getattr(args, k))
        p.error(f"{given} cannot apply with --checkpoint: the policy acts in its run's world (its config.yaml)")
    checks = [
        (args.out.endswith(".gif"), "--out", args.out, "a .gif path"),
        (args.seed >= 0, "--seed", args.seed, ">= 0"),
        (args.agents >= 1, "--agents", args.agents, ">= 1"),
        (0 <= args.agent < args.agents, "--agent", args.agent, f"0 <= agent < --agents={args.agents}"),
        (1 <= args.cell <= 64, "--cell", args.cell, "1 <= cell <= 64 pixels"),
        (0.01 <= args.fps <= 100, "--fps", args.fps, "0.01 <= fps <= 100 (a GIF frame lasts 1 to 10000 / 100 s)"),
    ]
    for ok, name, value, allowed in checks:
        if not ok:
            p.error(f"{name}={value!r} is not allowed: {allowed}")
    from searchrl.evaluate.episode_gif import episode_setup, render_episode

    sizes = {
        "world_size": ("--n", args.n),
        "n_agents": ("--agents", args.agents),
        "n_targets": ("--targets", args.targets),
        "n_distributions": ("--distributions", args.distributions),
    }
    try:
        check_writable(args.out, "--out")
        config, scenario, factory, label = episode_setup(
            args.checkpoint, args.model, args.controller, sizes, args.scenario, args.device
        )
    except ConfigError as err:
        p.error(str(err))
    state, frames = render_episode(
        config, scenario, factory, args.seed, args.agent, args.cell, args.fps, args.out, label
    )
    print(f"wrote {args.out}: {frames} frames, found {int(state.n_found[0])}/{int(state.n_targets[0])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
