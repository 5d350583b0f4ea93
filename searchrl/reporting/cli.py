"""Command lines of the notebooks in `analysis/`: `python analysis/<script>.py [DIR ...] [--out DIR]`.

Positional folders come first; without them the environment variable (SEARCHRL_EVAL_DIRS or SEARCHRL_RUN_DIRS,
comma-separated), then the script's default. `--out` falls back to SEARCHRL_ANALYSIS_OUT, then the script's
default. The same files run as Jupyter notebooks, whose kernel is started with its own flags (`-f <connection
file>`, `--HistoryManager.hist_file=...`): those are dropped, so a notebook reads the environment variables.
A folder that is missing or holds no results ends the script with one line naming it, as do folders of other
worlds put side by side (searchrl/evaluate/comparable.py).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq

from searchrl.evaluate.cell_checks import DamagedCell, check_cell
from searchrl.evaluate.comparable import Incomparable
from searchrl.evaluate.comparable import check_comparable as _check_comparable
from searchrl.evaluate.results import cell_files


def parser(description: str, dirs: str | None = "EVAL_DIR", dirs_help: str = "") -> argparse.ArgumentParser:
    """A parser with positional `dirs` (none if None) and `--out`; the script adds its own options."""
    p = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    if dirs:
        p.add_argument("dirs", nargs="*", metavar=dirs, help=dirs_help)
    p.add_argument("--out", metavar="DIR", help="output folder (default: $SEARCHRL_ANALYSIS_OUT, then the script's)")
    p.add_argument("-f", "--f", dest="kernel_connection_file", help=argparse.SUPPRESS)  # a Jupyter kernel's
    return p


def _kernel_flag(arg: str) -> bool:
    """A flag a Jupyter kernel gets (traitlets settings `--Class.name=value`)."""
    return arg.startswith("--") and "." in arg.split("=", 1)[0]


def parse(
    p: argparse.ArgumentParser, argv: Sequence[str] | None = None, rest: bool = False
) -> tuple[argparse.Namespace, list[str]]:
    """(options, the remaining arguments). Arguments `p` does not know are refused (usage and exit 2), except a
    kernel's flags; with `rest` the remaining ones are returned instead (missed_targets.py: Hydra overrides)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args, unknown = p.parse_known_args(argv)
    unknown = [a for a in unknown if not _kernel_flag(a)]
    if unknown and not rest:
        p.error(f"unrecognized arguments: {' '.join(unknown)}")
    return args, unknown


def folders(given: Sequence[str], variable: str, default: Callable[[], list[Path]]) -> list[Path]:
    """The positional folders, else those of `variable` (comma-separated), else `default()`."""
    if given:
        return [Path(d) for d in given]
    from_env = [Path(d) for d in setting(None, variable).split(",") if d]
    return from_env or default()


def setting(given: str | None, variable: str, default: str = "") -> str:
    """A notebook's option: the command line's, else the environment variable `variable` (what a notebook kernel
    reads: it takes no arguments), else `default`. The one place a script reads the environment."""
    return given or os.environ.get(variable) or default


def out_dir(given: str | None, default: Path) -> Path:
    """`--out`, else SEARCHRL_ANALYSIS_OUT, else `default`; a script stops in one line where it cannot be a folder."""
    out = Path(setting(given, "SEARCHRL_ANALYSIS_OUT") or default)
    blocked = next((p for p in (out, *out.parents) if p.exists() and not p.is_dir()), None)
    if blocked is not None:
        stop(f"--out={str(out)!r} is not allowed: {blocked} is a file, not a folder; give a folder for the tables")
    return out


def stop(message: str) -> None:
    """End the script with one line on stderr, exit status 1."""
    sys.exit(f"error: {message}")


