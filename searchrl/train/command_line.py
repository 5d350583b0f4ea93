"""The command line before Hydra reads it: what `python -m searchrl.train` checks and adds to `sys.argv` first,
and the one-line refusal (`fail`) every check of the training app uses."""

from __future__ import annotations

import sys
from pathlib import Path


def fail(message: str) -> None:
    """Name the bad value and what is allowed, in one line on stderr, and exit with status 2 (before any work)."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def check_resume_argument(argv: list[str]) -> None:
    """Hydra makes `<resume>/resumed/<date>/` before the app starts: a resume= that is not a folder is named here
    first, in one line, instead of in Hydra's traceback."""
    for arg in argv:
        value = arg.split("=", 1)[1] if arg.startswith("resume=") else "null"
        if value != "null" and not (value and Path(value).is_dir()):
            fail(f"{arg} is not allowed: a run folder (with config.yaml and checkpoints/)")


def recipe_arguments(argv: list[str]) -> list[str]:
    """The command line as Hydra gets it. conf/train.yaml picks the recipe by the model (`optional recipe:
    ${model}`), which Hydra cannot resolve when no model is chosen: such a command line (a resume, whose model is in
    its saved config; `--help`; a missing model, which check_model then names) gets `recipe=paper`, the paper's
    values. A model's recipe fine-tunes its shipped clone and so fixes the network: `network=` with it is refused."""
    keys = {arg.split("=", 1)[0].lstrip("+") for arg in argv if "=" in arg and not arg.startswith("-")}
    if "network" in keys and "model" in keys and not keys & {"recipe", "experiment"}:
        fail("network= does not apply to a model's recipe (conf/recipe/<model>.yaml), which starts from the shipped "
             "clone and so has its network: add recipe=paper to train another network from scratch")  # fmt: skip
    if keys & {"model", "experiment", "recipe"}:
        return argv
    return [*argv, "recipe=paper"]
