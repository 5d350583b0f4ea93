"""Every cell validated on read (searchrl/evaluate/cell_checks.py): an edited or damaged cell is refused in one line
by `load` and by every analysis script before any output, never summarised; an intact folder loads as before."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest

from searchrl.evaluate.cell_checks import DamagedCell, check_cell
from searchrl.evaluate.results import load
from tests.scripts import run_script
from tests.test_faults import _evaluate

pytestmark = pytest.mark.app  # runs an evaluation: not in the fast layer (docs/testing.md)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """An evaluation of surfing on the tiny slice (n20, N1-2, 4 targets, 2 maps)."""
    return _evaluate(tmp_path_factory.mktemp("cells") / "surfing", "controller=surfing")


def _edited(folder, tmp_path, edit) -> tuple:
    copy = shutil.copytree(folder, tmp_path / folder.name)
    cell = sorted((copy / "cells").glob("*.parquet"))[-1]
    frame = pd.read_parquet(cell)
    edit(frame)
    frame.to_parquet(cell)
    return copy, cell


def _first(column: str, value):
    """An edit setting row 0's `column` to `value`."""
    return lambda frame: frame.__setitem__(column, [value, *frame[column].iloc[1:]])


EDITS = {
    "found_fraction=1.5": (_first("found_fraction", 1.5), r"\[0.0, 1.0\]"),
    "found_fraction=-2.0": (_first("found_fraction", -2.0), r"\[0.0, 1.0\]"),
    "found_fraction=0.3": (_first("found_fraction", 0.3), "no whole"),
    "L=0": (_first("L", 0), ">= 1"),
    "n=40": (lambda frame: frame.__setitem__("n", 40), "not its name's"),
    "row twice": (lambda frame: frame.__setitem__("map_seed", frame.map_seed.iloc[0]), "repeats map_seed"),
}


def test_an_intact_folder_loads_and_every_cell_passes(folder):
    frame = load(folder)
    assert len(frame) == 2 * 2  # two cells of two maps
    for cell in (folder / "cells").glob("*.parquet"):
        check_cell(pd.read_parquet(cell), cell)


@pytest.mark.parametrize("edit", EDITS)
def test_an_edited_cell_is_refused_in_one_line_naming_it(folder, tmp_path, capsys, edit):
    change, words = EDITS[edit]
    copy, cell = _edited(folder, tmp_path, change)
    with pytest.raises(DamagedCell, match=words) as err:
        load(copy)
    message = str(err.value)
    assert "\n" not in message and message.startswith(str(cell)) and "rerun the evaluation" in message
    out = tmp_path / "out"
    result = run_script("compare.py", str(copy), str(folder), "--out", str(out))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert result.stderr.strip().splitlines()[-1].startswith(f"error: {cell}") and not out.exists()


def test_an_empty_cell_is_refused(tmp_path):
    with pytest.raises(DamagedCell, match="holds no episode"):
        check_cell(pd.DataFrame({"found_fraction": []}), tmp_path / "n20_N1.parquet")
