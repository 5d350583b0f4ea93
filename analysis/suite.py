# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A suite's tables and figure: found fraction per family of prior error (or scenario), severity and controller
#
# Reads every controller's folders of a suite (`python -m searchrl.evaluate suite=prior_error ...` writes
# `runs/suite/prior_error/<controller>/<scenario>/`; a controller is named by its folder, so `greedy_target` and
# `hedge0.1` stay apart though their rows both say `greedy`) and writes, with 95 % bootstrap CIs over maps (a map is
# a cell and map seed; its prior is the same under every scenario of the suite). A suite's groups are its families of
# prior error (prior_error: each over its severities), or its scenarios where it has none (obstacles: iid0.1c, ...):
# - `family.md` (`scenario.md`): per controller, the mean found fraction of each group over the suite's cells, with
#   the prior right (the open grid) and the whole suite;
# - `severity.md` (families only): the same per severity;
# - `tail.md`: the worst-10 % tail: per group and cell, the mean of a controller's worst tenth of maps, averaged
#   over the cells (how badly it can fail, where Search-TTA reports its gains);
# - `moves.md`: per controller and group, the share of moves a wall or agent blocked and the share of agent-steps
#   that swept no new cell (`blocked`, `stale`: how a rule fails among walls);
# - `quality.md`: per bin of prior quality (how well the prior the agents hold points at the episode's targets,
#   searchrl/world/truth.py), each controller's mean found fraction over the same episodes, and the best: which
#   controller to use at which prior quality;
# - `compare.md` (with `--focus LABEL`): that controller against every other, per group, paired over maps;
# - `suite.png`: found fraction against severity, a panel per family, a line per controller, CI bands (a suite of
#   scenarios: found fraction per scenario).
#
#     python analysis/suite.py runs/suite/prior_error [--focus policy:reference/robust/b] [--out DIR]
#     python analysis/suite.py runs/suite/obstacles --focus path_greedy

# %%
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from omegaconf import OmegaConf

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import cell_files, coverage, load
from searchrl.reporting import cli
from searchrl.reporting.stats import bootstrap_mean_ci, worst_tenth

parser = cli.parser("Tables and figure of a scenario suite", dirs="SUITE_DIR")
parser.add_argument("--focus", default=None, help="controller label compared, paired, with every other")
args, _ = cli.parse(parser)
if not args.dirs:
    parser.error("give a suite's folder, e.g. runs/suite/prior_error")
roots = [Path(d) for d in args.dirs]
folders = {f.parent.parent: root for root in roots for f in root.rglob("cells/*.parquet")}
folders = {f: root for f, root in sorted(folders.items()) if cell_files(f)}
if not folders:
    cli.stop(f"no results under {[str(r) for r in roots]}: run the suite first (docs/evaluation.md, Suites)")
cli.check_eval_dirs(list(folders))  # a damaged cell file named in one line, before any output
for scenario in {coverage(f).get("scenario") for f in folders}:  # the controllers of one scenario: the same worlds
    cli.check_comparable([f for f in folders if coverage(f).get("scenario") == scenario])


def labelled(folder: Path, root: Path) -> pd.DataFrame:
    """A scenario folder's rows, named by their controller's folder under the suite (`greedy_target`, `hedge0.1`,
    `policy:reference/b` for policy/reference/b): one controller run with two settings (target-greedy hedged or
    not, both recorded as `greedy`) stays two. The rows' own label where the root is the controller's folder."""
    rows = load(folder)  # one folder per scenario, so `load` names nothing apart
    parts = folder.parent.relative_to(root).parts
    if parts:
        rows["controller"] = "policy:" + "/".join(parts[1:]) if parts[0] == "policy" else "/".join(parts)
    return rows


episodes = pd.concat([labelled(f, root) for f, root in folders.items()], ignore_index=True)
episodes["map"] = episodes["n"].astype(str) + "_" + episodes["N"].astype(str) + "_" + episodes["map_seed"].astype(str)
controllers = sorted(episodes["controller"].unique())
GROUP = "family" if set(episodes["family"]) - {"paper"} else "scenario"  # a suite of scenarios has no family
families = sorted(set(episodes[GROUP]) - {"paper"})

# %% [markdown]
# Every table compares controllers on the same maps. A controller without some scenario is refused; a suite run part
# of the way (or two suites of different grids) is compared on the maps every controller has under every scenario,
# and the tables say how many were left out and which cells they cover.

# %%
held = episodes.groupby(["controller", "scenario"])["map"].agg(frozenset)
scenarios = sorted(episodes["scenario"].unique())
absent = [(c, sc) for c in controllers for sc in scenarios if (c, sc) not in held.index]
if absent:
    cli.stop(
        f"{absent[0][0]} has no results under scenario {absent[0][1]!r} ({len(absent)} controller and scenario "
        f"pairs missing): run it, or leave that controller's folder out"
    )
