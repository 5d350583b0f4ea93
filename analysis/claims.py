# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The paper's claims, checked on this reproduction
#
# Every trained policy found in the evaluation directories (controller `policy:<run>`) is compared, on the same
# maps, with information surfing, footprint-greedy (where evaluated) and geometric coverage, and with the other
# policies: the paired difference in found fraction per cell, with a 95 % bootstrap CI over maps. Then the paper's
# four claims:
#
# 1. DRL beats information surfing (here: on every cell with n ≥ 40 and N ≥ 4);
# 2. model B beats model C (communication helps);
# 3. model diagonal is best;
# 4. communication helps most at large N (B − C grows with N).
#
# Writes `margins.csv` (tidy), `margins.md` (rows N, columns n) and `claims.md`. Run from the repository root:
# `python analysis/claims.py [EVAL_DIR ...] [--out DIR]`; inputs and output as in `table3.py` (else
# `SEARCHRL_EVAL_DIRS`, `SEARCHRL_ANALYSIS_OUT`).

# %%
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import load
from searchrl.reporting import cli
from searchrl.reporting.stats import efficiency_summary, markdown, paired_margins, summarize

ROOT = Path.cwd()
EVAL_DIRS, OUT = cli.eval_inputs("The paper's claims, checked on this reproduction", ROOT / "analysis" / "out")
OUT.mkdir(parents=True, exist_ok=True)
episodes = load(*EVAL_DIRS)
policy_rows = episodes[episodes.controller.str.startswith("policy:")][["model", "controller"]].drop_duplicates()
if policy_rows.model.duplicated().any():
    raise SystemExit(f"several policies per model in {EVAL_DIRS}: {policy_rows.values.tolist()}; pass one per model")
policies = dict(zip(policy_rows.model, policy_rows.controller, strict=True))  # model name -> controller label
# Surfing runs in one model's world (Φ, communication, moves; `+model=<m>`, B's by default). Surfing in B's world
# is the paper's single baseline, "surfing"; surfing in another model's world is "surfing (<m>)" and is compared
# with that model's policy too: same sensing, merging and moves, only the controller differs.
# Footprint-greedy (`controller=greedy`, with whatever settings its evaluation ran) likewise.
for heuristic in ("surfing", "greedy"):
    other_world = (episodes.controller == heuristic) & (episodes.model != "b")
    episodes.loc[other_world, "controller"] = f"{heuristic} (" + episodes.loc[other_world, "model"] + ")"
baselines = [c for c in ("surfing", "greedy", "coverage") if c in set(episodes.controller)]
same_world = {m: "surfing" if m == "b" else f"surfing ({m})" for m in policies}
same_world = {m: label for m, label in same_world.items() if label in set(episodes.controller)}
teacher_world = {m: "greedy" if m == "b" else f"greedy ({m})" for m in policies}
teacher_world = {m: label for m, label in teacher_world.items() if label in set(episodes.controller)}
print(f"policies {policies}; baselines {baselines}; surfing in the policy's own world {same_world}")

# %% [markdown]
# ## Margins over the baselines, cell by cell

# %%
pairs = [(policies[m], base) for m in sorted(policies) for base in baselines]
pairs += [(policies[m], label) for m, label in sorted(same_world.items()) if label != "surfing"]
pairs += [(policies[m], label) for m, label in sorted(teacher_world.items()) if label != "greedy"]
pairs += [
    (policies[x], policies[y])
    for x, y in [("b", "c"), ("diagonal", "a"), ("diagonal", "b"), ("diagonal", "c")]
    if x in policies and y in policies
]
margins = pd.concat([paired_margins(episodes, a, b) for a, b in pairs], ignore_index=True) if pairs else None
sections = []
if margins is not None:
    write_atomic(OUT / "margins.csv", lambda tmp: margins.to_csv(tmp, index=False))
    labelled = margins.assign(
        entry=[
            f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}"
            for d, lo, hi, v in zip(margins["diff"], margins.low, margins.high, margins.verdict, strict=True)
        ]
    )
    for (mine, base), block in labelled.groupby(["controller", "baseline"], sort=False):
        layout = block.pivot_table(index="N", columns="n", values="entry", aggfunc="first").fillna("–")
        sections.append(f"### {mine} − {base}\n\n" + markdown(layout))
    write_text_atomic(OUT / "margins.md", "\n".join(sections))
