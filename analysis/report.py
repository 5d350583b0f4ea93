# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Aggregate report: IQM, performance profiles and probability of improvement over cells and scenarios
#
# The statistics rliable made the field's standard (searchrl/reporting/aggregate.py), over evaluation folders of one
# grid and seed: every (scenario, n, N) cell is a task and every map a run. Per controller the interquartile mean of
# its found fractions with a 95 % stratified-bootstrap interval, and its performance profile (the share of maps
# above each threshold); for each policy against each rule, the probability of improvement P(policy > rule). The
# suite's own paired verdicts per cell (analysis/compare.py, beyond.py) say where; this says how much overall.
# A folder whose controller is a trained policy (`policy:...`) is a policy, any other a rule (`--rules` names
# them instead). Run from the repository root, e.g.
#
#     python analysis/report.py runs/eval/open_b20/teacher_b runs/eval/open_b20/term_b \
#         runs/eval/open_b20/beyond_3m --out analysis/out/report
#
# `python analysis/report.py EVAL_DIR EVAL_DIR [...] [--rules NAME,...] [--out DIR]`: each controller is named by
# its folder.

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.comparable import comparison_note
from searchrl.evaluate.results import coverage_line, load
from searchrl.reporting import cli
from searchrl.reporting.aggregate import (
    bootstrap,
    common_tasks,
    iqm,
    performance_profile,
    probability_of_improvement,
    task_scores,
)
from searchrl.reporting.stats import markdown

ROOT = Path.cwd()
parser = cli.parser(
    "IQM, performance profiles and probability of improvement over cells and scenarios",
    "EVAL_DIR",
    "evaluation folders of one grid and seed (two or more)",
)
parser.add_argument(
    "--rules",
    help="comma-separated folder names that are rules (default: every folder whose controller is not a trained policy)",
)
EVAL_DIRS, OUT, args = cli.eval_args(parser, ROOT / "analysis" / "out" / "report", default_dirs=list, min_dirs=2)
names = [d.name for d in EVAL_DIRS]
if len(set(names)) != len(names):
    cli.stop(f"two folders share a name ({', '.join(names)}): each controller is named by its folder")
given_rules = [r for r in (args.rules or "").split(",") if r]
unknown = [r for r in given_rules if r not in names]
if unknown:
    cli.stop(f"--rules={args.rules!r} is not allowed: names of the folders given ({', '.join(names)})")
OUT.mkdir(parents=True, exist_ok=True)


def is_policy(folder: Path) -> bool:
    if given_rules:
        return folder.name not in given_rules
    return str(OmegaConf.load(folder / "evaluation.yaml").get("controller", "")).startswith("policy:")


# %%
scores = {}
for folder in EVAL_DIRS:
    (only,) = task_scores(load(folder).assign(controller=folder.name)).values()
    scores[folder.name] = only
try:
    aligned = dict(zip(scores, common_tasks(*scores.values()), strict=True))
except ValueError as err:
    cli.stop(str(err))
kinds = {d.name: "policy" if is_policy(d) else "rule" for d in EVAL_DIRS}
tasks = next(iter(aligned.values()))
maps = sum(s.size for s in tasks.values())
rows = []
for name, controller in aligned.items():
    point, low, high = bootstrap(iqm, controller)
    mean = float(np.concatenate(list(controller.values())).mean())
    rows.append(
        {
            "controller": name,
            "kind": kinds[name],
            "iqm": float(point),
            "low": float(low),
            "high": float(high),
            "mean": mean,
        }
    )
table = pd.DataFrame(rows).sort_values("iqm", ascending=False).reset_index(drop=True)
write_atomic(OUT / "report.csv", lambda tmp: table.to_csv(tmp, index=False))

pairs = []
for policy in [n for n in aligned if kinds[n] == "policy"]:
    for rule in [n for n in aligned if kinds[n] == "rule"]:
        point, low, high = bootstrap(probability_of_improvement, aligned[policy], aligned[rule])
        pairs.append(
            {"policy": policy, "rule": rule, "p_improvement": float(point), "low": float(low), "high": float(high)}
        )
improvement = pd.DataFrame(pairs, columns=["policy", "rule", "p_improvement", "low", "high"])
write_atomic(OUT / "improvement.csv", lambda tmp: improvement.to_csv(tmp, index=False))

heads = "\n".join(f"- {coverage_line(d)}" for d in EVAL_DIRS)
pair_table = markdown(improvement.set_index(["policy", "rule"])) if len(improvement) else "no policy and rule pair\n"
report = (
    f"Over {len(tasks)} cells and {maps} maps common to every folder:\n{heads}\n\n"
    f"{comparison_note(EVAL_DIRS)}\n\n"
    f"Interquartile mean of the found fraction (95 % stratified-bootstrap interval over maps):\n\n"
    f"{markdown(table.set_index('controller'))}\n"
    f"Probability of improvement P(policy > rule), per cell over every pair of maps, averaged over cells:\n\n"
    f"{pair_table}"
)
write_text_atomic(OUT / "report.md", report)
print(report)

# %% [markdown]
# ## The figure: IQM with its interval, and the performance profiles with their bands

# %%
thresholds = np.linspace(0.0, 1.0, 51)
fig, (left, right) = plt.subplots(1, 2, figsize=(10.0, 3.6))
for index, row in table.iloc[::-1].reset_index(drop=True).iterrows():
    left.plot([row["low"], row["high"]], [index, index], color="C0" if row["kind"] == "policy" else "C1", lw=6)
    left.plot([row["iqm"]], [index], "k|", markersize=12)
left.set(yticks=range(len(table)), yticklabels=table["controller"][::-1], xlabel="IQM of the found fraction")
for index, (name, controller) in enumerate(aligned.items()):
    point, low, high = bootstrap(lambda c: performance_profile(c, thresholds), controller, n_boot=500)
    right.plot(thresholds, point, color=f"C{index % 10}", label=name)
    right.fill_between(thresholds, low, high, color=f"C{index % 10}", alpha=0.2, linewidth=0)
right.set(xlabel="found fraction τ", ylabel="share of maps above τ", title="performance profiles")
right.legend(fontsize=7)
fig.tight_layout()
write_atomic(OUT / "report.png", lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
print(f"wrote {OUT / 'report.md'}, {OUT / 'report.csv'}, {OUT / 'improvement.csv'}, {OUT / 'report.png'}")
