# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Which k: the heuristics on the full grid in four worlds, beside the paper's Table 3
#
# The paper's sensing is Δp = λkΓp with λ = 0.001 and "k a coefficient related to world size n". This reads the
# evaluations `analysis/calibrate.sh` made (surfing, coverage, random, footprint-greedy and target-greedy, 100 maps ×
# 1 repeat per cell, in B's world) for λk = 1 (`bayes`) and k = n/2, n (`paper`), 2n, and writes to
# `analysis/out/calibration/`: `calibration.csv` (per world, controller and cell: mean with a 95 % bootstrap CI over
# maps), `calibration.md` (the measures below and the surfing table), `calibration.png` (found fraction against λk
# per world size, the paper's DRL numbers marked). Run from the repository root:
#
#     bash analysis/calibrate.sh && python analysis/calibration.py [runs/eval/calibration] [analysis/out/calibration]

# %%
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import load, world_config_of
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, paper_table3, summarize

ROOT = Path.cwd()
parser = cli.parser("Which k: the heuristics on the full grid in four worlds", dirs=None)
parser.add_argument("root", nargs="?", metavar="CAL_ROOT", help="default runs/eval/calibration")
parser.add_argument("out_dir", nargs="?", metavar="OUT", help="default analysis/out/calibration (or --out)")
args, _ = cli.parse(parser)  # a notebook kernel's own flags (-f <connection file>) are dropped
CAL = Path(args.root) if args.root else ROOT / "runs" / "eval" / "calibration"
OUT = Path(args.out_dir or args.out or ROOT / "analysis" / "out" / "calibration")
folders = sorted(p for p in CAL.glob("*/*") if (p / "cells").is_dir())
if not folders:
    sys.exit(f"error: no evaluation folders under {CAL}: run `bash analysis/calibrate.sh` first")
summaries = []
for folder in folders:  # the folder names the controller variant (greedy and target-greedy are both `greedy`)
    episodes, world = load(folder), world_config_of(folder)
    cells = summarize(episodes).assign(world=episodes.world.iloc[0], controller=folder.name)
    # λk of each cell: k + k_per_n·n of the world the folder records (a checkpoint folder records none)
    cells["lam_k"] = world.sensing_rate(cells.n.to_numpy()) if world else np.nan
    summaries.append(cells)
summary = pd.concat(summaries, ignore_index=True)
paper = paper_table3(ROOT / "analysis" / "paper_table3.csv")
drl_b = paper[paper.model == "B"].set_index(["n", "N"]).found_fraction  # the paper's DRL in B's world
summary["paper_B"] = [drl_b.get((n, agents), np.nan) for n, agents in zip(summary.n, summary.N, strict=True)]
OUT.mkdir(parents=True, exist_ok=True)
write_atomic(OUT / "calibration.csv", lambda tmp: summary.to_csv(tmp, index=False))
print(f"{len(summary)} cells from {len(folders)} folders under {CAL}")

# %% [markdown]
# ## The measures
#
# The paper says two things a world must reproduce: a single agent in a 20×20 world finds about half the targets
# in 256 steps (its DRL models: 0.51–0.60), and information surfing finds less than its DRL ("much better", Fig. 8:
# surfing "easily stuck in high information area"). So per world: (1) surfing's and random's found fraction at
# n = 20, N = 1; (2) on how many of the 30 cells surfing's 95 % CI lies below the paper's B, and on how many above;
# (3) the mean and root-mean-square of surfing − paper's B over the 30 cells (how far the world's difficulty sits
# from the paper's).

# %%
rows = []
for world, block in summary.groupby("world", sort=False):
    surf = block[block.controller == "surfing"].set_index(["n", "N"])
    single = block[(block.n == 20) & (block.N == 1)].set_index("controller")["mean"]
    diff = surf["mean"] - surf["paper_B"]
    rows.append(
        {
            "world": world,
            "surfing n20 N1": single.get("surfing"),
            "random n20 N1": single.get("random"),
            "target-greedy n20 N1": single.get("greedy_target"),
            "surfing < paper B": int((surf["high"] < surf["paper_B"]).sum()),
            "surfing > paper B": int((surf["low"] > surf["paper_B"]).sum()),
            "mean surfing − B": diff.mean(),
            "rms surfing − B": float(np.sqrt((diff**2).mean())),
        }
    )
measures = pd.DataFrame(rows).set_index("world")
surfing = summary[summary.controller == "surfing"].pivot_table(index=["world", "N"], columns="n", values="mean")
best = summary.loc[summary.groupby(["world", "n", "N"])["mean"].idxmax()]
best_table = best.pivot_table(index=["world", "N"], columns="n", values="controller", aggfunc="first")
text = (
    "# Which k: heuristics in four worlds beside the paper\n\n"
    f"Made by `bash analysis/calibrate.sh && python analysis/calibration.py` from {len(folders)} evaluations "
    "(100 maps × 1 repeat per cell, B's world). Paper B = the paper's DRL model B (Table 3).\n\n"
    "## Measures\n\n"
    + markdown(measures)
    + "\n## Surfing's found fraction (rows world, N; columns n)\n\n"
    + markdown(surfing)
    + "\n## The best heuristic per cell\n\n"
    + markdown(best_table.fillna("–"))
)
write_text_atomic(OUT / "calibration.md", text)
print(markdown(measures))

# %% [markdown]
# ## Found fraction against λk per world size
#
# Each panel one world size; x the λk of each world at that n (log scale), y the found fraction averaged over the
# cell's team sizes; the paper's DRL models (their mean over the same team sizes) dashed.

# %%
sizes = sorted(summary.n.unique())
fig, axes = plt.subplots(1, len(sizes), figsize=(4 * len(sizes), 3.6), sharey=True)
for ax, n in zip(np.atleast_1d(axes), sizes, strict=True):
    cells = summary[summary.n == n]
    for controller, block in cells.groupby("controller"):
        line = block.groupby("lam_k")["mean"].mean()
        ax.plot(line.index, line.values, marker="o", label=controller)
    for model, style in (("A", ":"), ("B", "--"), ("C", "-."), ("diagonal", (0, (1, 3)))):
        ax.axhline(
            paper[(paper.n == n) & (paper.model == model)].found_fraction.mean(),
            color="k",
            linestyle=style,
            linewidth=0.8,
            label=f"paper {model}",
        )
    ax.set_xscale("log")
    ax.set_title(f"n = {n}")
    ax.set_xlabel("λk")
np.atleast_1d(axes)[0].set_ylabel("found fraction (mean over N)")
np.atleast_1d(axes)[-1].legend(fontsize=7, loc="lower right")
fig.tight_layout()
write_atomic(OUT / "calibration.png", lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
