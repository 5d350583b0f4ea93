# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Fig. 7 and Fig. 8: found fraction against team size
#
# Fig. 7: found fraction against N at n = 160, one line per controller or policy (95 % bootstrap CI bands), the
# paper's four DRL models dashed, each in the colour of our policy of the same model. Fig. 8: every world size, DRL
# policies against information surfing and coverage. Where the evaluations carry the per-map search bound
# (searchrl/evaluate/cell_bounds.py), both show it dotted, and Fig. 8 gains a row of efficiency = found / bound.
# Run from the repository root:
# `python analysis/figures.py [EVAL_DIR ...] [--out DIR]`; inputs and output as in `table3.py`.

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from searchrl.atomic import write_atomic
from searchrl.evaluate.results import load
from searchrl.reporting import cli
from searchrl.reporting.stats import paper_table3, summarize

ROOT = Path.cwd()
EVAL_DIRS, OUT = cli.eval_inputs("Fig. 7 and Fig. 8: found fraction against team size", ROOT / "analysis" / "out")
OUT.mkdir(parents=True, exist_ok=True)
summary = summarize(load(*EVAL_DIRS))
paper = paper_table3(ROOT / "analysis" / "paper_table3.csv")
summary["label"] = summary["controller"] + " (" + summary["model"] + ")"

# %% [markdown]
# ## Fig. 7: n = 160

# %%
# One colour per controller; the paper's line for a model takes the colour of our policy of the same model.
colours = {label: f"C{i}" for i, label in enumerate(sorted(summary.label.unique()))}
policies = summary[summary.controller.str.startswith("policy:")]
policy_colour = {model.lower(): colours[label] for label, model in zip(policies.label, policies.model, strict=True)}
fig, ax = plt.subplots(figsize=(6, 4))
for label, group in summary[summary.n == 160].groupby("label"):
    group = group.sort_values("N")
    ax.plot(group.N, group["mean"], marker="o", label=label, color=colours[label])
    ax.fill_between(group.N, group["low"], group["high"], alpha=0.2, color=colours[label])
for model, group in paper[paper.n == 160].groupby("model"):
    ax.plot(
        group.N,
        group.found_fraction,
        linestyle="--",
        linewidth=1,
        label=f"paper {model}",
        color=policy_colour.get(model.lower(), "grey"),
    )
if "bound" in summary and summary["bound"].notna().any():  # the per-map search bound: no team can expect more
    ceiling = summary[summary.n == 160].groupby("N")["bound"].mean()
    ax.plot(ceiling.index, ceiling.values, color="black", linestyle=":", linewidth=1.5, label="search bound")
ax.set(xscale="log", xlabel="agents N", ylabel="found fraction", title="n = 160", ylim=(0, 1.02))
ax.set_xticks(sorted(summary[summary.n == 160].N.unique()), labels=sorted(summary[summary.n == 160].N.unique()))
ax.legend(fontsize=7)
fig.tight_layout()
write_atomic(OUT / "fig7_n160.png", lambda tmp: fig.savefig(tmp, dpi=120, format="png"))

# %% [markdown]
# ## Fig. 8: every world size

# %%
# With the search bound recorded, a second row: efficiency = found / bound, with the found fraction's CI.
sizes = sorted(summary.n.unique())
bounded = "efficiency" in summary and summary["efficiency"].notna().any()
rows = [("mean", "low", "high", "found fraction")]
rows += [("efficiency", "efficiency_low", "efficiency_high", "found / search bound")] if bounded else []
fig, axes = plt.subplots(
    len(rows), len(sizes), figsize=(3.2 * len(sizes), 3.2 * len(rows)), sharey="row", squeeze=False
)
for row, (value, low, high, name) in zip(axes, rows, strict=True):
    for ax, n in zip(row, sizes, strict=True):
        for label, group in summary[summary.n == n].groupby("label"):
            group = group.sort_values("N")
            ax.errorbar(
                group.N,
                group[value],
                yerr=[group[value] - group[low], group[high] - group[value]],
                marker="o",
                markersize=3,
                capsize=2,
                label=label,
                color=colours[label],
            )
        if bounded and value == "mean":
            ceiling = summary[summary.n == n].groupby("N")["bound"].mean()
            ax.plot(ceiling.index, ceiling.values, color="black", linestyle=":", label="search bound")
        ax.set(xscale="log", xlabel="agents N", title=f"n = {n}", ylim=(0, 1.02))
        ticks = sorted(summary[summary.n == n].N.unique())
        ax.set_xticks(ticks, labels=ticks)
    row[0].set_ylabel(name)
axes[0][-1].legend(fontsize=7)
fig.tight_layout()
write_atomic(OUT / "fig8_all_sizes.png", lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
print(f"wrote {OUT / 'fig7_n160.png'} and {OUT / 'fig8_all_sizes.png'}")
