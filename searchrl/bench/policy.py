"""Policy inference: SB3's `predict` against the traced `Actor` on one batch of real observations, in one run.

Both sample actions and carry the LSTM state; the batch holds every slot of a few Table 2 worlds (n80, N32). With
--device both run their network there, and both move the observations and LSTM states from numpy and back each
call."""

from __future__ import annotations

import time
from typing import TextIO

import numpy as np

from searchrl.controllers.policy import PolicyController
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config
from searchrl.policies.checkpoint import checkpoint_config, load_actor, load_checkpoint
from searchrl.threads import use_threads
from searchrl.world.config import WorldConfig
from searchrl.world.observe import observe
from searchrl.world.reset import reset_world
from searchrl.world.state import allocate


def _rate(act, batch: int, seconds: float) -> float:
    act()  # warm-up
    calls, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        act()
        calls += 1
    return calls * batch / elapsed


def run(
    checkpoint: str,
    threads: int = 2,
    worlds: int = 128,
    seconds: float = 3.0,
    device: str = "cpu",
    log: TextIO | None = None,
) -> list[dict]:
    """Two rows, SB3's predict and the actor's controller on the same batch, each with its network on `device` (a
    checked one, searchrl/policies/device.py): agent-steps/s, and the actor's speedup."""
    use_threads(threads, network_on_cpu=str(device) == "cpu")
    world_dict, _, _ = checkpoint_config(checkpoint)
    config = cell_config(WorldConfig.from_dict(world_dict), Cell(80, 32, 16, 32))
    state = allocate(config, worlds)
    for w in range(worlds):
        reset_world(config, state, w, np.random.default_rng(w))
    maps, vector = observe(config, state)
    batch = worlds * config.n_agents
    obs = {"map": maps.reshape(batch, *maps.shape[2:]), "vector": vector.reshape(batch, -1)}

    model = load_checkpoint(checkpoint, device=device)
    lstm = [None]
    starts = np.zeros(batch, bool)

    def sb3() -> None:
        _, lstm[0] = model.predict(obs, state=lstm[0], episode_start=starts)

    controller = PolicyController(load_actor(checkpoint, config, device=device), config, seed=0)
    controller.reset(state, np.ones(worlds, bool))
    rows = []
    for name, act in (("sb3_predict", sb3), ("actor", lambda: controller.act(state, maps, vector))):
        rows.append(
            {
                "case": f"policy_n80_N32_batch{batch}_threads{threads}",
                "engine": name,
                "device": str(device),
                "agent_steps_per_s": round(_rate(act, batch, seconds), 1),
            }
        )
    speedup = rows[1]["agent_steps_per_s"] / rows[0]["agent_steps_per_s"]
    rows[1]["speedup"] = round(speedup, 2)
    if log:
        print(
            f"{rows[0]['case']}: SB3 predict {rows[0]['agent_steps_per_s']:,.0f} agent-steps/s, traced actor "
            f"{rows[1]['agent_steps_per_s']:,.0f} ({speedup:.2f}x)",
            file=log,
        )
    return rows