# The suite's own list of scenarios (suite.yaml beside each controller's scenario folders): the tables name those
# with no results, and call a column "whole suite" only when there are none.
listed = {
    label
    for folder in folders
    for record in [folder.parent / "suite.yaml"]
    if record.exists()
    for label in OmegaConf.load(record).scenarios
}
missing = sorted(listed - set(scenarios))
WHOLE = "whole suite" if listed and not missing else f"the {len(scenarios)} scenarios held"
MISSING = (
    f"; no results for {len(missing)} of the suite's {len(listed)} scenarios ({', '.join(missing)})"
    if missing
    else ""
    if listed
    else "; the suite's list of scenarios is unknown (no suite.yaml)"
)
common = frozenset.intersection(*held)
if not common:
    cli.stop("the controllers and scenarios share no map (cell and map seed): folders of different grids or seeds")
left_out = episodes["map"].nunique() - len(common)
episodes = episodes[episodes["map"].isin(common)].reset_index(drop=True)
CELLS = sorted({(int(n), int(a)) for n, a in zip(episodes["n"], episodes["N"], strict=True)})
GRID = (
    f"cells {', '.join(f'n{n}_N{a}' for n, a in CELLS)}"
    + (f"; {left_out} maps that not every controller and scenario has left out" if left_out else "")
    + MISSING
)
if left_out:
    print(
        f"note: {left_out} maps left out, held by some controllers or scenarios only (a run not finished?)",
        file=sys.stderr,
    )
OUT = cli.out_dir(args.out, Path.cwd() / "analysis" / "out" / f"suite_{roots[0].name}")
OUT.mkdir(parents=True, exist_ok=True)


# %%
def per_map(frame: pd.DataFrame) -> pd.Series:
    """Mean found fraction per map (over the scenarios and repeats given)."""
    return frame.groupby("map")["found_fraction"].mean()


def ci(values) -> str:
    mean, low, high = bootstrap_mean_ci(np.asarray(values))
    return f"{mean:.3f} [{low:.3f}, {high:.3f}]"


def table(rows: dict[str, dict[str, str]], first: str) -> str:
    columns = list(next(iter(rows.values())))
    lines = [f"| {first} | " + " | ".join(columns) + " |", "|---" * (len(columns) + first.count("|") + 1) + "|"]
    return "\n".join(lines + [f"| {k} | " + " | ".join(v[c] for c in columns) + " |" for k, v in rows.items()])


right = episodes[episodes[GROUP] == "paper"]
wrong = episodes[episodes[GROUP] != "paper"]
first = "prior right" if GROUP == "family" else "open"
family_rows = {}
for c in controllers:
    mine = episodes[episodes["controller"] == c]
    row = {first: ci(per_map(mine[mine[GROUP] == "paper"]))} if (mine[GROUP] == "paper").any() else {}
    row |= {f: ci(per_map(mine[mine[GROUP] == f])) for f in families}
    row[WHOLE] = ci(per_map(mine))
    family_rows[c] = row
held = [f"{s:g}" for s in sorted(wrong["severity"].unique())]  # a part of a suite may hold only some
held = ", ".join(held[:-1]) + " and " + held[-1] if len(held) > 1 else "".join(held)
note = f"a family's column averages its severities {held}" if GROUP == "family" else "a column per scenario"
text = (
    f"Mean found fraction, 95 % CI over maps ({episodes['map'].nunique()} maps: cells x map seeds; {GRID}); "
    f"{note}\n\n" + table(family_rows, "controller")
)
write_text_atomic(OUT / f"{GROUP}.md", text + "\n")
print(text)

# %%
if GROUP == "family":
    severity_rows = {}
    for (c, f), block in wrong.groupby(["controller", "family"]):
        mine = right[right["controller"] == c]  # the prior right (severity 0): "–" where a part lacks it
        severity_rows[f"{c} | {f}"] = {"0": ci(per_map(mine)) if len(mine) else "–"} | {
            f"{s:g}": ci(per_map(part)) for s, part in block.groupby("severity")
        }
    write_text_atomic(OUT / "severity.md", table(severity_rows, "controller | family") + "\n")


# %%
groups = (["paper"] if (episodes[GROUP] == "paper").any() else []) + families
tail_rows = {
    c: {f: f"{worst_tenth(episodes[(episodes['controller'] == c) & (episodes[GROUP] == f)]):.3f}" for f in groups}
    for c in controllers
}
write_text_atomic(
    OUT / "tail.md",
    f"Worst-10 % tail: per {GROUP} and cell the mean of a controller's worst tenth of "
    "maps, averaged over the cells\n\n" + table(tail_rows, "controller") + "\n",
)

# %%
moves = {
    c: {
        f: " / ".join(
            f"{episodes[(episodes['controller'] == c) & (episodes[GROUP] == f)][m].mean():.3f}"
            if m in episodes
            else "–"
            for m in ("blocked", "stale")
        )
        for f in groups
    }
    for c in controllers
}
write_text_atomic(
    OUT / "moves.md",
    f"Blocked / stale: per {GROUP}, the mean share of a team's moves a wall or agent "
    "stopped / of its agent-steps that swept no cell new to the team (– where the rows predate the "
    "column)\n\n" + table(moves, "controller") + "\n",
)

