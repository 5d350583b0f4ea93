# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Which targets a controller misses, by distance to the world's edge
#
# Runs a controller given exactly as to `python -m searchrl.evaluate` (the same overrides, so the same maps, start
# cells and seeds as that evaluation) on the cells named by `--cells`, and counts the targets still unfound when
# each episode ends by their distance to the nearest edge of the world (0: on the edge). Run from the repository
# root:
#
#     python analysis/missed_targets.py [--cells CELL,CELL,...] [--label LABEL] [--out DIR] [OVERRIDE ...]
#
# e.g. `python analysis/missed_targets.py --cells n40_N8,n80_N64 --label greedy_target_c controller=greedy_target
# +model=c grid.repeats=1`. OVERRIDEs are Hydra overrides of `python -m searchrl.evaluate`. `--cells` defaults to
# `SEARCHRL_CELLS`, then n40_N8,n80_N64,n160_N256; `--label` to `SEARCHRL_LABEL`, then the controller's folder name
# (`runs/eval/<label>` of that evaluation); `--out` to `SEARCHRL_ANALYSIS_OUT`, then `analysis/out/missed_targets`
# (what a notebook reads: the environment variables, and no overrides).
#
# Writes `<label>.csv` (one row per cell) into the output folder, then `missed_targets.md` from every CSV there.

# %%
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from hydra import compose, initialize_config_dir
from hydra.errors import HydraException
from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.app import make_controller_factory
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.runner import run_cell
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown

ROOT = Path.cwd()
parser = cli.parser("Which targets a controller misses, by distance to the world's edge", dirs=None)
parser.add_argument(
    "--cells",
    help="comma-separated cells of the grid, e.g. n40_N8,n80_N64 (default: "
    "$SEARCHRL_CELLS, then n40_N8,n80_N64,n160_N256)",
)
parser.add_argument(
    "--label", help="name of the rows and of <label>.csv (default: $SEARCHRL_LABEL, then the controller's folder name)"
)
parser.usage = "missed_targets.py [-h] [--cells CELLS] [--label LABEL] [--out DIR] [OVERRIDE ...]"
args, OVERRIDES = cli.parse(parser, rest=True)  # the rest: Hydra overrides of python -m searchrl.evaluate
flags = [o for o in OVERRIDES if o.startswith("-")]
if flags:
    parser.error(f"unrecognized arguments: {' '.join(flags)}")
CELLS = [c for c in cli.setting(args.cells, "SEARCHRL_CELLS", "n40_N8,n80_N64,n160_N256").split(",") if c]
LABEL = cli.setting(args.label, "SEARCHRL_LABEL")
OUT = cli.out_dir(args.out, ROOT / "analysis" / "out" / "missed_targets")
BINS = ["on_edge", "1_in", "2_in", "3+_in"]  # distance to the nearest edge: 0, 1, 2, 3 or more cells

try:
    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        cfg = OmegaConf.to_object(compose("evaluate", overrides=OVERRIDES))  # the app's typed settings
    world, name, model, factory, needs_obs = make_controller_factory(cfg)
except (HydraException, OmegaConfBaseException, ValueError, FileNotFoundError) as err:  # ConfigError too
    message = str(err).split("\nConfig search path")[0]  # Hydra's lists a group's options, but not their schemas
    cli.stop("\n".join(line for line in message.splitlines() if not line.endswith("_schema")) or type(err).__name__)
# The evaluation's folder name: runs/eval/<controller=…> (greedy_target, though its rows say greedy) or policy_<run>
LABEL = LABEL or (name if cfg.checkpoint is not None else cfg.controller.name).replace(":", "_")
grid = table2_cells(
    list(cfg.grid.world_sizes), list(cfg.grid.n_targets), list(cfg.grid.n_distributions), list(cfg.grid.max_agents)
)
index = {cell.key: i for i, cell in enumerate(grid)}
unknown = [c for c in CELLS if c not in index]
if unknown:
    cli.stop(f"--cells has {unknown}: not cells of the grid; allowed: {', '.join(index)}")

# %% [markdown]
# ## Count the missed targets of each cell


# %%
def edge_bins(state, worlds: np.ndarray, which: np.ndarray) -> np.ndarray:
    """(4,) counts of the targets marked by `which` (K, T) in `worlds` (K,) by distance to the nearest edge."""
    n = state.size[:, None]
    row, col = state.target_pos[..., 0], state.target_pos[..., 1]
    distance = np.minimum(np.minimum(row, col), np.minimum(n - 1 - row, n - 1 - col))
    picked = distance[which & worlds[:, None]]
    return np.bincount(np.minimum(picked, 3), minlength=4)


rows = []
for key in CELLS:
    tally = {"missed": np.zeros(4, np.int64), "all": np.zeros(4, np.int64)}

    def count(state, first, playing, tally=tally):
        tally["missed"] += edge_bins(state, first, state.target_valid & ~state.target_found)
        tally["all"] += edge_bins(state, first, state.target_valid)

    frame = run_cell(
        factory,
        world,
        grid[index[key]],
        index[key],
        cfg.grid.maps_per_cell,
        cfg.grid.repeats,
        cfg.seed,
        cfg.batch_mb,
        needs_obs,
        on_done=count,
    )
    missed, every = tally["missed"], tally["all"]
    rows.append(
        {
            "controller": LABEL,
            "cell": key,
            "episodes": len(frame),
            "found": frame["found_fraction"].mean(),
            "complete": (frame["found_fraction"] == 1).mean(),
            "missed": int(missed.sum()),
            **{f"missed_{b}": int(m) for b, m in zip(BINS, missed, strict=True)},
            "share_of_targets_on_edge": every[0] / every.sum(),
        }
    )
    print(rows[-1], file=sys.stderr)

# %%
OUT.mkdir(parents=True, exist_ok=True)
table = pd.DataFrame(rows)
write_atomic(OUT / f"{LABEL}.csv", lambda tmp: table.to_csv(tmp, index=False))
every_run = pd.concat([pd.read_csv(f) for f in sorted(OUT.glob("*.csv"))], ignore_index=True)
every_run = every_run.sort_values(["cell", "controller"], key=lambda s: s.map(index) if s.name == "cell" else s)
text = "# Missed targets by distance to the edge\n\n" + markdown(every_run.set_index(["cell", "controller"])) + "\n"
write_text_atomic(OUT / "missed_targets.md", text)
print(text)
