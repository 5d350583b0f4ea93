"""The command line before Hydra reads it: what `python -m searchrl.train` checks in `sys.argv` first, and the
one-line refusal (`fail`) every check of the training app uses."""

from __future__ import annotations

from pathlib import Path

from searchrl.multirun import refuse

fail = refuse  # the one-line refusal, exit status 2 (searchrl/multirun.py)


def check_resume_argument(argv: list[str]) -> None:
    """Hydra makes `<resume>/resumed/<date>/` before the app starts: a resume= that is not a folder is named here
    first, in one line, instead of in Hydra's traceback."""
    for arg in argv:
        value = arg.split("=", 1)[1] if arg.startswith("resume=") else "null"
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "'\"":  # quoted for Hydra: a path with spaces
            value = value[1:-1]
        if value != "null" and not (value and Path(value).is_dir()):
            fail(f"{arg} is not allowed: a run folder (with config.yaml and checkpoints/)")
