"""One episode drawn as an animated GIF in the paper's colours (Fig. 1, Fig. 4), for `python -m searchrl.render`.

Left, the true maps with all agents (purple), hidden (green) and found (brown) targets; right, one agent's belief,
the agent ringed in black. The episode is played as evaluation plays one (`searchrl.controllers.episodes.play`,
its streams from the seed), so a GIF shows what an evaluation row of the same seed measured.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from searchrl.atomic import write_atomic
from searchrl.controllers.episodes import ControllerFactory, episode_streams, play
from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.shared_schema import group_option, model_world
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.frames import world_frame
from searchrl.world.scenario import Scenario
from searchrl.world.state import WorldState


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


def episode_world(base: WorldConfig | str, sizes: dict[str, tuple[str, int]]) -> WorldConfig:
    """The world of one drawn episode: `base` (a run's WorldConfig, or a model's name, its conf/model/ world) with
    `sizes` {field: (flag, value)} for world_size, n_agents, n_targets, n_distributions; a refused value is
    named by the flag the user gave, not by the world's field."""
    world = WorldConfig(**model_world(base)) if isinstance(base, str) else base
    values = {field: value for field, (_, value) in sizes.items()}
    try:
        return replace(
            world,
            world_size=(values["world_size"],) * 2,
            n_agents=values["n_agents"],
            n_targets=(values["n_targets"],) * 2,
            n_distributions=(values["n_distributions"],) * 2,
        )
    except ConfigError as err:
        field = next((f for f in sizes if str(err).startswith(f"{f}=")), None)
        raise ConfigError(f"{sizes[field][0]}={sizes[field][1]} ({err})" if field else str(err)) from None


def episode_setup(
    checkpoint: str | None,
    model: str | None,
    controller: str | None,
    sizes: dict[str, tuple[str, int]],
    scenario: str,
    device: str,
) -> tuple[WorldConfig, Scenario, ControllerFactory]:
    """(world, scenario, controller factory) of an episode to draw: a `checkpoint`'s policy in its run's world on
    `device`, else the heuristic `controller` (default surfing) in `model`'s world (default b); `sizes` as
    `episode_world` takes them, `scenario` a conf/scenario/ name. Everything is checked here, before the episode:
    ConfigError, ValueError or FileNotFoundError name what is refused."""
    if checkpoint or device != "cpu":  # torch is imported only where a policy runs or a device is named
        from searchrl.policies.device import policy_device

        device = policy_device(device, bool(checkpoint))
    if checkpoint:
        from searchrl.policies.checkpoint import checkpoint_config, load_actor

        config = episode_world(WorldConfig.from_dict(checkpoint_config(checkpoint)[0]), sizes)
    else:
        config = episode_world(model or "b", sizes)
    drawn = Scenario.from_dict(group_option("scenario", scenario))
    drawn.check(config)
    if checkpoint:
        return config, drawn, policy_factory(load_actor(checkpoint, config, device=device))
    return config, drawn, heuristic_factory(controller or "surfing", check=config)


def render_episode(
    config: WorldConfig,
    scenario: Scenario,
    factory: ControllerFactory,
    seed: int,
    agent: int,
    cell: int,
    fps: float,
    out: str | Path,
) -> tuple[WorldState, int]:
    """Play the episode of `seed` with the controller `factory` makes and write its frames to `out` (a GIF,
    atomically); returns the final state and the number of frames."""
    world_streams, controller_streams = episode_streams([(seed,)])  # an episode as evaluation plays one
    world = SearchWorld.from_maps(config, [seed], world_streams, scenario)
    frames = [frame(world.state, agent, cell)]
    play(
        world,
        factory(config, controller_streams),
        on_step=lambda world, _: frames.append(frame(world.state, agent, cell)),
    )
    images = [Image.fromarray(f) for f in frames]
    write_atomic(
        Path(out),
        lambda tmp: images[0].save(
            tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0
        ),
    )
    return world.state, len(frames)
