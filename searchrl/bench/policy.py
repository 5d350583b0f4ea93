"""Policy inference: every path of the actor beside SB3's `predict` and the CPU's peak, on one batch, in one run.

The batch holds every slot of a few Table 2 worlds (n80, N32). Rows: SB3's `predict`; the actor with torch's eager
extractor (`eager`, the fp32 reference); with the traced, frozen one (`torch`, the default path, bit for bit the
golden episodes'); on the CPU also with ONNX Runtime's (`onnx`). Each acts through the evaluation's controller
(observations and LSTM states from numpy and back, sampling included); `speedup` is the rate over eager's.
On the CPU the run also times a large float32 matrix product (`peak`: what the cores reach on the densest work
there is) and counts the network's multiply-adds a sample (forward hooks on its layers), so each path's GFLOP/s is
a share of that peak: the gap to the hardware is a number.
"""

from __future__ import annotations

import time
from typing import TextIO

import numpy as np
import torch
from torch import nn

from searchrl.controllers.policy import PolicyController
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import cell_config
from searchrl.policies.actor import Actor, policy_copy
from searchrl.policies.checkpoint import checkpoint_config, load_checkpoint
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


def peak_gflops(seconds: float, size: int = 1024) -> float:
    """float32 GFLOP/s of a (size × size) @ (size × size) product on torch's threads: the densest work the cores do."""
    a, b = torch.randn(size, size), torch.randn(size, size)
    return _rate(lambda: a @ b, 2 * size**3, seconds) / 1e9


def actor_flops(model, maps: np.ndarray, vector: np.ndarray) -> float:
    """FLOPs (2 × multiply-adds) of one sample through the actor's network: its convolutions, linear layers and one
    LSTM step, counted by forward hooks on an eager actor's pass over one row."""
    counted = [0]

    def hook(module: nn.Module, inputs: tuple, output: torch.Tensor | tuple) -> None:
        if isinstance(module, nn.Conv2d):
            per_out = module.in_channels // module.groups * module.kernel_size[0] * module.kernel_size[1]
            counted[0] += output[0].numel() * per_out
        elif isinstance(module, nn.Linear):
            counted[0] += module.in_features * module.out_features
        elif isinstance(module, nn.LSTM):
            counted[0] += 4 * module.hidden_size * (module.input_size + module.hidden_size) * module.num_layers

    policy = policy_copy(model).cpu()
    for module in policy.modules():
        module.register_forward_hook(hook)
    actor = Actor(policy, optimize=False)
    actor.logits(maps[:1], vector[:1], actor.initial_state(1))
    return 2.0 * counted[0]


def run(
    checkpoint: str,
    threads: int = 2,
    worlds: int = 128,
    seconds: float = 3.0,
    device: str = "cpu",
    log: TextIO | None = None,
) -> list[dict]:
    """One row per engine (sb3_predict, eager, torch and on the CPU onnx), each with its network on `device` (a
    checked one, searchrl/policies/device.py): agent-steps/s, the speedup over eager, and on the CPU GFLOP/s and
    their share of the peak measured in the same run."""
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

    engines = {"sb3_predict": sb3}
    on_cpu = torch.device(device).type == "cpu"
    paths = [("eager", "torch", False), ("torch", "torch", True)] + ([("onnx", "onnx", True)] if on_cpu else [])
    for name, inference, optimize in paths:
        actor = Actor(policy_copy(model), optimize=optimize, device=device, inference=inference)
        controller = PolicyController(actor, config, seed=0)
        controller.reset(state, np.ones(worlds, bool))
        engines[name] = lambda c=controller: c.act(state, maps, vector)
    case = f"policy_n80_N32_batch{batch}_threads{threads}"
    rows = [
        {"case": case, "engine": name, "device": str(device), "agent_steps_per_s": round(_rate(act, batch, seconds), 1)}
        for name, act in engines.items()
    ]
    eager = rows[1]["agent_steps_per_s"]
    for row in rows:
        row["speedup"] = round(row["agent_steps_per_s"] / eager, 2)
    if on_cpu:
        flops, peak = actor_flops(model, obs["map"], obs["vector"]), peak_gflops(seconds)
        for row in rows:
            row["gflops"] = round(row["agent_steps_per_s"] * flops / 1e9, 1)
            row["peak_share"] = round(row["gflops"] / peak, 2)
        rows.append({"case": case, "engine": "peak", "device": "cpu", "gflops": round(peak, 1), "mflop": flops / 1e6})
    if log:
        shown = ", ".join(f"{r['engine']} {r['agent_steps_per_s']:,.0f} ({r['speedup']:.2f}x)" for r in rows[:-1])
        print(f"{case}: agent-steps/s (x eager) {shown}", file=log)
        if on_cpu:
            shares = ", ".join(f"{r['engine']} {r['peak_share']:.0%}" for r in rows[:-1])
            print(f"  {flops / 1e6:.2f} MFLOP a sample; float32 peak {peak:.0f} GFLOP/s; share: {shares}", file=log)
    return rows
