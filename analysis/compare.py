# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Two evaluations, cell by cell
#
# Compares the first evaluation directory of `SEARCHRL_EVAL_DIRS` with each of the others, on the maps both ran:
# the paired difference in found fraction per cell with a 95 % bootstrap CI over maps, and its verdict (see
# `paired_margins`). Each directory is labelled by its folder name, so two runs of the same controller (surfing
# with other scales, a policy and its ablation) can be told apart.
#
# Writes `compare.csv` (tidy) and `compare.md` (verdict counts, then rows N, columns n per pair). Run from the
# repository root, e.g. `SEARCHRL_EVAL_DIRS=runs/eval/surfing,runs/eval/surfing_multiscale
# SEARCHRL_ANALYSIS_OUT=analysis/out/surfing_scales python analysis/compare.py`.

# %%
import os
from pathlib import Path

import pandas as pd

from searchrl.analysis.stats import markdown, paired_margins
from searchrl.evaluate.results import load

ROOT = Path.cwd()
EVAL_DIRS = [Path(d) for d in os.environ.get("SEARCHRL_EVAL_DIRS", "").split(",") if d]
if len(EVAL_DIRS) < 2:
    raise SystemExit("SEARCHRL_EVAL_DIRS must name two or more evaluation directories; the first meets each other")
if len({d.name for d in EVAL_DIRS}) < len(EVAL_DIRS):
    raise SystemExit(f"SEARCHRL_EVAL_DIRS={[str(d) for d in EVAL_DIRS]}: folder names label sides; make them differ")
OUT = Path(os.environ.get("SEARCHRL_ANALYSIS_OUT", ROOT / "analysis" / "out"))
OUT.mkdir(parents=True, exist_ok=True)
episodes = pd.concat([load(d).assign(controller=d.name) for d in EVAL_DIRS], ignore_index=True)

# %% [markdown]
# ## Paired margins, the first directory minus each other one

# %%
mine = EVAL_DIRS[0].name
margins = pd.concat([paired_margins(episodes, mine, other.name) for other in EVAL_DIRS[1:]], ignore_index=True)
margins.to_csv(OUT / "compare.csv", index=False)
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
(OUT / "compare.md").write_text("\n".join(lines))
print("\n".join(lines))
