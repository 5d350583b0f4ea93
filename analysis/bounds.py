# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The search bound over the grid, and each controller's efficiency against it
#
# The bound of a map (searchrl/world/bound.py) is the most targets any team of N agents can expect to find there in
# 256 steps: the expected targets on the K = N(13 + 5·255) cells most likely to hold one. Every controller of the
# suite runs on the same maps (a map depends on its cell and index only, not on the model or the sensing constant),
# so one table of per-cell mean bounds serves every Table 3: a cell's efficiency is its mean found fraction over
# its mean bound fraction. New evaluations also carry the bound per episode row (`bound_fraction`).
#
#     python analysis/bounds.py [TABLE_CSV ...] [--draws 1000] [--maps 100] [--cache runs/bounds] [--out DIR]
#
# Computes the grid's bounds (about 12 min on one core the first time; per-map rows are cached in runs/bounds/) into
# `bounds.csv` / `bounds.md`, then joins each given table (a `table3.csv`, or `calibration.csv`: columns
# controller, model, n, N, mean, low, high) into `efficiency.csv` / `efficiency.md`, and checks that no
# controller's mean exceeds the bound on any cell (beyond 3 Monte Carlo standard errors of the bound's mean).
#
# Beside it, labelled as such, the detection bound (tighter, proved in searchrl/world/bound.py): detection
# probability summed over cells grows by at most ΣΓ in a team member's first phase and D per phase after (3.17
# cardinal, 3.77 diagonal), so B = N(5.44 + 255 D) cells' worth of the largest marginals, about 0.63 K. Each row of
# a table is held to the bound of its model's moves (`env.world.diagonal` in conf/model/<model>.yaml).

# %%
from pathlib import Path

import pandas as pd
from omegaconf import OmegaConf

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.cell_bounds import BOUND_DRAWS, grid_bounds
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.schema import EvaluateConfig, GridConfig
from searchrl.reporting import cli
from searchrl.reporting.stats import is_hard, markdown, with_bounds
from searchrl.world.config import WorldConfig

parser = cli.parser(
    "The search bound over the grid and each controller's efficiency",
    dirs="TABLE_CSV",
    dirs_help="tables of per-cell means (table3.csv, calibration.csv) to join",
)
parser.add_argument("--draws", type=int, default=BOUND_DRAWS, help="placements per map (>= 100)")
parser.add_argument("--maps", type=int, default=GridConfig.maps_per_cell, help="maps per cell (>= 1)")
parser.add_argument("--cache", default="runs/bounds", help="folder of per-map bounds (default runs/bounds)")
args, _ = cli.parse(parser)
if args.draws < 100:
    parser.error(f"--draws={args.draws} is not allowed: an integer >= 100 (the bound's error goes as 1/sqrt(draws))")
if args.maps < 1:
    parser.error(f"--maps={args.maps} is not allowed: an integer >= 1")
tables = [Path(t) for t in args.dirs]
for table in tables:
    if not table.is_file():
        parser.error(f"{table}: no such table (give table3.csv or calibration.csv files)")
OUT = cli.out_dir(args.out, Path.cwd() / "analysis" / "out" / "bounds")
OUT.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## The bound per cell: mean bound fraction over the cell's maps

