"""Where the checkout is: the one place the repository root is computed (conf/ beside the package, runs/ under it)."""

from __future__ import annotations

from pathlib import Path


def repository_root() -> Path:
    """The checkout searchrl runs from: the folder holding `searchrl/` and `conf/`."""
    return Path(__file__).resolve().parents[1]


CONF_DIR = repository_root() / "conf"  # Hydra's config folder of every app


def group_options(group: str) -> list[str]:
    """The options of config group `group`: conf/<group>/**/*.yaml as `<group>=` names them (`term/b`)."""
    folder = CONF_DIR / group
    return sorted(p.relative_to(folder).with_suffix("").as_posix() for p in folder.rglob("*.yaml"))


def recipes() -> list[str]:
    """The training recipes, `+experiment=<name>`: conf/experiment/<name>.yaml, subfolders by what they make
    (`term/b` makes runs/reference/term/b, `clone/b` the clone runs/reference/b; `research/` ships nothing)."""
    return group_options("experiment")
