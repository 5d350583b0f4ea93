# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Which modules a training crosses: a trace of the calls from the command line to model.zip
#
# Runs `python -m searchrl.train` in this process on the command line given (a recipe with a small budget by
# default) under `sys.setprofile`, and counts the searchrl modules whose code was called (their import too), with
# their source lines and how many functions of their own each ran beyond its import (the modules a reader of the run
# follows; a module's and a class's body run on import). Written to `module_trace.md`. Run from the repository root:
#
#     python analysis/module_trace.py [--out DIR] [--root CHECKOUT] [OVERRIDE ...]
#
# (default overrides: `+experiment=term/b total_timesteps=12288 validation.every=0 progress_bar=false threads=1`,
# into a temporary run folder). `--root` traces the searchrl of another checkout (e.g. a `git worktree` of an older
# commit), so two commits are measured the same way: nothing of searchrl is imported before the trace.

# %%
import argparse
import inspect
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path.cwd()
parser = argparse.ArgumentParser(description="The searchrl modules a training calls into")
parser.add_argument("--out", type=Path, default=HERE / "analysis" / "out" / "module_trace", help="output folder")
parser.add_argument("--root", type=Path, default=HERE, help="the checkout whose searchrl is traced (default: here)")
parser.add_argument("overrides", nargs=argparse.REMAINDER, help="the training's overrides")
args = parser.parse_args()
ROOT, OUT = args.root.resolve(), args.out.resolve()
if not (ROOT / "searchrl" / "train").is_dir():
    sys.exit(f"error: --root={args.root} is not allowed: a checkout of this repository (no searchrl/train/ there)")
OVERRIDES = args.overrides or [
    "+experiment=term/b",
    "total_timesteps=12288",
    "validation.every=0",
    "progress_bar=false",
    "threads=1",
]
sys.path.insert(0, str(ROOT))  # the traced checkout's searchrl first; its conf/ and runs/ from its root
os.chdir(ROOT)

# %%
called: dict[str, int] = {}
functions: dict[str, set[str]] = {}  # the functions of its own source a module ran, besides its import


def profile(frame, event, arg):
    if event == "call":
        name = frame.f_globals.get("__name__", "")
        if name.startswith("searchrl."):
            called[name] = called.get(name, 0) + 1
            code = frame.f_code
            # A module's body and its classes' bodies run on import (their code is not CO_OPTIMIZED, a function's
            # is); dataclasses' generated methods have no file of their own
            if code.co_flags & inspect.CO_OPTIMIZED and not code.co_filename.startswith("<"):
                functions.setdefault(name, set()).add(code.co_qualname)


with tempfile.TemporaryDirectory() as run:
    argv = ["searchrl.train", *OVERRIDES, f"hydra.run.dir={run}"]
    sys.argv = argv
    import runpy

    sys.setprofile(profile)
    try:
        runpy.run_module("searchrl.train", run_name="__main__")
    except SystemExit as stop:
        if stop.code not in (0, None):
            sys.setprofile(None)
            sys.exit(f"error: the training ended with status {stop.code}")
    finally:
        sys.setprofile(None)

# Back to this checkout: its searchrl writes the report (the traced one may be another commit's)
for name in [m for m in sys.modules if m == "searchrl" or m.startswith("searchrl.")]:
    del sys.modules[name]
sys.path.remove(str(ROOT))
os.chdir(HERE)
import pandas as pd  # noqa: E402

from searchrl.atomic import write_text_atomic  # noqa: E402
from searchrl.reporting.stats import markdown  # noqa: E402

# %%

rows = []
for name, calls in sorted(called.items()):
    path = ROOT / (name.replace(".", "/") + ".py")
    if not path.exists():
        path = ROOT / name.replace(".", "/") / "__init__.py"
    lines = len(path.read_text().splitlines()) if path.exists() else 0
    rows.append({"module": name, "calls": calls, "functions": len(functions.get(name, ())), "lines": lines})
table = pd.DataFrame(rows).sort_values("module").set_index("module")
# the package's layer of each module (searchrl.world, envs, policies, controllers, train, the top level)
table.insert(
    0,
    "layer",
    [m.split(".")[1] if (ROOT / "searchrl" / m.split(".")[1]).is_dir() else "top level" for m in table.index],
)
layers = table.groupby("layer").agg(modules=("lines", "size"), lines=("lines", "sum"))
followed = table[table.functions > 0]  # the modules a reader of the run follows: those whose own code ran
outside = followed[followed.layer != "world"]
# The app: what turns a command line into a run (searchrl/train/ and the package's top-level modules), as against
# the parts it builds (world, envs, policies, controllers, imitation)
app = table[table.layer.isin(["train", "top level"])]
commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
report = (
    f"At {commit.stdout.strip() or 'an unknown commit'}, "
    f"`python -m searchrl.train {' '.join(OVERRIDES)}` calls into {len(table)} searchrl modules, "
    f"{int(table.lines.sum())} lines of source ({int(layers.drop('world').modules.sum())} modules and "
    f"{int(layers.drop('world').lines.sum())} lines outside the world). {len(followed)} of them ran a function "
    f"of their own beyond their import ({len(outside)} modules and {int(outside.lines.sum())} lines outside "
    f"the world). The app (searchrl/train/ and the top-level modules) is {len(app)} of them, "
    f"{int(app.lines.sum())} lines; {int((app.functions > 0).sum())} ran a function of their own:"
    f"\n\n{markdown(layers)}\n{markdown(table)}"
)
OUT.mkdir(parents=True, exist_ok=True)
write_text_atomic(OUT / "module_trace.md", report)
print(report)
