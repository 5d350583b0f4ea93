# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---
# %% [markdown]
# # The planner's move values on the student's own states: DAgger labels for expert iteration (an experiment)
#
# The student (a checkpoint) plays whole episodes on Table 2 cells, its actions sampled; at every step the rollout
# planner (`controller=rollout`) scores each agent's five moves on the team's posterior, one agent at a time as it
# plans, and those scores (expected finds of the imagined paths, in targets) are the labels: AggreVaTe's
# cost-to-go of each move under the planner's continuation, on the states the student reaches (DAgger's roll-in).
# `analysis/exit_train.py` fits the student to a softmax of them.
#
# A shard is `shard_<i>.npz` in `--out`, written atomically: the episodes of `--worlds` maps of one cell drawn by
# the shard's seed, one sequence per agent and episode (S sequences of T steps, padded, `mask` the real steps):
# `maps` (S, T, C, F, F) float16, `vector` (S, T, 3), `actions` (S, T) the student's, `values` (S, T, A) the
# planner's (NaN where it did not decide: a world whose targets are all found), and `part_<key>` (S, T, ...) float16
# for each observation part the student's network reads (a whole-map student's `own_map`). A killed collection keeps its
# shards and a rerun writes only the missing ones; `--shards` may grow between runs. A shard's index seeds its cell
# and maps: a later round starts at another `--first`, so it labels other maps.
#
#     python -m analysis.exit_labels --student runs/reference/term/b/model.zip --out runs/exit/round1/labels \
#         --shards 40 --worlds 4 --cells n40_N2,n40_N4,n80_N4,n80_N8 --settings '{"horizon": 32, "team": 8}'

# %%
from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from pathlib import Path

import numpy as np

from searchrl.atomic import write_atomic
from searchrl.controllers.factory import policy_factory
from searchrl.controllers.registry import make_controller
from searchrl.controllers.rollout import Rollout
from searchrl.evaluate.grid import Cell
from searchrl.evaluate.runner import run_cell
from searchrl.policies.checkpoint import checkpoint_config, load_actor
from searchrl.threads import use_threads
from searchrl.world.coarse import reset_parts
from searchrl.world.config import WorldConfig

TARGETS = {40: (8, 16), 80: (16, 32), 160: (32, 64)}  # Table 2's targets and Gaussians per world size
SEED = 9_000_000  # label maps: disjoint from evaluation (7,000,000 + …) and validation


class ValueRecorder(Rollout):
    """The rollout planner that keeps each decision's move values: `scored[i]` (worlds, (W, A)), the i-th agent's."""

    def score(self, state, worlds, *args, **kwargs) -> np.ndarray:
        scores = super().score(state, worlds, *args, **kwargs)
        self.scored.append((worlds, np.nanmean(scores, axis=2)))
        return scores

    def values(self, state, maps, vector, active: np.ndarray | None) -> np.ndarray:
        """(K, N, A) the move values of this step (NaN where no agent decides), the planner's memory advanced as
        its own `act` advances it (its chosen moves are not played)."""
        self.scored: list[tuple[np.ndarray, np.ndarray]] = []
        self.act(state, maps, vector, active)
        out = np.full((state.n_worlds, state.n_agents, self.config.n_actions), np.nan, np.float32)
        for agent, (worlds, scored) in enumerate(self.scored):
            out[worlds, agent] = scored
        return out


# %%
class Labeller:
    """The student acts; the planner labels. Keeps each world's episode and files it when the world restarts."""

    def __init__(self, student, planner: ValueRecorder, episodes: list) -> None:
        self.student, self.planner, self.episodes = student, planner, episodes
        self.open: dict[int, list] = {}
        # The student's observation parts, observed again here (its own copies are its memory, not the record's).
        self.parts = tuple(copy.deepcopy(part) for part in student.actor.parts)
        self.buffers: dict[str, np.ndarray] = {}

    def reset(self, state, mask) -> None:
        self.student.reset(state, mask)
        self.planner.reset(state, mask)
        reset_parts(self.parts, state, self.planner.config, np.flatnonzero(mask))
        for k in np.flatnonzero(mask):
            self.file(int(k))

    def file(self, k: int) -> None:
        steps = self.open.pop(k, [])
        if steps:
            self.episodes.append([np.stack(part, axis=1) for part in zip(*steps, strict=True)])  # each (N, T, ...)

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        values = self.planner.values(state, maps, vector, active)
        actions = self.student.act(state, maps, vector, active)
        playing = np.arange(state.n_worlds) if active is None else np.flatnonzero(active)
        for part in self.parts:
            buffer = self.buffers.get(part.key)
            if buffer is None or buffer.shape[0] != state.n_worlds:
                shape = (state.n_worlds, *part.shape(self.planner.config))
                buffer = self.buffers[part.key] = np.zeros(shape, np.float32)
            part.fill(state, self.planner.config, buffer, playing)
        for k in playing:
            step = (maps[k].astype(np.float16), vector[k].astype(np.float32), actions[k].astype(np.int8), values[k])
            step += tuple(self.buffers[part.key][k].astype(np.float16) for part in self.parts)
            self.open.setdefault(int(k), []).append(step)
        return actions


