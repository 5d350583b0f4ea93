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
# `python analysis/compare.py EVAL_DIR EVAL_DIR [EVAL_DIR ...] [--out DIR] [--unsaturated-by NAME]`: without
# folders as arguments, those of `SEARCHRL_EVAL_DIRS` (comma-separated; what a notebook reads); output folder
# `--out`, else `SEARCHRL_ANALYSIS_OUT`, else `analysis/out`. With `--unsaturated-by NAME` (one of the folders'
# names, a policy's teacher say) each tally is also split at the cells where NAME finds less than 0.95 of the
# targets: margins mean something there, and near 1 a tie is all there is to report. With `--metric NAME` another
# per-episode column is compared instead of the found fraction (F: neighbour pair-steps, how much of the episode
# agents spend within reach of each other); "better" then means higher, and no cell is called saturated.

# %%
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.comparable import comparison_note
from searchrl.evaluate.results import load
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, paired_margins

ROOT = Path.cwd()
UNSATURATED = 0.95  # below this found fraction of the reference a cell is "unsaturated" (issue 28's line)
parser = cli.parser(
    "Two or more evaluations, cell by cell: the first against each other one",
    "EVAL_DIR",
    "evaluation folders, two or more (default: $SEARCHRL_EVAL_DIRS, comma-separated)",
)
parser.add_argument(
    "--unsaturated-by",
    metavar="NAME",
    help=f"split each tally at the cells where the folder named NAME finds < {UNSATURATED} of the targets",
)
METRICS = ("found_fraction", "R", "F", "M_bar")  # per-episode columns of an evaluation (docs/evaluation.md)
parser.add_argument(
    "--metric",
    default="found_fraction",
    choices=METRICS,
    help="the per-episode column compared (default found_fraction; with another, 'better' means higher)",
)
EVAL_DIRS, OUT, args = cli.eval_args(parser, ROOT / "analysis" / "out", default_dirs=list, min_dirs=2)  # no default
names = [d.name for d in EVAL_DIRS]
if len(set(names)) < len(names):
    cli.stop(f"evaluation folders {[str(d) for d in EVAL_DIRS]}: their names label the sides; make them differ")
if args.unsaturated_by is not None and args.unsaturated_by not in names:
    cli.stop(f"--unsaturated-by {args.unsaturated_by!r} is not allowed: one of the folders' names {names}")
OUT.mkdir(parents=True, exist_ok=True)
episodes = pd.concat([load(d).assign(controller=d.name) for d in EVAL_DIRS], ignore_index=True)

# %% [markdown]
# ## Paired margins, the first directory minus each other one

# %%
mine = EVAL_DIRS[0].name
saturated = 0.995 if args.metric == "found_fraction" else float("inf")  # only a found fraction saturates
margins = pd.concat(
    [paired_margins(episodes, mine, other.name, args.metric, saturated=saturated) for other in EVAL_DIRS[1:]],
    ignore_index=True,
)
if args.unsaturated_by is not None:  # the reference's mean over all the maps it ran in each cell
    reference = episodes[episodes.controller == args.unsaturated_by].groupby(["n", "N"]).found_fraction.mean()
    below = reference.rename("reference").reset_index().assign(unsaturated=lambda r: r.reference < UNSATURATED)
    margins = margins.merge(below[["n", "N", "unsaturated"]], on=["n", "N"], how="left")
write_atomic(OUT / "compare.csv", lambda tmp: margins.to_csv(tmp, index=False))


def tally(block: pd.DataFrame) -> str:
    counts = block.verdict.value_counts()
    return ", ".join(f"{v} {counts.get(v, 0)}" for v in ("better", "tie", "saturated", "worse", "too few maps"))


metric = "" if args.metric == "found_fraction" else f", {args.metric} (better: higher)"
lines = [f"# {mine} against {', '.join(d.name for d in EVAL_DIRS[1:])}{metric}\n", f"{comparison_note(EVAL_DIRS)}\n"]
for other, block in margins.groupby("baseline", sort=False):
    lines.append(f"## {mine} − {other}\n")
    lines.append(f"{tally(block)} of {len(block)} cells\n")
    if args.unsaturated_by is not None:
        for where, part in (
            (f"< {UNSATURATED}", block[block.unsaturated == True]),  # noqa: E712 (NaN: not run)
            (f">= {UNSATURATED}", block[block.unsaturated == False]),  # noqa: E712
        ):
            lines.append(f"- where {args.unsaturated_by} finds {where}: {tally(part)} of {len(part)} cells")
        lines.append("")
    entries = block.assign(
        entry=[
            f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}"
            for d, lo, hi, v in zip(block["diff"], block.low, block.high, block.verdict, strict=True)
        ]
    )
    lines.append(markdown(entries.pivot_table(index="N", columns="n", values="entry", aggfunc="first").fillna("–")))
    lines.append("")
write_text_atomic(OUT / "compare.md", "\n".join(lines))
print("\n".join(lines))
