"""`python -m searchrl.render [--controller NAME | --checkpoint model.zip [--device cuda]] [--out episode.gif]`

NAME: a heuristic of searchrl/controllers/registry.py (docs/controllers.md lists them).

Writes one episode as an animated GIF in the paper's colours (Fig. 1, Fig. 4): left, the true maps with all agents
(purple), hidden (green) and found (brown) targets; right, one agent's belief, the agent ringed in black.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from searchrl.atomic import check_writable, write_atomic
from searchrl.controllers.episodes import episode_streams, play
from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.controllers.registry import HEURISTICS
from searchrl.paths import CONF_DIR
from searchrl.schema import group_option
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.render import world_frame
from searchrl.world.scenario import Scenario
from searchrl.world.state import WorldState

SCENARIOS = CONF_DIR / "scenario"  # the Hydra group's files, by name

MODELS = {
    "a": {"explicit_area": 11, "communication": False, "diagonal": False},
    "b": {"explicit_area": 5, "communication": True, "diagonal": False},
    "c": {"explicit_area": 5, "communication": False, "diagonal": False},
    "diagonal": {"explicit_area": 5, "communication": True, "diagonal": True},
}


def frame(state: WorldState, agent: int, cell: int) -> np.ndarray:
    """(H, 2W + gap, 3) uint8: the true world beside `agent`'s belief, with a caption line."""
    truth = world_frame(state, 0, cell=cell)
    belief = world_frame(state, 0, belief_of=agent, cell=cell)
    r, c = state.pos[0, agent] * cell
    belief[max(r - cell, 0) : r + 2 * cell, max(c - cell, 0) : c + 2 * cell][[0, -1]] = 0  # ring the agent
    belief[max(r - cell, 0) : r + 2 * cell, max(c - cell, 0) : c + 2 * cell][:, [0, -1]] = 0
    gap = np.full((truth.shape[0], 2 * cell, 3), 255, np.uint8)
    image = Image.fromarray(np.concatenate([truth, gap, belief], axis=1))
    canvas = Image.new("RGB", (image.width, image.height + 16), "white")
    canvas.paste(image, (0, 16))
    text = f"t={int(state.t[0])}  found {int(state.n_found[0])}/{int(state.n_targets[0])}   |   belief of agent {agent}"
    ImageDraw.Draw(canvas).text((2, 2), text, fill="black")
    return np.asarray(canvas)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m searchrl.render", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    p.add_argument("--controller", choices=list(HEURISTICS),
                   help="a heuristic (default surfing); not with --checkpoint")  # fmt: skip
    p.add_argument("--checkpoint", help="a trained model.zip (its run's world settings are used)")
    p.add_argument("--model", choices=sorted(MODELS), help="world settings for heuristics (default b)")
    p.add_argument("--n", type=int, default=40, help="world side")
    p.add_argument("--agents", type=int, default=8)
    p.add_argument("--targets", type=int, default=8)
    p.add_argument("--distributions", type=int, default=16)
    p.add_argument("--scenario", default="paper", choices=sorted(f.stem for f in SCENARIOS.glob("*.yaml")),
                   help="what the reset draws besides the prior (conf/scenario/)")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="the episode's seed (>= 0)")
    p.add_argument("--agent", type=int, default=0, help="whose belief is drawn")
    p.add_argument("--cell", type=int, default=6, help="pixels per cell (1 to 64)")
    p.add_argument(
        "--fps", type=float, default=10.0, help="frames per second, 0.01 to 100 (GIF delays are whole 1/100 s)"
    )
    p.add_argument("--out", default="runs/render/episode.gif")
    p.add_argument("--device", default="cpu",
                   help="torch device of a --checkpoint's network: cpu, cuda, cuda:<index>, mps or auto")  # fmt: skip
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
    device = "cpu"
    if args.checkpoint or args.device != "cpu":  # torch is imported only where a policy runs or a device is named
        from searchrl.policies.device import resolve_device

        try:
            device = resolve_device(args.device, "--device")
        except ConfigError as err:
            p.error(str(err))
        if not args.checkpoint and args.device != "auto":
            p.error(f"--device={args.device!r} is not allowed: cpu without --checkpoint (a heuristic runs on the CPU)")
    try:
        check_writable(args.out, "--out")
    except ValueError as err:
        p.error(str(err))
    try:
        if args.checkpoint:
            from searchrl.policies.checkpoint import checkpoint_config, load_actor

            world = WorldConfig.from_dict(checkpoint_config(args.checkpoint)[0])
        else:
            world = WorldConfig(**MODELS[args.model or "b"])
        flags = {
            "world_size": ("--n", args.n),
            "n_agents": ("--agents", args.agents),
            "n_targets": ("--targets", args.targets),
            "n_distributions": ("--distributions", args.distributions),
        }
        try:
            config = replace(world, world_size=(args.n, args.n), n_agents=args.agents,
                             n_targets=(args.targets, args.targets),
                             n_distributions=(args.distributions, args.distributions))  # fmt: skip
        except ConfigError as err:  # named by the flag the user gave, not by the world's field
            field = next((f for f in flags if str(err).startswith(f"{f}=")), None)
            raise ConfigError(f"{flags[field][0]}={flags[field][1]} ({err})" if field else str(err)) from None
        scenario = Scenario.from_dict(group_option("scenario", args.scenario))
        scenario.check(config)
        if args.checkpoint:
            factory = policy_factory(load_actor(args.checkpoint, config, device=device))
        else:  # its settings checked before the episode
            factory = heuristic_factory(args.controller or "surfing", check=config)
    except (ConfigError, FileNotFoundError, ValueError) as err:
        p.error(str(err))
    world_streams, controller_streams = episode_streams([(args.seed,)])  # an episode as evaluation plays one
    world = SearchWorld.from_maps(config, [args.seed], world_streams, scenario)
    frames = [frame(world.state, args.agent, args.cell)]
    play(world, factory(config, controller_streams),
         on_step=lambda world, _: frames.append(frame(world.state, args.agent, args.cell)))  # fmt: skip
    images = [Image.fromarray(f) for f in frames]
    write_atomic(Path(args.out), lambda tmp: images[0].save(tmp, format="GIF", save_all=True,
                 append_images=images[1:], duration=int(1000 / args.fps), loop=0))  # fmt: skip
    state = world.state
    print(f"wrote {args.out}: {len(frames)} frames, found {int(state.n_found[0])}/{int(state.n_targets[0])}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
