# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Past the teacher: policies against their teacher over a cell set, and the budget curve
#
# The first folder is the teacher (or any rule); every other folder a policy evaluated on the same grid and seed
# (the same maps; a policy folder that did not play exactly the teacher's maps is refused in one line). For each
# policy: the mean over the cells of its per-cell difference from the teacher (repeats averaged per map), with a
# 95 % CI from a bootstrap that resamples maps within each cell (stratified by cell); the count of each per-cell
# verdict of `paired_margins` (better / tie / worse, and saturated / too few maps where any); and, where its folder
# is an evaluation of a checkpoint, the training run and the agent-steps of RL it had (`<run>@step_<n>` in its
# label). A run's checkpoints in step order are its budget curve: `beyond.png` draws each run's, and for a run of
# three checkpoints or more `beyond.md` ends with its least-squares line (slope per million agent-steps, standard
# error, t-based 95 % CI, where it crosses 0 and +0.02).
# Run from the repository root, e.g.
#
#     python analysis/beyond.py runs/eval/open_b20/teacher_b runs/eval/open_b20/term_b \
#         runs/eval/open_b20/beyond_2p5m --out analysis/out/beyond
#
# `python analysis/beyond.py TEACHER_DIR POLICY_DIR [POLICY_DIR ...] [--out DIR]`.

# %%
import re
from pathlib import Path

import numpy as np
import pandas as pd
from omegaconf import OmegaConf
from scipy import stats

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import coverage_line, load
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, paired_margins

ROOT = Path.cwd()
parser = cli.parser(
    "Policies against their teacher over a cell set, and the budget curve",
    "EVAL_DIR",
    "the teacher's evaluation folder, then the policies' (same grid and seed)",
)
EVAL_DIRS, OUT, args = cli.eval_args(parser, ROOT / "analysis" / "out" / "beyond", default_dirs=list, min_dirs=2)
teacher = EVAL_DIRS[0].name
names = [d.name for d in EVAL_DIRS]
if len(set(names)) < len(names):  # rows are labelled by folder name: two folders of one name would merge
    twice = sorted({n for n in names if names.count(n) > 1})
    cli.stop(f"two evaluation folders are named {twice[0]!r}: give folders of distinct names")


def checkpoint_of(folder: Path) -> tuple[str, float]:
    """(the training run, its agent-steps) of the evaluated checkpoint, from its label (`<run>@step_<n>`); ("", NaN)
    for a rule or a model.zip."""
    label = str(OmegaConf.load(folder / "evaluation.yaml").get("controller", ""))
    found = re.search(r"^(.*)@step_(\d+)$", label)
    return (found.group(1), float(found.group(2))) if found else ("", float("nan"))


def stratified_mean_ci(diffs: dict, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """(mean over cells of each cell's mean per-map difference, 95 % percentile CI): maps resampled within cells."""
    rng = np.random.default_rng(seed)
    cells = [np.asarray(d, float) for d in diffs.values()]
    boots = np.mean([d[rng.integers(0, d.size, (n_boot, d.size))].mean(axis=1) for d in cells], axis=0)
    return float(np.mean([d.mean() for d in cells])), float(np.quantile(boots, 0.025)), float(np.quantile(boots, 0.975))


# %%
episodes = pd.concat([load(d).assign(controller=d.name) for d in EVAL_DIRS], ignore_index=True)
per_map = episodes.groupby(["controller", "n", "N", "map_seed"])["found_fraction"].mean()
VERDICTS = ("better", "tie", "worse", "saturated", "too few maps")  # every verdict of `paired_margins`
rows, runs = [], {}  # runs: each policy's training run, whose checkpoints make one budget curve
for folder in EVAL_DIRS[1:]:
    mine = folder.name
    missing = per_map[teacher].index.symmetric_difference(per_map[mine].index)
    if len(missing):
        cli.stop(
            f"{folder} and {EVAL_DIRS[0]} did not play the same maps ({len(missing)} (n, N, map) differ): "
            "evaluate both on the same grid, seed and maps_per_cell"
        )
    joined = pd.concat([per_map[mine].rename("mine"), per_map[teacher].rename("base")], axis=1)
    diffs = {cell: (g["mine"] - g["base"]).to_numpy() for cell, g in joined.groupby(level=["n", "N"])}
    mean, low, high = stratified_mean_ci(diffs)
    verdicts = paired_margins(episodes.assign(model="b"), mine, teacher)["verdict"].value_counts()
    runs[mine], steps = checkpoint_of(folder)
    rows.append(
        {
            "policy": mine,
            "agent_steps": steps,
            "cells": len(diffs),
            "minus_teacher": mean,
            "ci_low": low,
            "ci_high": high,
            **{v: int(verdicts.get(v, 0)) for v in VERDICTS},
        }
    )
table = pd.DataFrame(rows).sort_values("agent_steps", na_position="first").reset_index(drop=True)
table = table.drop(columns=[v for v in VERDICTS[3:] if not table[v].any()])  # a verdict no row has: no column
write_atomic(OUT / "beyond.csv", lambda tmp: table.to_csv(tmp, index=False))
text = (
    f"Each policy minus {teacher} over {coverage_line(EVAL_DIRS[0])}: the mean over cells of the per-cell "
    "paired difference in found fraction, 95 % CI over maps stratified by cell, and the per-cell verdicts.\n\n"
    + markdown(
        table.assign(agent_steps=[f"{s / 1e6:.2f}M" if pd.notna(s) else "–" for s in table.agent_steps]).set_index(
            "policy"
        )
    )
)
curves = dict(list(table.dropna(subset=["agent_steps"]).groupby(table.policy.map(runs), sort=False)))
for run, curve in curves.items():  # a run's checkpoints: its budget curve's least-squares line, from 3 points
    if len(curve) < 3:
        continue
    x, y = curve["agent_steps"].to_numpy() / 1e6, curve["minus_teacher"].to_numpy()
    line = stats.linregress(x, y)
    half = stats.t.ppf(0.975, len(x) - 2) * line.stderr
    at = [(level - line.intercept) / line.slope for level in (0.0, 0.02)] if line.slope > 0 else []
    where = f"; the line crosses 0 at {at[0]:.1f}M and +0.02 at {at[1]:.1f}M" if at else ""
    text = text.rstrip("\n") + (
        f"\n\nThe budget curve of {run} ({len(x)} checkpoints), least squares: {line.slope:+.5f} per million "
        f"agent-steps (standard error {line.stderr:.5f}, 95 % CI [{line.slope - half:+.5f}, {line.slope + half:+.5f}], "
        f"t with {len(x) - 2} degrees of freedom){where}."
    )
OUT.mkdir(parents=True, exist_ok=True)
write_text_atomic(OUT / "beyond.md", text + "\n")
print(text)

# %%
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(5, 3.2))
ax.axhline(0, color="grey", lw=1, label=teacher)
for run, curve in curves.items():  # one line per training run
    ax.errorbar(
        curve["agent_steps"] / 1e6,
        curve["minus_teacher"],
        yerr=[curve["minus_teacher"] - curve["ci_low"], curve["ci_high"] - curve["minus_teacher"]],
        marker="o",
        capsize=3,
        label=f"{run} − teacher",
    )
ax.set_xlabel("agent-steps of RL (millions)")
ax.set_ylabel("found fraction − teacher's")
ax.legend(frameon=False)
fig.tight_layout()
write_atomic(OUT / "beyond.png", lambda tmp: fig.savefig(tmp, format="png", dpi=120))
