# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A suite's tables and figure: found fraction per family of prior error, severity and controller
#
# Reads every controller's folders of a suite (`python -m searchrl.evaluate suite=prior_error ...` writes
# `runs/suite/prior_error/<controller>/<scenario>/`) and writes, with 95 % bootstrap CIs over maps (a map is a cell
# and map seed; its prior is the same under every scenario of the suite):
# - `family.md`: per controller, the mean found fraction of each family over its severities (0.25, 0.5, 1) and
#   the suite's cells, and at severity 0 (the prior right) and over the whole suite;
# - `severity.md`: the same per severity;
# - `tail.md`: the worst-10 % tail: per family and cell, the mean of a controller's worst tenth of maps, averaged
#   over the cells (how badly it can fail, where Search-TTA reports its gains);
# - `compare.md` (with `--focus LABEL`): that controller against every other, per family, paired over maps;
# - `suite.png`: found fraction against severity, a panel per family, a line per controller, CI bands.
#
#     python analysis/suite.py runs/suite/prior_error [--focus policy:reference/robust/b] [--out DIR]

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from searchrl.analysis import cli
from searchrl.analysis.stats import bootstrap_mean_ci
from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.evaluate.results import cell_files, load

parser = cli.parser("Tables and figure of a scenario suite", dirs="SUITE_DIR")
parser.add_argument("--focus", default=None, help="controller label compared, paired, with every other")
args, _ = cli.parse(parser)
if not args.dirs:
    parser.error("give a suite's folder, e.g. runs/suite/prior_error")
roots = [Path(d) for d in args.dirs]
folders = sorted({f.parent.parent for root in roots for f in root.rglob("cells/*.parquet")})
folders = [f for f in folders if cell_files(f)]
if not folders:
    cli.stop(f"no results under {[str(r) for r in roots]}: run the suite first (docs/evaluation.md, Suites)")
OUT = cli.out_dir(args.out, Path.cwd() / "analysis" / "out" / f"suite_{roots[0].name}")
OUT.mkdir(parents=True, exist_ok=True)
# One folder per scenario: loaded one by one, since `load` would name a controller apart per folder
episodes = pd.concat([load(f) for f in folders], ignore_index=True)
episodes["map"] = episodes["n"].astype(str) + "_" + episodes["N"].astype(str) + "_" + episodes["map_seed"].astype(str)
controllers = sorted(episodes["controller"].unique())
families = sorted(set(episodes["family"]) - {"paper"})


# %%
def per_map(frame: pd.DataFrame) -> pd.Series:
    """Mean found fraction per map (over the scenarios and repeats given)."""
    return frame.groupby("map")["found_fraction"].mean()


def ci(values) -> str:
    mean, low, high = bootstrap_mean_ci(np.asarray(values))
    return f"{mean:.3f} [{low:.3f}, {high:.3f}]"


def table(rows: dict[str, dict[str, str]], first: str) -> str:
    columns = list(next(iter(rows.values())))
    lines = [f"| {first} | " + " | ".join(columns) + " |", "|---" * (len(columns) + 1) + "|"]
    return "\n".join(lines + [f"| {k} | " + " | ".join(v[c] for c in columns) + " |" for k, v in rows.items()])


right = episodes[episodes["family"] == "paper"]
wrong = episodes[episodes["family"] != "paper"]
family_rows = {}
for c in controllers:
    mine = episodes[episodes["controller"] == c]
    row = {"prior right": ci(per_map(mine[mine["family"] == "paper"]))}
    row |= {f: ci(per_map(mine[mine["family"] == f])) for f in families}
    row["whole suite"] = ci(per_map(mine))
    family_rows[c] = row
text = (f"Mean found fraction, 95 % CI over maps ({episodes['map'].nunique()} maps: cells x map seeds); a family's "
        "column averages its severities 0.25, 0.5 and 1\n\n" + table(family_rows, "controller"))  # fmt: skip
write_text_atomic(OUT / "family.md", text + "\n")
print(text)

# %%
severity_rows = {}
for (c, f), block in wrong.groupby(["controller", "family"]):
    severity_rows[f"{c} | {f}"] = {"0": ci(per_map(right[right["controller"] == c]))} | {
        f"{s:g}": ci(per_map(part)) for s, part in block.groupby("severity")
    }
write_text_atomic(OUT / "severity.md", table(severity_rows, "controller | family") + "\n")


# %%
def worst_tenth(frame: pd.DataFrame) -> float:
    """Mean over the cells of the mean of the worst 10 % of maps (at least one) of each cell."""
    tails = []
    for _, cell in frame.groupby(["n", "N"]):
        values = np.sort(per_map(cell).to_numpy())
        tails.append(values[: max(1, int(np.ceil(0.1 * len(values))))].mean())
    return float(np.mean(tails))


tail_rows = {c: {f: f"{worst_tenth(episodes[(episodes['controller'] == c) & (episodes['family'] == f)]):.3f}"
                 for f in ["paper", *families]} for c in controllers}  # fmt: skip
write_text_atomic(OUT / "tail.md", "Worst-10 % tail: per family and cell the mean of a controller's worst tenth of "
                  "maps, averaged over the cells\n\n" + table(tail_rows, "controller") + "\n")  # fmt: skip

# %%
if args.focus:
    if args.focus not in controllers:
        cli.stop(f"--focus={args.focus!r} is not among the suite's controllers: {controllers}")
    lines = [f"{args.focus} minus each controller, paired over maps, mean [95 % CI]; verdict better / tie / worse", ""]
    for other in [c for c in controllers if c != args.focus]:
        verdicts, cells = [], []
        for f in ["paper", *families]:
            a = per_map(episodes[(episodes["controller"] == args.focus) & (episodes["family"] == f)])
            b = per_map(episodes[(episodes["controller"] == other) & (episodes["family"] == f)])
            diff = (a - b).dropna()
            mean, low, high = bootstrap_mean_ci(diff.to_numpy())
            verdicts.append("better" if low > 0 else "worse" if high < 0 else "tie")
            cells.append(f"{f}: {mean:+.3f} [{low:+.3f}, {high:+.3f}] {verdicts[-1]}")
        count = {v: verdicts.count(v) for v in ("better", "tie", "worse")}
        lines += [f"## {args.focus} − {other}", "", f"better {count['better']}, tie {count['tie']}, worse "
                  f"{count['worse']} of {len(verdicts)} families (prior right included)", "", *cells, ""]  # fmt: skip
    write_text_atomic(OUT / "compare.md", "\n".join(lines))

# %%
fig, axes = plt.subplots(2, (len(families) + 1) // 2, figsize=(4 * ((len(families) + 1) // 2), 7), sharey=True)
for ax, f in zip(np.ravel(axes), families, strict=False):
    for c in controllers:
        points = [(0.0, right[right["controller"] == c])] + [
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
fig.tight_layout()
write_atomic(OUT / "suite.png", lambda tmp: fig.savefig(tmp, format="png", dpi=110))
