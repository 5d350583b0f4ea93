# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Table 3: fraction of targets found in 256 steps, per cell
#
# Loads evaluation results (`python -m searchrl.evaluate ...`, one directory per controller or policy), averages
# the repeats of each map, and bootstraps a 95 % confidence interval over maps. Writes `table3.csv` (tidy, with
# CIs and the paper's number for the same model where there is one; with the search bound where the evaluations
# carry it) and `table3.md` (the paper's layout: rows N, columns n), and `table3_efficiency.md` with the bound.
# Run as a script from the repository root:
#
#     python analysis/table3.py [EVAL_DIR ...] [--out DIR]
#
# Evaluation folders as arguments, else `SEARCHRL_EVAL_DIRS` (comma-separated; what a notebook reads), else every
# folder under `runs/eval/` with results; output folder `--out`, else `SEARCHRL_ANALYSIS_OUT`, else `analysis/out`.

# %%
from pathlib import Path

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import coverage_line, load
from searchrl.reporting import cli
from searchrl.reporting.stats import beside_paper, efficiency_summary, markdown, paper_table3, summarize, table3

ROOT = Path.cwd()
EVAL_DIRS, OUT = cli.eval_inputs(
    "Table 3: fraction of targets found per cell, beside the paper", ROOT / "analysis" / "out"
)
OUT.mkdir(parents=True, exist_ok=True)
episodes = load(*EVAL_DIRS)
print(f"{len(episodes)} episodes from {[d.name for d in EVAL_DIRS]}")
# What each folder covers (scenario, seed, maps, cells held and missing): at the head of every table written here.
COVERS = "Covers:\n" + "".join(f"- {coverage_line(d)}\n" for d in EVAL_DIRS) + "\n"
print(COVERS)

# %% [markdown]
# ## Per-cell means with 95 % bootstrap CIs, beside the paper
#
# Heuristics are evaluated with one model's world settings (`model` column); the paper's number shown beside a
# heuristic is that of the DRL model with the same settings, for reference. Only results of the paper's scenario
# (the open grid, the prior right) stand beside the paper's numbers; other scenarios' `paper` is empty.

# %%
summary = summarize(episodes)
compared = beside_paper(summary, paper_table3(ROOT / "analysis" / "paper_table3.csv"))
write_atomic(OUT / "table3.csv", lambda tmp: compared.to_csv(tmp, index=False))
compared.head(12)

# %% [markdown]
# ## Table 3 layout: rows N, columns n

# %%
wide = table3(summary)
write_text_atomic(OUT / "table3.md", COVERS + markdown(wide))
print(markdown(wide))

# %% [markdown]
# ## Each trained policy beside the paper: "ours (paper)" per cell
#
# Rows N, columns n, one block per model; written to `table3_vs_paper.md`.

# %%
policies = compared[compared.controller.str.startswith("policy:") & compared.paper.notna()]
if len(policies):
    entries = policies.assign(
        entry=[f"{o:.3f} ({p:.2f})" for o, p in zip(policies["mean"], policies.paper, strict=True)]
    )
    side_by_side = entries.pivot_table(index=["model", "N"], columns="n", values="entry", aggfunc="first")
    write_text_atomic(OUT / "table3_vs_paper.md", COVERS + markdown(side_by_side.fillna("–")))
    print(markdown(side_by_side.fillna("–")))

# %% [markdown]
# ## Efficiency against the search bound
#
# Where the evaluations carry the per-map search bound (`bound_fraction`; searchrl/evaluate/cell_bounds.py): per cell,
# found / bound (rows N, columns n), and per controller its means over the hard cells and the unsaturated ones.
# Written to `table3_efficiency.md`.

# %%
if "efficiency" in summary and summary["efficiency"].notna().any():
    per_cell, overall = markdown(table3(summary, "efficiency")), markdown(efficiency_summary(summary))
    efficiency = f"Efficiency, found / search bound:\n\n{per_cell}\nOver the hard and unsaturated cells:\n\n{overall}"
    write_text_atomic(OUT / "table3_efficiency.md", COVERS + efficiency)
    print(efficiency)
