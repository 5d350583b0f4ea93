# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A guided policy's probe, one row per scenario
#
# Reads the probe of `analysis/guided_probe.sh` (runs/eval/guided_probe/<scenario>/<controller>/) and writes, per
# scenario, each controller's mean found fraction over the probe's 100 maps (n = 40, 80 x N = 4, 16, 25 maps each)
# and the guided policy's paired difference to each, with a 95 % bootstrap CI over maps (the same maps, cells and
# seeds for every controller): `summary.md`; and against the best rule probed in each scenario: `best_rule.md`.
#
#     python analysis/guided_summary.py b [--probe runs/eval/guided_probe] [--out analysis/out/guided_probe/b]

# %%
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from searchrl.analysis.stats import bootstrap_mean_ci, markdown
from searchrl.evaluate.results import load

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("tag", help="the guided policy's folder name in each scenario of the probe")
parser.add_argument("--probe", default="runs/eval/guided_probe")
parser.add_argument("--out", default=None)
args = parser.parse_args()
out = Path(args.out or f"analysis/out/guided_probe/{args.tag}")
KEY = ["n", "N", "map_seed", "repeat"]
RULES = ("path_greedy", "greedy_target", "coverage", "switch")

# %% [markdown]
# Each controller against the guided policy on the maps both ran (all of them: the probe runs the same cells, maps
# and seeds for each), and the best of the rules probed in the scenario.

# %%
rows = []
for scenario in sorted(p for p in Path(args.probe).iterdir() if (p / args.tag).is_dir()):
    frames = {c.name: load(c).set_index(KEY)["found_fraction"] for c in sorted(scenario.iterdir()) if c.is_dir()}
    mine = frames.pop(args.tag)
    row = {"scenario": scenario.name, args.tag: f"{mine.mean():.3f}"}
    best = None  # the best rule probed here: (mean, name, paired difference text)
    for name, theirs in frames.items():
        both = pd.concat([mine, theirs], axis=1, join="inner").dropna()
        diff = both.iloc[:, 0] - both.iloc[:, 1]
        _, low, high = bootstrap_mean_ci(diff.to_numpy(), seed=0)
        verdict = "better" if low > 0 else "worse" if high < 0 else "tie"
        row[name] = f"{theirs.mean():.3f} ({diff.mean():+.3f} [{low:+.3f}, {high:+.3f}] {verdict}, {len(both)} maps)"
        if name in RULES and (best is None or theirs.mean() > best[0]):
            best = (theirs.mean(), name, f"{diff.mean():+.3f} [{low:+.3f}, {high:+.3f}] {verdict}")
    row["best rule"] = f"{best[1]} {best[0]:.3f}" if best else ""
    row[f"{args.tag} − best rule"] = best[2] if best else ""
    rows.append(row)
ORDER = ["path_greedy", "greedy_target", "coverage", "term_b", "walls_b", "robust_b"]  # the rules, then the policies
table = pd.DataFrame(rows).fillna("")
table = table[
    [
        "scenario",
        args.tag,
        *[c for c in ORDER if c in table],
        *[c for c in table if c not in ORDER and c not in ("scenario", args.tag)],
    ]
]
out.mkdir(parents=True, exist_ok=True)
text = (f"Mean found fraction per scenario; beside each baseline: {args.tag} − it, paired over maps, 95 % bootstrap "
        "CI\n\n" + markdown(table.set_index("scenario")) + "\n")  # fmt: skip
(out / "summary.md").write_text(text)
short = table[["scenario", args.tag, "best rule", f"{args.tag} − best rule"]]
(out / "best_rule.md").write_text(f"{args.tag} against the best rule probed in each scenario, paired over maps, 95 % "
                                  "bootstrap CI\n\n" + markdown(short.set_index("scenario")) + "\n")  # fmt: skip
print(text)
