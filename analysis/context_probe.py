# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Does a context policy read its context?
#
# Runs a checkpoint trained with the whole-belief context (`env.world.context` = G > 0) on a few hard cells and,
# at every step, asks the same network — same LSTM state, same field of view — for its action distribution twice
# more: once with the context blanked (all zeros) and once with the context of another world of the same cell
# (the next world in the batch: real, but not this agent's). The episode itself follows the real context.
#
# Per cell it reports, over all agent-steps: how often the most likely action changes, and the mean total-variation
# distance between the action distributions. A policy that ignores its context scores near 0 on both; one that
# steers by it changes its choice when shown another world's belief. For scale, the same for the field of view
# of another world's agent (the context kept). And the share of agent-steps whose view is depleted (no belief p in
# it above a tenth of the prior's peak): there the view has nothing left to say and only the context can steer,
# with how often the other world's context changes the choice on those steps.
#
#     python analysis/context_probe.py runs/train/b/context_term/model.zip --out analysis/out/context_policy
#
# `--cells n80_N4,n160_N8` picks cells of the evaluation's default grid (Table 2's targets and distributions),
# `--worlds 32` the worlds per cell, `--seed` their draw. Writes `context_probe.md`.

# %%
import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import torch

from searchrl.analysis.stats import markdown
from searchrl.atomic import write_text_atomic
from searchrl.controllers.policy import checkpoint_config, load_checkpoint
from searchrl.evaluate.grid import Cell, table2_cells
from searchrl.evaluate.runner import cell_config
from searchrl.evaluate.schema import GridConfig
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld

GRID = GridConfig()  # the evaluation's default grid, Table 2
P_CHANNEL = 3  # belief p in the field of view, scaled by 1 / the prior's peak (searchrl/world/observe.py)
DEPLETED = 0.1

parser = argparse.ArgumentParser(description="How much a context policy's actions depend on its context")
parser.add_argument("checkpoint", help="a model.zip trained with env.world.context > 0")
parser.add_argument("--cells", default="n40_N2,n80_N4,n80_N8,n160_N8,n160_N32", help="comma-separated n<n>_N<N>")
parser.add_argument("--worlds", type=int, default=32, help="worlds per cell (>= 2)")
parser.add_argument("--seed", type=int, default=11, help="seed of the worlds and of the sampled actions")
parser.add_argument("--out", default="analysis/out/context_policy", help="output folder")
args = parser.parse_args()

if args.worlds < 2:
    parser.error(f"--worlds={args.worlds} is not allowed: 2 or more (the swap shows each world its neighbour's)")
table2 = table2_cells(GRID.world_sizes, GRID.n_targets, GRID.n_distributions, GRID.max_agents)
grid = {cell.key: cell for cell in table2}
unknown = [key for key in args.cells.split(",") if key not in grid]
if unknown:
    parser.error(f"--cells has {unknown}: not cells of the grid; allowed: {', '.join(grid)}")
cells = [grid[key] for key in args.cells.split(",")]
try:
    world_settings, algo, _ = checkpoint_config(args.checkpoint)
except (FileNotFoundError, ValueError) as err:
    parser.error(str(err))
base = WorldConfig.from_dict(world_settings)
if not base.context:
    parser.error(f"checkpoint={args.checkpoint!r} was trained without the context (env.world.context=0)")
try:
    model = load_checkpoint(args.checkpoint, algo)
except ValueError as err:
    parser.error(str(err))
policy = model.policy


# %%
def distribution(obs: dict[str, np.ndarray], lstm: tuple, starts: np.ndarray) -> tuple[np.ndarray, tuple]:
    """Action probabilities (B, A) and the LSTM state after this step, for a flat batch of B agents."""
    with torch.no_grad():
        obs_tensor, _ = policy.obs_to_tensor(obs)
        dist, state = policy.get_distribution(obs_tensor, lstm, torch.as_tensor(starts, dtype=torch.float32))
    return dist.distribution.probs.numpy(), state


def probe_cell(cell: Cell) -> dict[str, float]:
    agents = cell.n_agents
    world = SearchWorld(cell_config(base, cell), args.worlds, seed=args.seed)
    maps, vector = world.reset()
    flat = args.worlds * agents
    shape = (policy.lstm_actor.num_layers, flat, policy.lstm_actor.hidden_size)
    lstm = (torch.zeros(shape), torch.zeros(shape))
    starts = np.ones(flat, np.float32)
    rng = np.random.default_rng(args.seed)
    finished = np.zeros(args.worlds, bool)
    changed = {"blank": [], "other world": [], "view of another world": []}
    distance = {name: [] for name in changed}
    depleted = []  # steps whose view holds no belief p above DEPLETED of the prior's peak: where context must steer
    while not finished.all():
        context = world.context.reshape(flat, *world.context.shape[2:])
        obs = {"map": maps.reshape(flat, *maps.shape[2:]), "vector": vector.reshape(flat, -1), "context": context}
        probs, next_lstm = distribution(obs, lstm, starts)
        other = np.roll(world.context, 1, axis=0).reshape(context.shape)  # world k sees world k-1's beliefs
        other_view = np.roll(maps, 1, axis=0).reshape(obs["map"].shape)
        live = np.repeat(~finished, agents)
        depleted.append((obs["map"][:, P_CHANNEL].max(axis=(1, 2)) < DEPLETED)[live])
        for name, altered in (
            ("blank", {"context": np.zeros_like(context)}),
            ("other world", {"context": other}),
            ("view of another world", {"map": other_view}),  # the scale: what the field of view moves
        ):
            alt, _ = distribution({**obs, **altered}, lstm, starts)
            changed[name].append((probs.argmax(1) != alt.argmax(1))[live])
            distance[name].append(0.5 * np.abs(probs - alt).sum(1)[live])
        lstm = next_lstm
        cumulative = probs.cumsum(1)
        actions = (cumulative < rng.random((flat, 1))).sum(1).clip(max=probs.shape[1] - 1)
        tr = world.step(actions.reshape(args.worlds, agents))
        maps, vector = tr.maps, tr.vector
        finished |= tr.result.done
        starts = np.repeat(tr.result.done, agents).astype(np.float32)
    empty = np.concatenate(depleted)
    row = {"cell": cell.key, "depleted view": float(empty.mean())}
    for name in changed:
        row[f"argmax changed, {name}"] = float(np.concatenate(changed[name]).mean())
        row[f"TV distance, {name}"] = float(np.concatenate(distance[name]).mean())
    row["argmax changed, other world, depleted view"] = float(np.concatenate(changed["other world"])[empty].mean())
    return row


# %%
rows = [probe_cell(cell) for cell in cells]
table = pd.DataFrame(rows)
print(table.to_string(index=False, float_format="%.3f"))
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
text = (
    f"# Context probe of {args.checkpoint}\n\n{args.worlds} worlds per cell, seed {args.seed}; per agent-step, "
    "the share whose most likely action changes and the mean total-variation distance of the action distribution "
    "when the context is blanked or swapped for another world's, and (for scale) when the field of view is.\n\n"
    + markdown(table.set_index("cell"))
    + "\n"
)
write_text_atomic(out / "context_probe.md", text)
