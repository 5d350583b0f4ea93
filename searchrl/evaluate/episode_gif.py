"""One episode drawn as an animated GIF in the paper's colours (Fig. 1, Fig. 4), for `python -m searchrl.render`.

Left, the true maps with all agents (purple), hidden (green) and found (brown) targets; right, one agent's belief,
the agent ringed in black. The episode is played as evaluation plays one (`searchrl.controllers.episodes.play`,
its streams from the seed), so a GIF shows what an evaluation row of the same seed measured.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from searchrl.atomic import write_atomic
from searchrl.controllers.episodes import ControllerFactory, episode_streams, play
from searchrl.controllers.factory import heuristic_factory, policy_factory
from searchrl.multirun import said_as_refusal
from searchrl.shared_schema import group_option, model_world
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.frames import AGENT, FOUND, HIDDEN, OBSTACLE, world_frame
from searchrl.world.scenario import Scenario
from searchrl.world.state import WorldState

# What each colour and mark means, drawn under every frame (searchrl/world/frames.py's colours).
LEGEND = (
    (AGENT, "agent"),
    (HIDDEN, "hidden target"),
    (FOUND, "found target"),
    (OBSTACLE, "wall"),
    ((220, 40, 40), "probability"),
    ((40, 40, 220), "uncertainty"),
)


def frame(state: WorldState, agent: int, cell: int, title: str = "") -> np.ndarray:
    """(H, 2W + gap, 3) uint8: the true world beside `agent`'s belief (the agent ringed), under a caption (`title`,
    the step and the targets found) and the panels' names, above a legend of the colours."""
    truth = world_frame(state, 0, cell=cell)
    belief = world_frame(state, 0, belief_of=agent, cell=cell)
    r, c = state.pos[0, agent] * cell
    belief[max(r - cell, 0) : r + 2 * cell, max(c - cell, 0) : c + 2 * cell][[0, -1]] = 0  # ring the agent
    belief[max(r - cell, 0) : r + 2 * cell, max(c - cell, 0) : c + 2 * cell][:, [0, -1]] = 0
    gap = np.full((truth.shape[0], 2 * cell, 3), 255, np.uint8)
    image = Image.fromarray(np.concatenate([truth, gap, belief], axis=1))
    size = max(10, min(2 * cell, 16))  # the font's pixels: readable at every cell size
    font = ImageFont.load_default(size=size)
    line = size + 4
    canvas = Image.new("RGB", (max(image.width, 24 * size), image.height + 4 * line), "white")
    canvas.paste(image, (0, 2 * line))
    draw = ImageDraw.Draw(canvas)
    found = f"t = {int(state.t[0])}, found {int(state.n_found[0])} of {int(state.n_targets[0])} targets"
    draw.text((2, 2), f"{title}   {found}" if title else found, fill="black", font=font)
    draw.text((2, line + 2), "true world", fill="black", font=font)
    draw.text((truth.shape[1] + 2 * cell + 2, line + 2), f"belief of agent {agent} (ringed)", fill="black", font=font)
    x, y = 2, 2 * line + image.height + 4
    for colour, name in LEGEND:
        if x + size + draw.textlength(name, font=font) > canvas.width:  # wrap to the next line
            x, y = 2, y + line
        draw.rectangle((x, y + 2, x + size - 4, y + size - 2), fill=colour)
        draw.text((x + size, y), name, fill="black", font=font)
        x += size + int(draw.textlength(name, font=font)) + size
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


@said_as_refusal
def episode_setup(
    checkpoint: str | None,
    model: str | None,
    controller: str | None,
    sizes: dict[str, tuple[str, int]],
    scenario: str,
    device: str,
) -> tuple[WorldConfig, Scenario, ControllerFactory, str]:
    """(world, scenario, controller factory, its label for the caption) of an episode to draw: a `checkpoint`'s
    policy in its run's world on `device`, else the heuristic `controller` (default surfing) in `model`'s world
    (default b); `sizes` as `episode_world` takes them, `scenario` a conf/scenario/ name. Everything is checked
    here, before the episode: ConfigError, ValueError or FileNotFoundError name what is refused."""
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
        return config, drawn, policy_factory(load_actor(checkpoint, config, device=device)), f"policy {checkpoint}"
    return config, drawn, heuristic_factory(controller or "surfing", check=config), controller or "surfing"


def render_episode(
    config: WorldConfig,
    scenario: Scenario,
    factory: ControllerFactory,
    seed: int,
    agent: int,
    cell: int,
    fps: float,
    out: str | Path,
    controller: str = "",
) -> tuple[WorldState, int]:
    """Play the episode of `seed` with the controller `factory` makes and write its frames to `out` (a GIF,
    atomically), captioned with `controller` (its label), the scenario and the world's size; returns the final
    state and the number of frames."""
    world_streams, controller_streams = episode_streams([(seed,)])  # an episode as evaluation plays one
    world = SearchWorld.from_maps(config, [seed], world_streams, scenario)
    n = int(world.state.size[0])
    title = f"{controller + ', ' if controller else ''}scenario {scenario.label}, {n}x{n}, N = {config.n_agents}"
    frames = [frame(world.state, agent, cell, title)]
    play(
        world,
        factory(config, controller_streams),
        on_step=lambda world, _: frames.append(frame(world.state, agent, cell, title)),
    )
    images = [Image.fromarray(f) for f in frames]
    write_atomic(
        Path(out),
        lambda tmp: images[0].save(
            tmp, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0
        ),
    )
    return world.state, len(frames)
