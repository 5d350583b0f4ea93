"""Where the checkout is: the one place the repository root is computed (conf/ beside the package, runs/ under it)."""

from __future__ import annotations

from pathlib import Path


def repository_root() -> Path:
    """The checkout searchrl runs from: the folder holding `searchrl/` and `conf/`."""
    return Path(__file__).resolve().parents[1]


CONF_DIR = repository_root() / "conf"  # Hydra's config folder of every app
