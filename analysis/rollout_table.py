# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The rollout planner against B's teacher and the best rule of each cell
#
# `python analysis/rollout_table.py PLANNER_DIR [PLANNER_DIR ...] --rules TEACHER_DIR RULE_DIR ... --out DIR`:
# every planner folder (`controller=rollout`, labelled by its folder name, e.g. its
# budget) paired per map with each rule folder evaluated on the same grid and seed. The first rule folder is the
# teacher; a cell's *best rule* is the rule folder with the highest mean on that cell's maps. Per cell: each side's
# mean, planner − teacher and planner − best rule (the mean of the per-map differences, repeats averaged per map,
# 95 % bootstrap CI over maps, `paired_margins`' verdict), then the tallies. Where a planner folder has a
# `<folder>_seconds.txt` beside it (lines `<cell> <seconds>`, each cell's evaluation timed), its decisions per second
# are the agent-steps it played over those seconds. Writes `rollout.csv`, `rollout.md` and `budgets.md` (each
# planner's gain over the teacher and decisions per second, side by side per cell).
#
#     python analysis/rollout_table.py runs/eval/roll100/rollout_m1_h0 \
#         --rules runs/eval/roll100/teacher_b runs/eval/roll100/coverage runs/eval/roll100/surfing \
#         --out analysis/out/rollout_planner

# %%
from pathlib import Path

import pandas as pd

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import load
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown, paired_margins

parser = cli.parser(
    "The rollout planner against the teacher and the best rule, cell by cell",
    "PLANNER_DIR",
    "planner evaluation folders, one or more",
)
parser.add_argument(
    "--rules",
    nargs="+",
    required=True,
    metavar="RULE_DIR",
    help="rule evaluation folders on the same grid and seed; the first is the teacher",
)
PLANNERS, OUT, args = cli.eval_args(parser, Path("analysis") / "out" / "rollout_planner", default_dirs=list)
RULES = [Path(d) for d in args.rules]
cli.check_eval_dirs(RULES, 1)
cli.check_comparable([*PLANNERS, *RULES])
names = [d.name for d in [*PLANNERS, *RULES]]
if len(set(names)) < len(names):
    cli.stop(f"folders {names}: their names label the sides; make them differ")
episodes = pd.concat([load(d).assign(controller=d.name) for d in [*PLANNERS, *RULES]], ignore_index=True)

# %% [markdown]
# ## Each planner against the teacher and against the best rule on its cells

# %%
teacher = RULES[0].name
per_map = episodes.groupby(["controller", "n", "N", "map_seed"]).found_fraction.mean().reset_index()
rule_means = per_map[per_map.controller.isin([d.name for d in RULES])]
rows = []
for planner in PLANNERS:
    cells = per_map[per_map.controller == planner.name][["n", "N", "map_seed"]]
    # each cell's best rule: the highest mean over the maps this planner played there
    on_maps = rule_means.merge(cells, on=["n", "N", "map_seed"])
    best = on_maps.groupby(["n", "N", "controller"]).found_fraction.mean().reset_index()
    best = best.loc[best.groupby(["n", "N"]).found_fraction.idxmax()].rename(columns={"controller": "best_rule"})
    against = {"teacher": paired_margins(episodes, planner.name, teacher)}
    for rule in {r for r in best.best_rule}:
        margins = paired_margins(episodes, planner.name, rule)
        keep = best[best.best_rule == rule][["n", "N"]]
        against.setdefault("best", []).append(margins.merge(keep, on=["n", "N"]))
    best_margins = pd.concat(against["best"], ignore_index=True)
    table = (
        against["teacher"]
        .merge(best_margins, on=["n", "N"], suffixes=("", "_best"))
        .merge(best[["n", "N", "best_rule"]], on=["n", "N"])
    )
    table["planner"] = planner.name
    timed = planner.parent / f"{planner.name}_seconds.txt"
    if timed.is_file():  # decisions per second: the planner's agent-steps over each cell's timed seconds
        seconds = pd.read_csv(timed, sep=" ", names=["cell", "seconds"])
        mine = episodes[episodes.controller == planner.name]
        steps = (mine.L * mine.N).groupby([mine.n, mine.N]).sum().rename("agent_steps").reset_index()
        steps["cell"] = "n" + steps.n.astype(str) + "_N" + steps.N.astype(str)
        rate = steps.merge(seconds, on="cell").assign(decisions_per_s=lambda r: r.agent_steps / r.seconds)
        table = table.merge(rate[["n", "N", "decisions_per_s"]], on=["n", "N"], how="left")
    rows.append(table)
result = pd.concat(rows, ignore_index=True).sort_values(["planner", "n", "N"])
OUT.mkdir(parents=True, exist_ok=True)
write_atomic(OUT / "rollout.csv", lambda tmp: result.to_csv(tmp, index=False))


def tally(verdicts: pd.Series) -> str:
    counts = verdicts.value_counts()
    return ", ".join(f"{v} {counts.get(v, 0)}" for v in ("better", "tie", "saturated", "worse", "too few maps"))


lines = [f"# The rollout planner against {teacher} and the best of {', '.join(d.name for d in RULES)} per cell\n"]
for planner, block in result.groupby("planner", sort=False):
    lines.append(f"## {planner}\n")
    lines.append(f"- − {teacher}: {tally(block.verdict)} of {len(block)} cells")
    lines.append(f"- − the best rule: {tally(block.verdict_best)} of {len(block)} cells\n")
    shown = pd.DataFrame(
        {
            "n": block.n,
            "N": block.N,
            "maps": block.maps,
            "planner": block.mine,
            teacher: block.base,
            f"− {teacher}": [
                f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}"
                for d, lo, hi, v in zip(block["diff"], block.low, block.high, block.verdict, strict=True)
            ],
            "best rule": block.best_rule,
            "− best rule": [
                f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}] {v}"
                for d, lo, hi, v in zip(
                    block.diff_best, block.low_best, block.high_best, block.verdict_best, strict=True
                )
            ],
        }
    )
    lines.append(markdown(shown.set_index(["n", "N"])))
write_text_atomic(OUT / "rollout.md", "\n".join(lines))
print("\n".join(lines))

# %% [markdown]
# ## The budgets side by side: each planner's gain over the teacher and its decisions per second, per cell

# %%
rates = result["decisions_per_s"] if "decisions_per_s" in result else pd.Series(float("nan"), index=result.index)
entry = [
    f"{d:+.3f} [{lo:+.3f}, {hi:+.3f}]" + (f", {r:,.0f}/s" if r == r else "")
    for d, lo, hi, r in zip(result["diff"], result.low, result.high, rates, strict=True)
]
budgets = result.assign(entry=entry).pivot_table(index=["n", "N"], columns="planner", values="entry", aggfunc="first")
budgets = budgets[[p.name for p in PLANNERS if p.name in budgets]].fillna("–")
text = (
    f"# Each planner minus {teacher} (95 % CI over maps) and its decisions per second, per cell\n\n{markdown(budgets)}"
)
write_text_atomic(OUT / "budgets.md", text)
