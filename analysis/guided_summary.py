# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A guided policy against the rules, one row per scenario
#
# Reads evaluations laid out as `<root>/<scenario>/<controller>/` (the probe of `analysis/guided_probe.sh` on seeds
# no suite uses, or the suites' own maps of `analysis/guided_suites.sh`) and writes, per scenario, each
# controller's mean found fraction and the guided policy's paired difference to each, with a 95 % bootstrap CI over
# maps (the same cells, maps and seeds for every controller): `summary.md`; against the best rule of each scenario
# (the highest mean among path_greedy, target-greedy, coverage and the evidence switch): `best_rule.md`; and each
# controller's worst-10 % tail (per cell the mean of its worst tenth of maps, averaged over the cells): `tail.md`.
# Where two scenarios or more were run, a last row, `whole`, takes each map's mean over every scenario, for the
# controllers run on all of them (on the maps each ran under every one).
#
#     python analysis/guided_summary.py b [--probe runs/eval/guided_probe] [--out analysis/out/guided_probe/b]
#     python analysis/guided_summary.py b_plan --probe runs/eval/guided_suite/obstacles \
#         --out analysis/out/guided_suite/obstacles

# %%
from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_text_atomic
from searchrl.evaluate.results import load
from searchrl.reporting.stats import bootstrap_mean_ci, markdown, worst_tenth

parser = argparse.ArgumentParser(description=__doc__)
parser.add_argument("tag", help="the guided policy's folder name in each scenario")
parser.add_argument("--probe", default="runs/eval/guided_probe", help="the root: <root>/<scenario>/<controller>/")
parser.add_argument("--out", default=None)
args = parser.parse_args()
out = Path(args.out or f"analysis/out/guided_probe/{args.tag}")
KEY = ["n", "N", "map_seed", "repeat"]
RULES = ("path_greedy", "greedy_target", "coverage", "switch")
ORDER = ["path_greedy", "greedy_target", "coverage", "switch", "term_b", "walls_b", "robust_b"]  # rules, policies

# %% [markdown]
# Each scenario's episodes, one frame per controller, indexed by map (cell, map seed, repeat); then `whole`: each
# map's mean over the scenarios, for the controllers that ran every one of them.

# %%
scenarios = {}
for scenario in sorted(p for p in Path(args.probe).iterdir() if (p / args.tag).is_dir()):
    scenarios[scenario.name] = {
        c.name: load(c).set_index(KEY)["found_fraction"] for c in sorted(scenario.iterdir()) if c.is_dir()
    }
if len(scenarios) > 1:
    everywhere = set.intersection(*(set(frames) for frames in scenarios.values()))
    # each map's mean over the scenarios, on the maps a controller ran under every one of them
    scenarios["whole"] = {
        c: pd.concat([frames[c] for frames in scenarios.values()], axis=1).dropna().mean(axis=1)
        for c in sorted(everywhere)
    }


def paired(mine: pd.Series, theirs: pd.Series) -> tuple[float, str]:
    """(the other's mean, "mine − it [95 % CI] verdict, maps") over the maps both ran."""
    both = pd.concat([mine, theirs], axis=1, join="inner").dropna()
    diff = both.iloc[:, 0] - both.iloc[:, 1]
    _, low, high = bootstrap_mean_ci(diff.to_numpy(), seed=0)
    verdict = "better" if low > 0 else "worse" if high < 0 else "tie"
    return theirs.mean(), f"{diff.mean():+.3f} [{low:+.3f}, {high:+.3f}] {verdict}, {len(both)} maps"


# %%
rows, tails = [], []
for name, frames in scenarios.items():
    mine = frames[args.tag]
    row, best = {"scenario": name, args.tag: f"{mine.mean():.3f}"}, None
    for other, theirs in frames.items():
        if other == args.tag:
            continue
        mean, text = paired(mine, theirs)
        row[other] = f"{mean:.3f} ({text})"
        if other in RULES and (best is None or mean > best[0]):
            best = (mean, other, text)
    row["best rule"] = f"{best[1]} {best[0]:.3f}" if best else ""
    row[f"{args.tag} − best rule"] = best[2] if best else ""
    rows.append(row)
    tails.append(
        {"scenario": name}
        | {c: f"{worst_tenth(s.rename('found_fraction').reset_index()):.3f}" for c, s in frames.items()}
    )


def ordered(frame: pd.DataFrame) -> pd.DataFrame:
    """The scenario, the guided policy, the rules, the policies, then any other controller."""
    rest = [c for c in frame if c not in ORDER and c not in ("scenario", args.tag)]
    return frame[["scenario", args.tag, *[c for c in ORDER if c in frame], *rest]].set_index("scenario")


table = pd.DataFrame(rows).fillna("")
text = (
    f"Mean found fraction per scenario; beside each baseline: {args.tag} − it, paired over maps, 95 % bootstrap "
    "CI\n\n" + markdown(ordered(table)) + "\n"
)
out.mkdir(parents=True, exist_ok=True)
write_text_atomic(out / "summary.md", text)
short = table[["scenario", args.tag, "best rule", f"{args.tag} − best rule"]].set_index("scenario")
write_text_atomic(
    out / "best_rule.md",
    f"{args.tag} against the best rule of each scenario, paired over maps, 95 % "
    "bootstrap CI\n\n" + markdown(short) + "\n",
)
tail = markdown(ordered(pd.DataFrame(tails).fillna("")))
write_text_atomic(
    out / "tail.md",
    "Worst-10 % tail: per scenario and cell the mean of a controller's worst tenth of "
    f"maps, averaged over the cells\n\n{tail}\n",
)
print(text)
