# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The shipped RL policies at a glance
#
# One row per model: the RL policy `runs/reference/term/<m>`, its RL agent-steps and wall time (the last
# `time/time_elapsed` of each segment of its `progress.csv`, summed: one core), and the mean found fraction
# over the 12 hard cells (`HARD_CELLS`) of the policy, the paper's model, its teacher (target-greedy), surfing and
# coverage, each in the model's world, from the full-grid tables `analysis/out/full_<m>/table3.csv`.
#
#     python analysis/shipped.py [--out DIR]        # -> shipped.md (default analysis/out/)

# %%
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_text_atomic
from searchrl.reporting import cli
from searchrl.reporting.stats import HARD_CELLS, is_hard, markdown

ROOT = Path(__file__).resolve().parents[1]
MODELS = ["a", "b", "c", "diagonal"]
parser = cli.parser("The shipped RL policies: budget, time and hard-cell found fractions", dirs=None)
args, _ = cli.parse(parser)
OUT = cli.out_dir(args.out, ROOT / "analysis" / "out")

# %%
rows = []
for model in MODELS:
    table_path = ROOT / "analysis" / "out" / f"full_{model}" / "table3.csv"
    log_path = ROOT / "runs" / "reference" / "term" / model / "progress.csv"
    for path in (table_path, log_path):
        if not path.is_file():
            cli.stop(f"{path}: missing (every model's full-grid table and RL log are needed)")
    table = pd.read_csv(table_path)
    hard = table[is_hard(table)]
    if len(hard.groupby(["n", "N"])) != sum(top.bit_length() for top in HARD_CELLS.values()):  # N = 1, 2, 4, …
        cli.stop(f"{table_path}: not every hard cell is there")
    means = hard.groupby("controller")["mean"].mean()
    clock = pd.read_csv(log_path).dropna(subset=["time/time_elapsed"])
    segment = clock["time/time_elapsed"].diff().lt(0).cumsum()  # runs resumed before the clock went on restarted it
    hours = clock.groupby(segment)["time/time_elapsed"].max().sum() / 3600
    rows.append(
        {
            "policy": f"runs/reference/term/{model}",
            "RL agent-steps": f"{clock['time/total_timesteps'].iloc[-1] / 1e6:.1f}M",
            "RL hours (1 core)": f"{hours:.1f}",
            "policy found": means[f"policy:reference/term/{model}"],
            "paper": hard["paper"].mean(),
            "teacher": means["greedy"],
            "surfing": means["surfing"],
            "coverage": means["coverage"],
        }
    )
shipped = pd.DataFrame(rows).set_index("policy")
shipped  # noqa: B018 (the notebook shows it)

# %%
write_text_atomic(OUT / "shipped.md", markdown(shipped.round(3)) + "\n")
print(f"wrote {OUT / 'shipped.md'}")