print("\n".join(sections) or "no policy results to compare")

# %% [markdown]
# ## The claims


# %%
def verdicts(mine: str, base: str, region: pd.Series | None = None) -> str:
    block = margins[(margins.controller == mine) & (margins.baseline == base)]
    if region is not None:
        block = block[region.loc[block.index]]
    if block.empty:
        return "no evaluated cell in this region"
    counts = block.verdict.value_counts()
    worst = block.loc[block["diff"].idxmin()]
    return (
        f"better on {counts.get('better', 0)} of {len(block)} cells, tie {counts.get('tie', 0)}, saturated "
        f"{counts.get('saturated', 0)}, worse {counts.get('worse', 0)}, too few maps "
        f"{counts.get('too few maps', 0)}; smallest margin {worst['diff']:+.3f} "
        f"[{worst.low:+.3f}, {worst.high:+.3f}] at n = {worst.n}, N = {worst.N}"
    )


def not_better(block: pd.DataFrame) -> str:
    """Markdown table of the cells of `block` (margins rows) where a policy is not better: rows cells, columns
    policies; the cells a policy is better on read "better"."""
    short = block[block.verdict != "better"].sort_values(["n", "N"])
    short = short.assign(
        cell=[f"n{n} N{agents}" for n, agents in zip(short.n, short.N, strict=True)],
        entry=[
            f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}"
            for d, lo, hi, v in zip(short["diff"], short.low, short.high, short.verdict, strict=True)
        ],
    )
    if short.empty:
        return "(none)"
    return markdown(
        short.pivot_table(index="cell", columns="controller", values="entry", aggfunc="first", sort=False)
        .sort_index(axis=1)
        .fillna("better")
    )


lines = ["# Claims\n"]
region = (margins.n >= 40) & (margins.N >= 4) if margins is not None else None
if margins is not None and "surfing" in baselines:
    lines.append("## 1. DRL beats information surfing (cells with n ≥ 40 and N ≥ 4)\n")
    lines += [f"- {m}: " + verdicts(policies[m], "surfing", region) for m in sorted(policies)]
    lines.append("\nCells of that region where a policy does not find more than surfing (tie, saturated or worse):\n")
    lines.append(not_better(margins[region & (margins.baseline == "surfing")]))
    lines.append("\nAll cells:\n")
    lines += [f"- {m}: " + verdicts(policies[m], "surfing") for m in sorted(policies)]
    # Where a policy trails surfing: does it leave the last targets (fewer complete episodes, longer L)?
    behind = margins[(margins.baseline == "surfing") & (margins.verdict == "worse")][["controller", "n", "N"]]
    if len(behind):
        pairs_behind = pd.concat([behind, behind.assign(controller="surfing")]).drop_duplicates()
        detail = (
            episodes.merge(pairs_behind, on=["controller", "n", "N"])
            .groupby(["n", "N", "controller"])
            .agg(
                found=("found_fraction", "mean"),
                complete=("found_fraction", lambda f: (f == 1).mean()),
                mean_L=("L", "mean"),
            )
        )
        lines.append("\nCells where a policy trails surfing: share of episodes that find every target, mean L:\n")
        lines.append(markdown(detail))
if margins is not None and len(same_world) > 1:
    lines.append("\n## 1b. DRL beats information surfing in the policy's own world (n ≥ 40 and N ≥ 4)\n")
    lines.append("Surfing with the model's Φ, communication and moves (`+model=<m>`); for B this is section 1.\n")
    lines += [f"- {m} − {label}: " + verdicts(policies[m], label, region) for m, label in sorted(same_world.items())]
    own = pd.concat(
        [margins[(margins.controller == policies[m]) & (margins.baseline == label)] for m, label in same_world.items()]
    )
    lines.append("\nCells of that region where a policy does not find more than surfing in its own world:\n")
    lines.append(not_better(own[region.loc[own.index]]))
