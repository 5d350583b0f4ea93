# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Fig. 5 and Fig. 6: training curves of R, L, F, M̄ and the validation found fraction
#
# Reads `progress.csv` of training runs, smooths each team metric over a window of log rows, and writes
# `training_curves.png` and the tidy `training_curves.csv`. Run from the repository root:
#
#     python analysis/training_curves.py [RUN_DIR ...] [--out DIR]
#
# Run folders as arguments, else `SEARCHRL_RUN_DIRS` (comma-separated; what a notebook reads), else every run under
# `runs/train/`; output folder `--out`, else `SEARCHRL_ANALYSIS_OUT`, else `analysis/out`.

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, training_curves

ROOT = Path.cwd()
RUN_DIRS, OUT = cli.run_inputs("Fig. 5 and Fig. 6: training curves", ROOT / "analysis" / "out")
OUT.mkdir(parents=True, exist_ok=True)
curves = training_curves(RUN_DIRS)
write_atomic(OUT / "training_curves.csv", lambda tmp: curves.to_csv(tmp, index=False))
print(f"{len(RUN_DIRS)} runs, {len(curves)} points")

# %% [markdown]
# ## Team metrics per world episode (smoothed over 5 log rows) and validation on fixed worlds
#
# Runs of one setting (the same config but for the seed) are drawn as their mean with a band from the lowest to the
# highest seed (`training_bands.csv`); a setting of one seed as its line. The dotted lines are the random walk on
# each model's validation worlds.

# %%
METRICS = [
    ("team/R", "reward R"),
    ("team/L", "search time L"),
    ("team/F", "communications F"),
    ("team/M_bar", "information per step M̄"),
    ("val/found_fraction", "validation found fraction"),
]
fig, axes = plt.subplots(1, len(METRICS), figsize=(3.3 * len(METRICS), 3.0))
bands = []
for ax, (metric, title) in zip(axes, METRICS, strict=True):
    for index, (setting, group) in enumerate(curves[curves.metric == metric].groupby("setting", sort=False)):
        color, window = f"C{index % 10}", 5 if metric.startswith("team") else 1
        per_run = {}
        for run, g in group.groupby("run"):
            g = g.sort_values("step")
            per_run[run] = g.assign(smooth=g.value.rolling(window, min_periods=1).mean())
        if len(per_run) == 1:  # one seed: its line
            ((run, line),) = per_run.items()
            ax.plot(line.step, line.smooth, color=color, label=f"{line.model.iloc[0]} ({run})")
            continue
        # several seeds of one setting: their mean, and a band from the lowest to the highest seed at each step
        table = pd.concat(per_run.values()).pivot_table(index="step", columns="run", values="smooth").dropna()
        ax.plot(table.index, table.mean(axis=1), color=color, label=f"{group.model.iloc[0]} ({len(per_run)} seeds)")
        ax.fill_between(table.index, table.min(axis=1), table.max(axis=1), color=color, alpha=0.2, linewidth=0)
        bands.append(
            pd.DataFrame(
                {
                    "metric": metric,
                    "setting": setting,
                    "seeds": len(per_run),
                    "step": table.index,
                    "mean": table.mean(axis=1).to_numpy(),
                    "low": table.min(axis=1).to_numpy(),
                    "high": table.max(axis=1).to_numpy(),
                }
            )
        )
    if metric == "val/found_fraction":  # the random walk on each model's validation worlds (its action count)
        random = curves[curves.metric == "val/random_found_fraction"]
        for model, level in random.groupby("model")["value"].mean().items():
            ax.axhline(level, color="grey", linestyle=":", label=f"random walk ({model})")
    ax.set(title=title, xlabel="agent-steps")
axes[-1].legend(fontsize=6)
fig.tight_layout()
write_atomic(OUT / "training_curves.png", lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
if bands:  # the seeds' bands as numbers: one row per setting, metric and step
    table = pd.concat(bands, ignore_index=True)
    write_atomic(OUT / "training_bands.csv", lambda tmp: table.to_csv(tmp, index=False))

# %% [markdown]
# ## Convergence: validation found fraction and meetings per million agent-steps
#
# The mean of the validation points in each window of 10⁶ agent-steps (window [k, k + 1) M, labelled k + 1), per
# run, for the found fraction and for meetings F; written to `training_convergence.md`. A flat tail of the found
# fraction is the evidence that a run stopped short of the paper's 18.4M has converged.


# %%
def per_million(metric: str) -> str:
    points = curves[curves.metric == metric].assign(window=lambda f: f.step // 1_000_000 + 1)
    return markdown(points.pivot_table(index="window", columns=["model", "run"], values="value", aggfunc="mean"))


# Meetings (val/F, neighbour pairs summed over a validation episode) show what each policy learned about staying
# near the others: the communication reward (eq. 17) pays B and diagonal for what a meeting adds to their maps;
# A and C gain nothing from meeting.
report = (
    f"Validation found fraction:\n\n{per_million('val/found_fraction')}\n"
    f"Validation meetings F per episode:\n\n{per_million('val/F')}"
)
write_text_atomic(OUT / "training_convergence.md", report)
print(report)

# %% [markdown]
# ## Every validation, run by run
#
# The validation found fraction at each validation step (rows) of each run (columns); a run started from a clone
# or `init=` has a row at step 0, the starting policy's. Written to `validation.md`.

# %%
points = curves[curves.metric == "val/found_fraction"]
validation = points.pivot_table(index="step", columns="run", values="value", aggfunc="last")
write_text_atomic(OUT / "validation.md", markdown(validation))
print(markdown(validation))

# %% [markdown]
# ## Distance to the teacher, and the critic
#
# For runs with a teacher (`imitation.teacher`), the cross-entropy of the policy's action distribution toward the
# teacher's actions on the learner's own states (nats; the teacher term's loss, logged also when its weight is 0),
# the policy's own entropy (nats: minus SB3's `train/entropy_loss`) and the critic's explained variance, each the
# mean over windows of 250k agent-steps (labelled by their first step). A run whose cross-entropy climbs while its
# validation falls is being moved away from its teacher; whether toward other moves or toward no move in
# particular, its entropy says. Written to `teacher_distance.md`.


# %%
def per_window(metric: str, width: int = 250_000) -> str:
    points = curves[curves.metric == metric].assign(window=lambda f: f.step // width * width)
    return markdown(points.pivot_table(index="window", columns="run", values="value", aggfunc="mean"))


if (curves.metric == "train/imitation_loss").any():
    curves.loc[curves.metric == "train/entropy_loss", "value"] *= -1  # SB3 logs minus the entropy
    report = (
        f"Cross-entropy toward the teacher (nats):\n\n{per_window('train/imitation_loss')}\n"
        f"Entropy of the policy (nats):\n\n{per_window('train/entropy_loss')}\n"
        f"Explained variance of the critic:\n\n{per_window('train/explained_variance')}"
    )
    write_text_atomic(OUT / "teacher_distance.md", report)
    print(report)