# %%
grid = GridConfig()
cells = table2_cells(grid.world_sizes, grid.n_targets, grid.n_distributions, grid.max_agents)
bounds = grid_bounds(WorldConfig(), cells, args.maps, EvaluateConfig.seed, args.draws, args.cache)
diagonal = grid_bounds(WorldConfig(diagonal=True), cells, args.maps, EvaluateConfig.seed, args.draws, args.cache)
assert diagonal["bound"].equals(bounds["bound"])  # the same maps, reach and draws: only the detection bound differs
both = bounds.merge(
    diagonal[["n", "N", "budget", "detection_bound", "detection_mc_stderr"]], on=["n", "N"], suffixes=("", "_diagonal")
)
write_atomic(OUT / "bounds.csv", lambda tmp: both.to_csv(tmp, index=False))
wide = bounds.pivot_table(index="N", columns="n", values="bound")
largest_error = bounds["mc_stderr"].max()
text = (
    f"Mean bound fraction per cell ({args.maps} maps, {args.draws} placements per map; the largest Monte Carlo "
    f"standard error of a cell's mean is {largest_error:.4f}):\n\n{markdown(wide)}\n\n"
    f"The detection bound (cardinal moves; largest standard error {bounds['detection_mc_stderr'].max():.4f}):"
    f"\n\n{markdown(bounds.pivot_table(index='N', columns='n', values='detection_bound'))}\n\n"
    f"The detection bound of diagonal moves (largest standard error {diagonal['detection_mc_stderr'].max():.4f}):"
    f"\n\n{markdown(diagonal.pivot_table(index='N', columns='n', values='detection_bound'))}"
)
write_text_atomic(OUT / "bounds.md", text)
print(text)

# %% [markdown]
# ## Efficiency: found / bound per cell, and the upper-bound check


# %%
def moves_diagonally(model: str) -> bool:
    """Whether `model`'s config (conf/model/<model>.yaml) gives its agents diagonal moves."""
    path = Path.cwd() / "conf" / "model" / f"{model}.yaml"
    return path.is_file() and bool(OmegaConf.select(OmegaConf.load(path), "env.world.diagonal", default=False))


frames = []
for table in tables:
    frame = pd.read_csv(table)
    frame = frame.assign(world=frame["world"] if "world" in frame else "bayes", table=str(table))
    frame = frame[["table", "controller", "model", "world", "n", "N", "mean", "low", "high"]]
    frame = frame.assign(order=range(len(frame)))
    moves = frame["model"].map(moves_diagonally)  # each row against the detection bound of its model's moves
    parts = [with_bounds(frame[~moves], bounds), with_bounds(frame[moves], diagonal)]
    frames.append(pd.concat(parts).sort_values("order").drop(columns="order"))
if frames:
    joined = pd.concat(frames, ignore_index=True)
    write_atomic(OUT / "efficiency.csv", lambda tmp: joined.to_csv(tmp, index=False))
    over = joined[joined["mean"] > joined["bound"] + 3 * joined["mc_stderr"]]
    over_detection = joined[joined["mean"] > joined["detection_bound"] + 3 * joined["detection_mc_stderr"]]
    hard = joined[is_hard(joined)]
    columns = ["mean", "bound", "efficiency", "detection_bound", "detection_efficiency"]
    by_controller = hard.groupby(["table", "world", "controller", "model"])[columns].mean()
    unsaturated = joined[joined["bound"] < 0.995]
    parts = [
        f"Upper-bound check: {len(over)} of {len(joined)} cells have a mean above the bound "
        f"(largest found/bound: {joined['efficiency'].max():.3f}; on the {len(unsaturated)} cells whose bound is "
        f"below 0.995: {unsaturated['efficiency'].max():.3f}).\n",
        f"Detection-bound check: {len(over_detection)} of {len(joined)} cells have a mean above the detection bound "
        f"of their model's moves (largest found/detection bound: {joined['detection_efficiency'].max():.3f}).\n",
        f"Mean over the {int(is_hard(bounds).sum())} hard cells "
        "(n = 40 with N <= 2, n = 80 with N <= 8, n = 160 with N <= 32) of found fraction, bound and efficiency "
        "(mean of the per-cell found / bound), and the same against the detection bound of the model's moves:\n",
        markdown(by_controller),
    ]
    for (table, world), block in joined.groupby(["table", "world"], sort=False):
        wide = block.pivot_table(index=["controller", "model", "N"], columns="n", values="efficiency")
        parts.append(f"Efficiency per cell, {table} ({world}):\n\n{markdown(wide)}")
    write_text_atomic(OUT / "efficiency.md", "\n".join(parts))
    print("\n".join(parts[:4]))
    if len(over) or len(over_detection):
        print(pd.concat([over, over_detection]).to_string())
