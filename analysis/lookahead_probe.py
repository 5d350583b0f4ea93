# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # How much one move can add to the teacher's episode (a probe, outside the library)
#
# The question before AggreVaTe-style imitation (learn the move that is best when the teacher plays on after it,
# Ross & Bagnell 2014): at a state the teacher reaches, does any move of one agent lead to more targets found by the
# episode's end than the teacher's own move, everyone playing the teacher afterwards? Measured in the true world,
# which training may use and no agent sees: the privileged one-step advantage Q(s, a) − Q(s, teacher(s)).
#
# A sample: one map of a cell (model B's settings), the teacher (target-greedy, reach 2) played to a random step t0,
# one agent. There each action is tried in M continuations; continuation m draws the same numbers (detections,
# priorities, the teacher's random moves) whatever the action (common random numbers), so the branches differ only by
# the move. The best move is chosen on half the continuations and scored on the other half, both ways round
# (cross-fitting), so the gain is not the maximum of noise: its mean is an unbiased estimate of what a learner that
# knew the true state could add per decision. Found fraction at the episode's end (256 steps), as the evaluation
# scores it.
#
#     python -m analysis.lookahead_probe --samples 40 --continuations 8 --out analysis/out/lookahead_probe  # 5 min
#
# Per cell: the mean privileged gain per decision over the teacher's move (`gain_per_decision`, 95 % CI over
# samples) and how often the teacher's move is the best one; then the *planned* move, chosen as a planner without
# the truth would choose it (the highest mean over `--imagined` copies per move whose unfound targets are redrawn
# from the team's posterior, `analysis/lookahead.py`'s `posterior_targets`) and scored in the true continuations it
# did not see (`gain_planned`, with its 95 % half-width). The privileged gain bounds what AggreVaTe could learn from the
# truth; the planned gain is what the team's own knowledge finds of it.

# %%
from pathlib import Path

import numba
import numpy as np
import pandas as pd

from analysis.lookahead import posterior_targets
from searchrl.atomic import write_text_atomic
from searchrl.bench.world import case_config
from searchrl.controllers.registry import make_controller
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown
from searchrl.world.engine import SearchWorld
from searchrl.world.streams import WorldStreams

parser = cli.parser("How much one move can add to the teacher's episode", dirs=None)
parser.add_argument("--cells", default="40x1,80x4,160x16", help="n x N, comma-separated (Table 2's side n)")
parser.add_argument("--samples", type=int, default=40, help="samples per cell (map, step, agent), >= 2")
parser.add_argument("--continuations", type=int, default=8, help="continuations per move, even, >= 2")
parser.add_argument("--imagined", type=int, default=0, help="imagined copies per move (0: as many as continuations)")
parser.add_argument("--seed", type=int, default=0, help="the samples' seed, >= 0")
args, _ = cli.parse(parser)
OUT = cli.out_dir(args.out, Path("analysis") / "out" / "lookahead_probe")
TABLE2_SIDES = (20, 40, 80, 160)  # the sides `case_config` knows Table 2's targets and Gaussians for
CELLS = []
for cell in args.cells.split(","):
    n, _, team = cell.partition("x")
    if not (n.isdigit() and int(n) in TABLE2_SIDES and team.isdigit() and int(team) >= 1):
        cli.stop(f"--cells {cell!r} is not allowed: n x N with n one of {TABLE2_SIDES} and N >= 1, e.g. 40x1")
    CELLS.append((int(n), int(team)))
if args.samples < 2 or args.continuations < 2 or args.continuations % 2 or args.imagined < 0 or args.seed < 0:
    cli.stop(
        f"--samples {args.samples}, --continuations {args.continuations}, --imagined {args.imagined}, --seed "
        f"{args.seed} are not allowed: samples >= 2, continuations even and >= 2 (two halves), imagined >= 0, "
        "seed >= 0"
    )
IMAGINED = args.imagined or args.continuations
numba.set_num_threads(1)


