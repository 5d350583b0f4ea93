"""Running an analysis script in the test process, as `python analysis/<script>.py args` runs it."""

from __future__ import annotations

import contextlib
import io
import os
import runpy
import subprocess
import sys
import traceback
from pathlib import Path
from unittest import mock

from tests.registries import isolated_registries

ROOT = Path(__file__).resolve().parents[1]


def run_script(notebook: str, *args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    """Run analysis/<notebook> as `python analysis/<notebook> args` does, with none of the SEARCHRL_* variables but
    those of `env`, in this process (the ~2 s of imports a new interpreter pays, saved): its exit status, stdout and
    stderr, an uncaught exception's traceback in stderr with status 1."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SEARCHRL_")} | {"MPLBACKEND": "Agg"} | (env or {})
    out, err, code = io.StringIO(), io.StringIO(), 0
    # a script may register parts for its process (analysis/oracle_teacher.py a teacher): the registries are restored
    with (isolated_registries(), mock.patch.dict(os.environ, env, clear=True),
          mock.patch.object(sys, "argv", [notebook, *args]), contextlib.chdir(ROOT),
          contextlib.redirect_stdout(out), contextlib.redirect_stderr(err)):  # fmt: skip
        try:
            runpy.run_path(str(ROOT / "analysis" / notebook), run_name="__main__")
        except SystemExit as stop:  # as the interpreter reports it: a message is printed, status 1
            code = stop.code if isinstance(stop.code, int) else 0 if stop.code is None else 1
            if isinstance(stop.code, str):
                print(stop.code, file=err)
        except Exception:
            traceback.print_exc(file=err)
            code = 1
        finally:  # a notebook's figures stay open for its display; this process runs many notebooks
            if "matplotlib.pyplot" in sys.modules:
                sys.modules["matplotlib.pyplot"].close("all")
    return subprocess.CompletedProcess([notebook, *args], code, out.getvalue(), err.getvalue())
