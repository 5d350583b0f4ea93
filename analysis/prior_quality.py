# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # How much the prior is worth: prior quality per family of prior error
#
# `prior_quality` (searchrl/world/truth.py) scores how well the prior the agents start from points at a world's true
# targets: per target, the share of free cells the prior rates lower than the target's cell minus the share it rates
# higher, averaged (0: no better than a uniform prior; 1: every target on the prior's best cell). This notebook draws
# the worlds of the grid's world sizes (the Table 2 cell with N = 1 of each n, its targets and Gaussians) under each
# family of prior error at severities 0, 0.5 and 1, with the paper's broad priors (variance scale 10) and sharp ones
# (scale 1), and tabulates the mean quality with a 95 % bootstrap CI over maps. Only worlds are drawn: no controller.
#
#     python analysis/prior_quality.py [--maps 100] [--out DIR]   # -> prior_quality.csv, prior_quality.md

# %%
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.grid import map_seed, table2_cells
from searchrl.evaluate.runner import cell_config
from searchrl.evaluate.schema import EvaluateConfig, GridConfig
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown
from searchrl.world.config import WorldConfig
from searchrl.world.reset import reset_world
from searchrl.world.scenario import Scenario
from searchrl.world.state import allocate
from searchrl.world.truth import PLACERS, prior_qualities

parser = cli.parser("Prior quality per family of prior error, severity and prior sharpness", dirs=None)
parser.add_argument("--maps", type=int, default=100, help="maps per world size (>= 2)")
args, _ = cli.parse(parser)
if args.maps < 2:
    parser.error(f"--maps={args.maps} is not allowed: an integer >= 2 (a CI needs two maps)")
OUT = cli.out_dir(args.out, Path.cwd() / "analysis" / "out" / "prior_quality")
OUT.mkdir(parents=True, exist_ok=True)
FAMILIES = {"off_prior": {}, "shifted": {}, "sharper": {"power": 4.0}, "flatter": {"power": 0.0}, "adversarial": {}}
KINDS = {"sharper": "tempered", "flatter": "tempered"}

# %%
grid, seed = GridConfig(), EvaluateConfig().seed
cells = [
    (index, c)
    for index, c in enumerate(table2_cells(grid.world_sizes, grid.n_targets, grid.n_distributions, grid.max_agents))
    if c.n_agents == 1
]
rows = []
for scale in (10.0, 1.0):
    world = replace(WorldConfig(), prob_variance_scale=scale)
    for index, cell in cells:
        config = cell_config(world, cell)
        for family, settings in FAMILIES.items():
            for severity in (0.0, 0.5, 1.0):
                placer = PLACERS[KINDS.get(family, family)](severity=severity, **settings)
                state = allocate(config, args.maps)
                for m in range(args.maps):  # map m of the cell: the prior every controller sees there
                    reset_world(
                        config, state, m, np.random.default_rng(map_seed(seed, index, m)), Scenario(targets=placer)
                    )
                quality = prior_qualities(state)
                means = np.random.default_rng(0).choice(quality, (1000, len(quality))).mean(axis=1)
                rows.append(
                    {
                        "variance_scale": scale,
                        "n": cell.n,
                        "family": family,
                        "severity": severity,
                        "quality": quality.mean(),
                        "low": np.quantile(means, 0.025),
                        "high": np.quantile(means, 0.975),
                        "maps": args.maps,
                    }
                )
table = pd.DataFrame(rows)
table.head()

# %% [markdown]
# Mean prior quality at severity 0 (the paper's placement), 0.5 and 1, per family; rows: prior sharpness and n.

# %%
table["column"] = [f"{f} {s:g}" if s > 0 else "paper" for f, s in zip(table.family, table.severity, strict=True)]
order = ["paper"] + [f"{f} {s:g}" for f in FAMILIES for s in (0.5, 1.0)]  # severity 0 of every family: the paper's
wide = table[table.severity > 0].pivot_table(index=["variance_scale", "n"], columns="column", values="quality")
wide["paper"] = table[table.family == "off_prior"].pivot_table(
    index=["variance_scale", "n"], columns="column", values="quality"
)["paper"]
wide = wide[order]
write_atomic(OUT / "prior_quality.csv", lambda path: table.to_csv(path, index=False))
write_text_atomic(
    OUT / "prior_quality.md",
    f"Mean prior quality over {args.maps} maps per n (95 % CIs in "
    "prior_quality.csv); columns family and severity, severity 0 the paper's placement\n\n" + markdown(wide) + "\n",
)
print(f"wrote {OUT / 'prior_quality.md'}")