def pad(episodes: list, part_keys: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """The episodes' sequences (one per agent) padded to the longest: maps, vector, actions, values, the parts
    (`part_<key>`), mask."""
    length = max(e[0].shape[1] for e in episodes)
    keys = ("maps", "vector", "actions", "values", *(f"part_{key}" for key in part_keys))
    out: dict[str, list] = {key: [] for key in (*keys, "mask")}
    for episode in episodes:
        n, t = episode[2].shape
        grow = [(0, 0), (0, length - t)]
        for key, array in zip(keys, episode, strict=True):
            fill = np.nan if key == "values" else 0
            out[key].append(np.pad(array, grow + [(0, 0)] * (array.ndim - 2), constant_values=fill))
        out["mask"].append(np.pad(np.ones((n, t), bool), grow))
    return {key: np.concatenate(parts) for key, parts in out.items()}


def collect_shard(student: str, cells: list[Cell], shard: int, worlds: int, settings: dict) -> dict[str, np.ndarray]:
    """The labelled episodes of shard `shard`: `worlds` maps of the cell its seed draws, one repeat each."""
    world = WorldConfig.from_dict(checkpoint_config(student)[0])
    rng = np.random.default_rng([SEED, shard])
    cell = cells[int(rng.integers(len(cells)))]
    episodes: list = []
    base_factory = None

    def factory(config, streams):
        nonlocal base_factory
        if base_factory is None:
            base_factory = policy_factory(load_actor(student, config))
        own = {**settings}
        if own.get("team", 0) >= config.n_agents:  # a neighbourhood as large as the team is the whole team
            own["team"] = 0
        return Labeller(
            base_factory(config, streams), ValueRecorder(config, seed=streams, rules=make_controller, **own), episodes
        )

    labeller: list = []
    run_cell(lambda c, s: labeller.append(factory(c, s)) or labeller[-1], world, cell, shard, worlds, 1, SEED)
    for made in labeller:
        for k in list(made.open):
            made.file(k)
    part_keys = tuple(part.key for part in labeller[0].parts) if labeller else ()
    return {**pad(episodes, part_keys), "cell": np.array([cell.n, cell.n_agents])}


def save_npz(path: Path, data: dict[str, np.ndarray]) -> None:
    with open(path, "wb") as f:  # a file object: np.savez would add ".npz" to the temporary's name
        np.savez(f, **data)


def parse_cells(text: str) -> list[Cell]:
    cells = []
    for key in text.split(","):
        n, agents = (int(x) for x in key.removeprefix("n").split("_N"))
        if n not in TARGETS:
            raise ValueError(f"--cells: {key!r} is not allowed: n40, n80 or n160 with _N<agents>")
        cells.append(Cell(n, agents, *TARGETS[n]))
    return cells


# %%
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m analysis.exit_labels", description=__doc__)
    parser.add_argument("--student", required=True, help="the student's model.zip")
    parser.add_argument("--out", required=True, help="the labels' folder (shards already there are kept)")
    parser.add_argument("--shards", type=int, default=40)
    parser.add_argument("--first", type=int, default=0, help="the first shard's index (its maps): another round's")
    parser.add_argument("--worlds", type=int, default=4, help="maps per shard")
    parser.add_argument("--cells", default="n40_N2,n40_N4,n80_N4,n80_N8")
    parser.add_argument("--settings", default="{}", help="the planner's settings as JSON")
    args = parser.parse_args(argv)
    try:
        cells, settings = parse_cells(args.cells), json.loads(args.settings)
    except (ValueError, json.JSONDecodeError) as err:
        parser.error(str(err))
    use_threads(1)
    out = Path(args.out)
    for shard in range(args.first, args.first + args.shards):
        path = out / f"shard_{shard:04d}.npz"
        if path.exists():
            continue
        start = time.perf_counter()
        data = collect_shard(args.student, cells, shard, args.worlds, settings)
        write_atomic(path, lambda tmp, d=data: save_npz(tmp, d))
        steps = int(data["mask"].sum())
        print(
            f"{path}: n{data['cell'][0]}_N{data['cell'][1]}, {steps} labelled agent-steps, "
            f"{time.perf_counter() - start:.0f} s",
            file=sys.stderr,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
