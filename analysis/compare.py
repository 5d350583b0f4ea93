# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Two evaluations, cell by cell
#
# Compares the first evaluation directory with each of the others, on the maps both ran:
# the paired difference in found fraction per cell with a 95 % bootstrap CI over maps, and its verdict (see
# `paired_margins`). Each directory is labelled by its folder name, so two runs of the same controller (surfing
# with other scales, a policy and its ablation) can be told apart.
#
# Writes `compare.csv` (tidy) and `compare.md` (verdict counts, then rows N, columns n per pair). Run from the
# repository root, e.g.
#
#     python analysis/compare.py runs/eval/surfing runs/eval/surfing_multiscale --out analysis/out/surfing_scales
#
# `python analysis/compare.py EVAL_DIR EVAL_DIR [EVAL_DIR ...] [--out DIR]`: without folders as arguments, those of
# `SEARCHRL_EVAL_DIRS` (comma-separated; what a notebook reads); output folder `--out`, else `SEARCHRL_ANALYSIS_OUT`,
# else `analysis/out`.

# %%
from pathlib import Path

import pandas as pd

from searchrl.analysis import cli
from searchrl.analysis.stats import markdown, paired_margins
from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import load

ROOT = Path.cwd()
EVAL_DIRS, OUT = cli.eval_inputs(
    "Two or more evaluations, cell by cell: the first against each other one",
    ROOT / "analysis" / "out",
    default_dirs=list,
    min_dirs=2,
)  # no default
if len({d.name for d in EVAL_DIRS}) < len(EVAL_DIRS):
    cli.stop(f"evaluation folders {[str(d) for d in EVAL_DIRS]}: their names label the sides; make them differ")
OUT.mkdir(parents=True, exist_ok=True)
episodes = pd.concat([load(d).assign(controller=d.name) for d in EVAL_DIRS], ignore_index=True)

# %% [markdown]
# ## Paired margins, the first directory minus each other one

# %%
mine = EVAL_DIRS[0].name
margins = pd.concat([paired_margins(episodes, mine, other.name) for other in EVAL_DIRS[1:]], ignore_index=True)
write_atomic(OUT / "compare.csv", lambda tmp: margins.to_csv(tmp, index=False))
lines = [f"# {mine} against {', '.join(d.name for d in EVAL_DIRS[1:])}\n"]
for other, block in margins.groupby("baseline", sort=False):
    counts = block.verdict.value_counts()
    lines.append(f"## {mine} − {other}\n")
    tally = ", ".join(f"{v} {counts.get(v, 0)}" for v in ("better", "tie", "saturated", "worse", "too few maps"))
    lines.append(f"{tally} of {len(block)} cells\n")
    entries = block.assign(entry=[f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}" for d, lo, hi, v in
                                  zip(block["diff"], block.low, block.high, block.verdict, strict=True)])  # fmt: skip
    lines.append(markdown(entries.pivot_table(index="N", columns="n", values="entry", aggfunc="first").fillna("–")))
    lines.append("")
write_text_atomic(OUT / "compare.md", "\n".join(lines))
print("\n".join(lines))