def check_eval_dirs(dirs: Sequence[Path], min_dirs: int = 1) -> None:
    """Stop, naming the folder, unless every one of `dirs` exists and holds `cells/*.parquet`, and there are at
    least `min_dirs` of them."""
    if not dirs and min_dirs == 1:
        stop(
            "no evaluation folders given and none with results under runs/eval/: pass EVAL_DIR ... (folders "
            "written by `python -m searchrl.evaluate`) or set SEARCHRL_EVAL_DIRS"
        )
    if len(dirs) < min_dirs:
        stop(
            f"{len(dirs)} evaluation folders given, {min_dirs} or more needed: pass EVAL_DIR EVAL_DIR ... or set "
            "SEARCHRL_EVAL_DIRS (comma-separated)"
        )
    for d in dirs:
        if not d.is_dir():
            stop(f"evaluation folder {str(d)!r} does not exist")
        if not cell_files(d):
            stop(
                f"evaluation folder {str(d)!r} holds no results (no cells/*.parquet): run "
                f"`python -m searchrl.evaluate ... out_dir={d}` first"
            )
        for cell in cell_files(d):  # a damaged file named here, not as pyarrow's traceback halfway through a notebook
            try:
                pq.read_metadata(cell)
            except Exception as err:  # pyarrow's errors for a damaged file have no common base but Exception
                stop(
                    f"{cell} cannot be read as a cell's results ({type(err).__name__}); remove it and rerun the "
                    f"evaluation into {d} to write it again"
                )
            try:  # and every row one an episode can have (searchrl/evaluate/cell_checks.py), before any output
                check_cell(pd.read_parquet(cell), cell)
            except DamagedCell as err:
                stop(str(err))


def check_comparable(dirs: Sequence[Path]) -> None:
    """Stop, naming both folders and what differs, unless every one of `dirs` holds results of the same worlds."""
    try:
        _check_comparable(dirs)
    except Incomparable as err:
        stop(str(err))


def check_run_dirs(dirs: Sequence[Path]) -> None:
    """Stop, naming the folder, unless every one of `dirs` holds a training log progress.csv (and there is one)."""
    if not dirs:
        stop(
            "no run folders given and none with a progress.csv under runs/train/: pass RUN_DIR ... "
            "(folders written by `python -m searchrl.train`) or set SEARCHRL_RUN_DIRS"
        )
    for d in dirs:
        if not d.is_dir():
            stop(f"run folder {str(d)!r} does not exist")
        if not (d / "progress.csv").is_file():
            stop(f"run folder {str(d)!r} has no progress.csv (not a run of `python -m searchrl.train`?)")


def with_results(root: Path) -> list[Path]:
    """Every folder directly under `root` with a cells/ folder, sorted (the scripts' default inputs)."""
    return sorted(p for p in root.glob("*") if (p / "cells").is_dir())


def eval_inputs(
    description: str,
    default_out: Path,
    default_dirs: Callable[[], list[Path]] | None = None,
    min_dirs: int = 1,
    argv: Sequence[str] | None = None,
) -> tuple[list[Path], Path]:
    """(evaluation folders, output folder) of `python analysis/<script>.py [EVAL_DIR ...] [--out DIR]`: the folders
    given, else $SEARCHRL_EVAL_DIRS, else `default_dirs()` (every folder under runs/eval/ with results); checked
    (`check_eval_dirs`)."""
    p = parser(
        description,
        "EVAL_DIR",
        "evaluation folders (default: $SEARCHRL_EVAL_DIRS, comma-separated, then "
        "every folder under runs/eval/ with results)",
    )
    dirs, out, _ = eval_args(p, default_out, default_dirs, min_dirs, argv)
    return dirs, out


def eval_args(
    p: argparse.ArgumentParser,
    default_out: Path,
    default_dirs: Callable[[], list[Path]] | None = None,
    min_dirs: int = 1,
    argv: Sequence[str] | None = None,
) -> tuple[list[Path], Path, argparse.Namespace]:
    """`eval_inputs` with a parser the script made (`parser(...)` plus its own options): also its parsed options."""
    args, _ = parse(p, argv)
    default = default_dirs or (lambda: with_results(Path.cwd() / "runs" / "eval"))
    dirs = folders(args.dirs, "SEARCHRL_EVAL_DIRS", default)
    check_eval_dirs(dirs, min_dirs)
    check_comparable(dirs)  # every script puts its folders side by side
    return dirs, out_dir(args.out, default_out), args


def run_inputs(description: str, default_out: Path, argv: Sequence[str] | None = None) -> tuple[list[Path], Path]:
    """(run folders, output folder) of `python analysis/<script>.py [RUN_DIR ...] [--out DIR]`: the folders given,
    else $SEARCHRL_RUN_DIRS, else every run under runs/train/<model>/ with a progress.csv; each checked."""
    p = parser(
        description,
        "RUN_DIR",
        "training run folders (default: $SEARCHRL_RUN_DIRS, comma-separated, then "
        "every run under runs/train/ with a progress.csv)",
    )
    args, _ = parse(p, argv)
    default = lambda: sorted(f.parent for f in (Path.cwd() / "runs" / "train").glob("*/*/progress.csv"))  # noqa: E731
    dirs = folders(args.dirs, "SEARCHRL_RUN_DIRS", default)
    check_run_dirs(dirs)
    return dirs, out_dir(args.out, default_out)
