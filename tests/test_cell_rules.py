"""Each rule of the cell check (searchrl/evaluate/cell_checks.py) on hand-made rows, one edit at a time: the first
offending row named with its value and what is allowed, in one line; what an episode can have passes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from searchrl.evaluate.cell_checks import DamagedCell, check_cell

PATH = Path("runs/eval/x/cells/n20_N2.parquet")
NAN = float("nan")


def _rows(**edits) -> pd.DataFrame:
    """Three episodes an evaluation can write (the bound NaN in the last: a scenario whose prior misleads), edited."""
    rows = {
        "n": [20, 20, 20], "N": [2, 2, 2], "targets": [4, 4, 4], "map_seed": [1, 2, 3], "repeat": [0, 0, 1],
        "found_fraction": [0.5, 1.0, 0.0], "L": [40, 12, 256], "F": [0, 3, 0], "M_bar": [0.0, 0.2, 0.1],
        "bound": [2.5, 4.0, NAN], "bound_stderr": [0.1, 0.0, NAN], "bound_fraction": [0.8, 1.0, NAN],
    }  # fmt: skip
    for column, (row, value) in edits.items():
        rows[column] = [value if i == row else v for i, v in enumerate(rows[column])]
    return pd.DataFrame(rows)


def test_rows_an_evaluation_writes_pass_with_or_without_the_optional_columns():
    check_cell(_rows(), PATH)
    check_cell(_rows().drop(columns=["bound", "bound_stderr", "bound_fraction", "F", "M_bar"]), PATH)
    check_cell(_rows(), Path("a_file_of_another_name.parquet"))  # no name to hold n and N to
    check_cell(_rows(found_fraction=(0, 0.25), L=(1, 1)), PATH)  # the bounds themselves are allowed


FF = "found_fraction"
EDITS = {
    "found_fraction=1.25": (dict(found_fraction=(1, 1.25)), "found_fraction=1.25 in row 1 is not allowed ([0.0, 1.0])"),
    "found_fraction=-0.25": (dict(found_fraction=(2, -0.25)), f"{FF}=-0.25 in row 2 is not allowed ([0.0, 1.0])"),
    "found_fraction=nan": (dict(found_fraction=(0, NAN)), "found_fraction=nan in row 0 is not allowed ([0.0, 1.0])"),
    "found_fraction='x'": (dict(found_fraction=(0, "x")), "found_fraction=x in row 0 is not allowed ([0.0, 1.0])"),
    "bound_fraction=1.5": (dict(bound_fraction=(0, 1.5)), "bound_fraction=1.5 in row 0 is not allowed ([0.0, 1.0])"),
    "bound_fraction=inf": (dict(bound_fraction=(0, np.inf)), "bound_fraction=inf in row 0 is not allowed ([0.0, 1.0])"),
    "targets=0": (dict(targets=(1, 0)), "targets=0 in row 1 is not allowed (>= 1)"),
    "L=0": (dict(L=(2, 0)), "L=0 in row 2 is not allowed (>= 1)"),
    "F=-1": (dict(F=(0, -1)), "F=-1 in row 0 is not allowed (>= 0)"),
    "M_bar=-0.1": (dict(M_bar=(1, -0.1)), "M_bar=-0.1 in row 1 is not allowed (>= 0.0)"),
    "bound=-1": (dict(bound=(0, -1.0)), "bound=-1.0 in row 0 is not allowed (>= 0.0)"),
    "bound_stderr=-1": (dict(bound_stderr=(0, -1.0)), "bound_stderr=-1.0 in row 0 is not allowed (>= 0.0)"),
    "repeat=-1": (dict(repeat=(0, -1)), "repeat=-1 in row 0 is not allowed (>= 0)"),
    "0.3 of 4 targets": (dict(found_fraction=(1, 0.3)), f"{FF}=0.3 in row 1 is no whole number of its 4 targets"),
    "n=40": (dict(n=(1, 40)), "row 1 has n=40, N=2, not its name's"),
    "N=3": (dict(N=(2, 3)), "row 2 has n=20, N=3, not its name's"),
    "an episode twice": (dict(map_seed=(1, 1)), "row 1 repeats map_seed 1, repeat 0"),
}  # fmt: skip


@pytest.mark.parametrize("edit", EDITS)
def test_each_rule_names_the_first_row_that_breaks_it(edit):
    change, words = EDITS[edit]
    with pytest.raises(DamagedCell) as err:
        check_cell(_rows(**change), PATH)
    assert str(err.value) == f"{PATH}: {words}: the cell is damaged; remove it and rerun the evaluation into its folder"


def test_a_cell_of_no_rows_is_refused_naming_it():
    with pytest.raises(DamagedCell) as err:
        check_cell(_rows().iloc[:0], PATH)
    tail = "the cell is damaged; remove it and rerun the evaluation into its folder"
    assert str(err.value) == f"{PATH}: it holds no episode: {tail}"


def test_the_same_map_in_another_repeat_is_no_duplicate():
    check_cell(_rows(map_seed=(2, 1)), PATH)  # rows 0 and 2: map 1 in repeats 0 and 1


def test_a_missing_column_skips_its_own_rule_only():
    refused = {"L=0 without bound_fraction": _rows(L=(1, 0)).drop(columns=["bound_fraction", "F"]),
               "n=40 without N's neighbours": _rows(n=(0, 40))[["n", "N"]],
               "an episode twice alone": _rows(map_seed=(1, 1))[["map_seed", "repeat"]]}  # fmt: skip
    for frame in refused.values():
        with pytest.raises(DamagedCell):
            check_cell(frame, PATH)
    check_cell(_rows().drop(columns=["targets"]), PATH)  # no whole-number rule without the targets
    check_cell(_rows(n=(0, 40)).drop(columns=["N"]), PATH)  # nor a name rule without both n and N
    check_cell(_rows(N=(0, 3)).drop(columns=["n"]), PATH)