if margins is not None and teacher_world:
    lines.append("\n## Policies against footprint-greedy in their own world (all cells)\n")
    lines.append(
        "How close a policy comes to footprint-greedy in its own world (`controller=greedy +model=<m>`, with "
        "the settings of the evaluated greedy runs; pass the teacher's to compare a clone with its "
        "teacher, `conf/experiment/clone_<m>.yaml`).\n"
    )
    lines += [f"- {m} − {label}: " + verdicts(policies[m], label) for m, label in sorted(teacher_world.items())]
if margins is not None and "coverage" in baselines:
    lines.append("\n## Against geometric coverage (all cells)\n")
    lines += [f"- {m}: " + verdicts(policies[m], "coverage") for m in sorted(policies)]
    # Why: coverage ignores the prior but never overlaps. Its lanes are 3 rows apart, so in 256 steps a team
    # sweeps about N·256·3 cells; where that exceeds the n² of the domain, a sweep finds nearly everything.
    lines.append(
        "\nVerdicts against coverage by sweep capacity N·256·3 / n² (the share of the domain a team of N "
        "can sweep once in 256 steps):\n"
    )
    versus = margins[margins.baseline == "coverage"]
    capacity = pd.cut(versus.N * 256 * 3 / versus.n**2, [0, 0.5, 1, float("inf")], labels=["< 0.5", "0.5-1", "≥ 1"])
    tally = versus.assign(capacity=capacity).pivot_table(
        index=["controller", "capacity"], columns="verdict", values="n", aggfunc="count", fill_value=0, observed=True
    )
    lines.append(markdown(tally))
if "b" in policies and "c" in policies:
    lines.append("\n## 2. B beats C\n")
    lines.append("- b − c: " + verdicts(policies["b"], policies["c"]))
    lines.append("\n## 4. Communication helps most at large N: mean of B − C over world sizes, by N\n")
    by_n = margins[(margins.controller == policies["b"]) & (margins.baseline == policies["c"])]
    lines.append(markdown(by_n.groupby("N")[["diff"]].mean()))
    # How often agents are within communication range (Chebyshev ≤ 2): F counts neighbour pairs per step, so
    # 2F / (N·L) is the mean number of neighbours an agent has per step. C's F is counted though it cannot merge.
    lines.append("\nNeighbours per agent per step, 2F / (N·L) (how often communication can happen), by n:\n")
    near = episodes[episodes.controller.isin([policies["b"], policies["c"], "surfing"])]
    near = near.assign(neighbours=2 * near.F / (near.N * near.L.clip(lower=1)))
    lines.append(markdown(near.pivot_table(index="N", columns=["controller", "n"], values="neighbours"), digits=2))
if "diagonal" in policies:
    lines.append("\n## 3. Diagonal is best\n")
    lines += [
        f"- diagonal − {m}: " + verdicts(policies["diagonal"], policies[m]) for m in ("a", "b", "c") if m in policies
    ]
    # The best model per cell by mean found fraction (a "best" within CI noise of the next is still listed).
    means = episodes[episodes.controller.isin(policies.values())].groupby(["n", "N", "model"]).found_fraction.mean()
    best = means.groupby(["n", "N"]).idxmax().map(lambda key: key[2]).unstack("n")
    lines.append("\nModel with the highest mean found fraction per cell (rows N, columns n):\n")
    lines.append(markdown(best.fillna("–")))
if "bound_fraction" in episodes and episodes["bound_fraction"].notna().all():
    # How much of what any team could expect each controller finds (searchrl/evaluate/cell_bounds.py).
    lines.append("\n## Efficiency against the search bound\n")
    lines.append(
        "Mean found fraction, bound and found / bound over the hard cells (n = 40 with N <= 2, n = 80 "
        "with N <= 8, n = 160 with N <= 32), and mean found / bound over every cell whose bound is below "
        "0.995:\n"
    )
    lines.append(markdown(efficiency_summary(summarize(episodes))))
write_text_atomic(OUT / "claims.md", "\n".join(lines) + "\n")
print("\n".join(lines))