# %%
EDGES = [-1.0, 0.0, 0.2, 0.4, 0.6, 1.0]  # prior quality: 0 no better than uniform, 1 every target on the best cell
BINS = ["<= 0", "0 to 0.2", "0.2 to 0.4", "0.4 to 0.6", "> 0.6"]
binned = episodes.assign(quality=pd.cut(episodes["prior_quality"], EDGES, labels=BINS, include_lowest=True))
by_bin = binned.pivot_table(
    index="quality", columns="controller", values="found_fraction", aggfunc="mean", observed=True
)
count = binned[binned["controller"] == controllers[0]].groupby("quality", observed=True).size()
quality_rows = {
    str(b): {
        "episodes": str(count.get(b, 0)),
        **{c: f"{row[c]:.3f}" for c in controllers},
        "best (lead)": f"{row.idxmax()} ({row.max() - row.drop(row.idxmax()).max():+.3f})"
        if len(row) > 1
        else row.idxmax(),
    }
    for b, row in by_bin.iterrows()
}
write_text_atomic(
    OUT / "quality.md",
    "Mean found fraction per bin of prior quality (the same episodes for every "
    "controller; 0 = the prior no better than uniform at the targets)\n\n"
    + table(quality_rows, "prior quality")
    + "\n",
)

# %%
if args.focus:
    if args.focus not in controllers:
        cli.stop(f"--focus={args.focus!r} is not among the suite's controllers: {controllers}")
    lines = [f"{args.focus} minus each controller, paired over maps, mean [95 % CI]; verdict better / tie / worse", ""]
    for other in [c for c in controllers if c != args.focus]:
        verdicts, cells = [], []
        for f in groups:
            a = per_map(episodes[(episodes["controller"] == args.focus) & (episodes[GROUP] == f)])
            b = per_map(episodes[(episodes["controller"] == other) & (episodes[GROUP] == f)])
            diff = (a - b).dropna()
            mean, low, high = bootstrap_mean_ci(diff.to_numpy())
            verdicts.append("better" if low > 0 else "worse" if high < 0 else "tie")
            cells.append(f"{f}: {mean:+.3f} [{low:+.3f}, {high:+.3f}] {verdicts[-1]}")
        count = {v: verdicts.count(v) for v in ("better", "tie", "worse")}
        lines += [
            f"## {args.focus} − {other}",
            "",
            f"better {count['better']}, tie {count['tie']}, worse "
            f"{count['worse']} of {len(verdicts)} {GROUP} groups (the open or right one included)",
            "",
            *cells,
            "",
        ]
    write_text_atomic(OUT / "compare.md", "\n".join(lines))


# %%
plt.rcParams["axes.prop_cycle"] = plt.cycler(color=plt.cm.tab20.colors)  # 20 colours: a suite holds over 10 controllers


def scenario_figure():
    """One panel: found fraction per scenario, a line per controller, CI bars (a suite without families)."""
    fig, ax = plt.subplots(figsize=(1.2 * len(groups) + 3, 4))
    for c in controllers:
        mine = episodes[episodes["controller"] == c]
        stats = np.array([bootstrap_mean_ci(per_map(mine[mine[GROUP] == g]).to_numpy()) for g in groups])
        ax.errorbar(
            range(len(groups)),
            stats[:, 0],
            yerr=[stats[:, 0] - stats[:, 1], stats[:, 2] - stats[:, 0]],
            marker="o",
            capsize=3,
            label=c,
        )
    ax.set_xticks(range(len(groups)), ["open" if g == "paper" else g for g in groups], rotation=30)
    ax.set_ylabel("found fraction")
    ax.legend(fontsize=7)
    return fig


def family_figure():
    """Found fraction against severity, a panel per family, a line per controller, CI bands."""
    fig, axes = plt.subplots(2, (len(families) + 1) // 2, figsize=(4 * ((len(families) + 1) // 2), 7), sharey=True)
    for ax, f in zip(np.ravel(axes), families, strict=False):
        for c in controllers:
            start = right[right["controller"] == c]  # the prior right, at severity 0, unless a part lacks it
            points = ([(0.0, start)] if len(start) else []) + [
                (s, part) for s, part in wrong[(wrong["controller"] == c) & (wrong["family"] == f)].groupby("severity")
            ]
            stats = np.array([bootstrap_mean_ci(per_map(p).to_numpy()) for _, p in points])
            xs = [s for s, _ in points]
            ax.plot(xs, stats[:, 0], marker="o", label=c)
            ax.fill_between(xs, stats[:, 1], stats[:, 2], alpha=0.2)
        ax.set_title(f)
        ax.set_xlabel("severity")
    np.ravel(axes)[0].set_ylabel("found fraction")
    for ax in np.ravel(axes)[len(families) :]:
        ax.axis("off")
    np.ravel(axes)[0].legend(fontsize=7)
    return fig


fig = family_figure() if GROUP == "family" else scenario_figure()
fig.tight_layout()
write_atomic(OUT / "suite.png", lambda tmp: fig.savefig(tmp, format="png", dpi=110))
