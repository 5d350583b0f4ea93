# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Past the teacher: policies against their teacher over a cell set, and the budget curve
#
# The first folder is the teacher (or any rule); every other folder a policy evaluated on the same grid and seed
# (the same maps). For each policy: the mean over the cells of its per-cell difference from the teacher (repeats
# averaged per map), with a 95 % CI from a bootstrap that resamples maps within each cell (stratified by cell); the
# per-cell verdicts of `paired_margins` (better / tie / worse); and, where its folder is an evaluation of a
# checkpoint, the agent-steps of RL it had (`@step_<n>` in its label). The rows in step order are the budget curve;
# `beyond.png` draws it. Run from the repository root, e.g.
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

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import coverage_line, load
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, paired_margins

ROOT = Path.cwd()
parser = cli.parser("Policies against their teacher over a cell set, and the budget curve", "EVAL_DIR",
                    "the teacher's evaluation folder, then the policies' (same grid and seed)")  # fmt: skip
EVAL_DIRS, OUT, args = cli.eval_args(parser, ROOT / "analysis" / "out" / "beyond", default_dirs=list, min_dirs=2)
OUT.mkdir(parents=True, exist_ok=True)
teacher = EVAL_DIRS[0].name


def step_of(folder: Path) -> float:
    """Agent-steps of the evaluated checkpoint, from its label (`<run>@step_<n>`; NaN for a rule or a model.zip)."""
    label = str(OmegaConf.load(folder / "evaluation.yaml").get("controller", ""))
    found = re.search(r"@step_(\d+)$", label)
    return float(found.group(1)) if found else float("nan")


def stratified_mean_ci(diffs: dict, n_boot: int = 2000, seed: int = 0) -> tuple[float, float, float]:
    """(mean over cells of each cell's mean per-map difference, 95 % percentile CI): maps resampled within cells."""
    rng = np.random.default_rng(seed)
    cells = [np.asarray(d, float) for d in diffs.values()]
    boots = np.mean([d[rng.integers(0, d.size, (n_boot, d.size))].mean(axis=1) for d in cells], axis=0)
    return float(np.mean([d.mean() for d in cells])), float(np.quantile(boots, 0.025)), float(np.quantile(boots, 0.975))


# %%
episodes = pd.concat([load(d).assign(controller=d.name) for d in EVAL_DIRS], ignore_index=True)
per_map = episodes.groupby(["controller", "n", "N", "map_seed"])["found_fraction"].mean()
rows = []
for folder in EVAL_DIRS[1:]:
    mine = folder.name
    joined = pd.concat([per_map[mine].rename("mine"), per_map[teacher].rename("base")], axis=1, join="inner")
    diffs = {cell: (g["mine"] - g["base"]).to_numpy() for cell, g in joined.groupby(level=["n", "N"])}
    mean, low, high = stratified_mean_ci(diffs)
    verdicts = paired_margins(episodes.assign(model="b"), mine, teacher)["verdict"].value_counts()
    rows.append({"policy": mine, "agent_steps": step_of(folder), "cells": len(diffs),
                 "minus_teacher": mean, "ci_low": low, "ci_high": high,
                 **{v: int(verdicts.get(v, 0)) for v in ("better", "tie", "worse")}})  # fmt: skip
table = pd.DataFrame(rows).sort_values("agent_steps", na_position="first").reset_index(drop=True)
write_atomic(OUT / "beyond.csv", lambda tmp: table.to_csv(tmp, index=False))
text = (f"Each policy minus {teacher} over {coverage_line(EVAL_DIRS[0])}: the mean over cells of the per-cell "
        "paired difference in found fraction, 95 % CI over maps stratified by cell, and the per-cell verdicts.\n\n"
        + markdown(table.assign(agent_steps=[f"{s / 1e6:.2f}M" if pd.notna(s) else "–" for s in table.agent_steps])
                   .set_index("policy")))  # fmt: skip
write_text_atomic(OUT / "beyond.md", text + "\n")
print(text)

# %%
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

curve = table.dropna(subset=["agent_steps"])
fig, ax = plt.subplots(figsize=(5, 3.2))
ax.axhline(0, color="grey", lw=1, label=teacher)
ax.errorbar(curve["agent_steps"] / 1e6, curve["minus_teacher"],
            yerr=[curve["minus_teacher"] - curve["ci_low"], curve["ci_high"] - curve["minus_teacher"]],
            marker="o", capsize=3, label="policy − teacher")  # fmt: skip
ax.set_xlabel("agent-steps of RL (millions)")
ax.set_ylabel("found fraction − teacher's")
ax.legend(frameon=False)
fig.tight_layout()
write_atomic(OUT / "beyond.png", lambda tmp: fig.savefig(tmp, format="png", dpi=120))