# %%
def branch_values(n: int, n_agents: int, sample: int, m: int, imagined: int, rng: np.random.Generator) -> dict | None:
    """One sample: q[a, j], the found fraction at the episode's end in the true world after agent i plays a at t0
    and the teacher plays every other move, and the same in `imagined` worlds whose unfound targets are redrawn from
    the team's posterior; None when the episode ends before t0."""
    config = case_config(n, n_agents)
    n_actions, max_steps = config.n_actions, config.max_steps
    k = n_actions * (m + imagined)  # the true world's m continuations per move, then `imagined` copies per move
    map_seed = int(rng.integers(2**31))
    t0, agent = int(rng.integers(0, max_steps // 2)), int(rng.integers(n_agents))
    # The prefix: K identical worlds on identical streams play the teacher to t0, so they stay identical.
    world = SearchWorld.from_maps(config, [map_seed] * k, WorldStreams([[args.seed, sample, 0]] * k), observe=False)
    teacher_streams = WorldStreams([[args.seed, sample, 1]] * k)
    teacher = make_controller("greedy_target", config, seed=teacher_streams, settings={"reach": 2})
    teacher.reset(world.state, np.ones(k, bool))
    for _ in range(t0):
        if world.step(teacher.act(world.state, None, None)).result.done[0]:
            return None
    # World a·m + j is the true world's continuation j of move a, world A·m + a·imagined + j imagined copy j of move
    # a; their streams depend on (true or imagined, j) only (common random numbers), imagined copy j's targets on j.
    half = n_actions * m
    state, h, drawn = world.state, world.state.halo, world._last_map[1]
    inner = (0, slice(h, h + n), slice(h, h + n))
    lost = np.flatnonzero(state.target_valid[0] & ~state.target_found[0])
    free = drawn.free & ~state.found_grid[inner]
    draws = posterior_targets(
        state.p[inner], drawn.u, free, len(lost), imagined, np.random.default_rng([args.seed, sample, 3])
    )
    for place in range(half, k):
        state.target_pos[place, lost] = draws[(place - half) % imagined]
    keys = [
        [args.seed, sample, 2, g, j]
        for g, count in ((0, m), (1, imagined))
        for _ in range(n_actions)
        for j in range(count)
    ]
    world.rng.restart(range(k), keys)
    teacher_streams.restart(range(k), [[*key, 1] for key in keys])
    actions = teacher.act(world.state, None, None)
    own = int(actions[0, agent])
    actions[:, agent] = np.concatenate([np.repeat(np.arange(n_actions), m), np.repeat(np.arange(n_actions), imagined)])
    world.step(actions)
    while int(world.state.t[0]) < max_steps and not (world.state.n_found == world.state.n_targets).all():
        world.step(teacher.act(world.state, None, None))
    found = world.state.n_found / world.state.n_targets
    return {
        "t0": t0,
        "teacher": own,
        "q": found[:half].reshape(n_actions, m),
        "imagined": found[half:].reshape(n_actions, imagined),
    }


def cross_fitted_gain(q: np.ndarray, own: int) -> float:
    """Mean over the two halves of (best move chosen on one half) − (the teacher's move), scored on the other."""
    half = q.shape[1] // 2
    gains = []
    for pick, score in ((slice(0, half), slice(half, None)), (slice(half, None), slice(0, half))):
        best = int(np.argmax(q[:, pick].mean(axis=1)))
        gains.append(q[best, score].mean() - q[own, score].mean())
    return float(np.mean(gains))


# %%
rows = []
for n, n_agents in CELLS:
    rng = np.random.default_rng([args.seed, n, n_agents])
    drawn = 0
    while drawn < args.samples:
        got = branch_values(n, n_agents, len(rows), args.continuations, IMAGINED, rng)
        if got is None:
            continue
        q, own = got["q"], got["teacher"]
        means = q.mean(axis=1)
        planned = int(np.argmax(got["imagined"].mean(axis=1)))  # the best move by the team's posterior
        rows.append(
            {
                "n": n,
                "N": n_agents,
                "t0": got["t0"],
                "teacher_q": means[own],
                "best_q": means.max(),
                "teacher_is_best": bool(means[own] >= means.max() - 1e-12),
                "spread": float(means.max() - means.min()),
                "sd_within": float(q.std(axis=1, ddof=1).mean()),
                "sd_paired": float(np.delete(q - q[own], own, axis=0).std(axis=1, ddof=1).mean()),
                "gain": cross_fitted_gain(q, own),
                "planned_is_teacher": planned == own,
                "gain_planned": float(means[planned] - means[own]),
            }
        )
        drawn += 1
    print(f"{n}x{n_agents}: {drawn} samples", flush=True)

# %%
table = pd.DataFrame(rows)
summary = []
for (n, n_agents), cell in table.groupby(["n", "N"]):
    gain = cell["gain"].to_numpy()
    half = 1.96 * gain.std(ddof=1) / np.sqrt(len(gain))
    summary.append(
        {
            "n": n,
            "N": n_agents,
            "samples": len(cell),
            "found_by_teacher": cell["teacher_q"].mean(),
            "gain_per_decision": gain.mean(),
            "ci_low": gain.mean() - half,
            "ci_high": gain.mean() + half,
            "teacher_is_best": cell["teacher_is_best"].mean(),
            "spread": cell["spread"].mean(),
            "sd_within": cell["sd_within"].mean(),
            "sd_paired": cell["sd_paired"].mean(),
            "planned_is_teacher": cell["planned_is_teacher"].mean(),
            "gain_planned": cell["gain_planned"].mean(),
            "gain_planned_ci": 1.96 * cell["gain_planned"].std(ddof=1) / np.sqrt(len(cell)),
        }
    )
summary = markdown(pd.DataFrame(summary).set_index(["n", "N"]), digits=4)
OUT.mkdir(parents=True, exist_ok=True)
write_text_atomic(OUT / "samples.csv", table.to_csv(index=False))
write_text_atomic(OUT / "probe.md", summary)
print(summary)
