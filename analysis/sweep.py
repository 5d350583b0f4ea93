# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A sweep as an answer: the score by setting, with a 95 % CI over seeds, and validation curves
#
# Reads one Hydra multirun folder of `python -m searchrl.train -m ...` (each job's `.hydra/overrides.yaml`,
# `score.json` and `progress.csv`) and writes `sweep.md` and `sweep.csv` (one row per setting: the overrides that
# differ between jobs, seeds finished, mean score and a bootstrap CI over seeds) and `sweep_curves.png` (validation
# found fraction against agent-steps, mean over seeds per setting, each seed faint). Run from the repository root:
#
#     python analysis/sweep.py SWEEP_DIR [--out DIR]
#
# The folder as argument, else `SEARCHRL_SWEEP_DIR` (what a notebook reads), else the newest folder under
# `runs/multirun/`; output folder `--out`, else `SEARCHRL_ANALYSIS_OUT`, else `analysis/out/sweep_<folder name>`.

# %%
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import yaml

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown
from searchrl.reporting.sweep import load_jobs, score_table, setting_keys, validation_curves

ROOT = Path.cwd()
p = cli.parser(
    "The score of a sweep by setting",
    "SWEEP_DIR",
    "a multirun folder (default: $SEARCHRL_SWEEP_DIR, then the newest under runs/multirun/)",
)
args, _ = cli.parse(p)
given = args.dirs or [d for d in [cli.setting(None, "SEARCHRL_SWEEP_DIR")] if d]
newest = sorted((ROOT / "runs" / "multirun").glob("*/"), key=lambda d: d.stat().st_mtime)[-1:]
if len(given) > 1:
    cli.stop(f"one sweep folder at a time ({len(given)} given)")
SWEEP = Path(given[0]) if given else (newest[0] if newest else None)
if SWEEP is None or not SWEEP.is_dir():
    cli.stop(f"sweep folder {str(SWEEP)!r} does not exist: pass a folder of `python -m searchrl.train -m ...`")
try:
    jobs = load_jobs(SWEEP)
except (FileNotFoundError, ValueError) as err:  # no job, or a job's file that cannot be trusted: named
    cli.stop(str(err))
OUT = cli.out_dir(args.out, ROOT / "analysis" / "out" / f"sweep_{SWEEP.name}")
OUT.mkdir(parents=True, exist_ok=True)
keys = setting_keys(jobs)
print(f"{SWEEP}: {len(jobs)} jobs, {int(jobs.finished.sum())} finished; settings vary in {keys or 'nothing'}")

# %% [markdown]
# ## The score by setting
#
# The score of a run is its mean validation found fraction over its last validations (`score.json`); a setting's
# row is the mean over its seeds with a 95 % percentile-bootstrap interval (scipy). With three seeds the interval
# shows the seeds' spread; settings whose intervals overlap are not told apart by this sweep.

# %%
table = score_table(jobs, keys)
write_atomic(OUT / "sweep.csv", lambda tmp: table.to_csv(tmp, index=False))
# Settings as the command line gives them (markdown() rounds numbers to 3 digits: 3e-4 would read 0.000).
shown = table.assign(**{k: table[k].map(lambda v: f"{v:.4g}" if isinstance(v, float) else str(v)) for k in keys})
report = markdown(shown.set_index(keys) if keys else shown)
try:
    curves = validation_curves(SWEEP, jobs)
except ValueError as err:
    cli.stop(str(err))
if curves.random_found_fraction.notna().any():  # the same validation worlds in every job of a sweep over algo.*
    levels = curves.random_found_fraction.dropna().unique()
    report += f"\nRandom walk on the validation worlds: {', '.join(f'{v:.3f}' for v in sorted(levels))}\n"
results = SWEEP / "optimization_results.yaml"  # an Optuna sweep's best trial (hydra-optuna-sweeper writes it)
if results.is_file():
    best = yaml.safe_load(results.read_text())
    if "best_value" in best:
        report += f"\nOptuna's best trial: {best['best_params']} with score {best['best_value']:.4f}\n"
write_text_atomic(OUT / "sweep.md", report)
print(report)

# %% [markdown]
# ## Validation curves by setting

# %%
curves = curves.merge(jobs[["job", *keys]], on="job")
fig, ax = plt.subplots(figsize=(6.5, 4.0))
for index, (key, group) in enumerate(curves.groupby(keys, sort=False) if keys else [("all", curves)]):
    values = key if isinstance(key, tuple) else (key,)
    label = ", ".join(f"{k}={v}" for k, v in zip(keys, values, strict=True)) if keys else ""
    color = f"C{index % 10}"
    for _, seed in group.groupby("job"):
        ax.plot(seed.step, seed.found_fraction, color=color, alpha=0.25, linewidth=0.8)
    mean = group.groupby("step", as_index=False).found_fraction.mean()
    ax.plot(mean.step, mean.found_fraction, color=color, linewidth=2, label=label or "all jobs")
ax.set(xlabel="agent-steps", ylabel="validation found fraction", title=f"sweep {SWEEP.name}")
ax.legend(fontsize=7)
fig.tight_layout()
write_atomic(OUT / "sweep_curves.png", lambda tmp: fig.savefig(tmp, dpi=120, format="png"))
print(f"wrote {OUT / 'sweep.md'}, {OUT / 'sweep.csv'}, {OUT / 'sweep_curves.png'}")
