"""Like with like (searchrl/evaluate/comparable.py): folders of other worlds are never put side by side. Every
analysis script that reads two or more evaluation folders, given a pair that differs in one world setting, refuses
in one line naming both folders and the setting, and writes nothing; given a damaged cell it refuses likewise; on
folders of the same worlds it runs and its table's head says what differs by design."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest

from searchrl.evaluate.comparable import (
    Incomparable,
    check_comparable,
    comparison_note,
    world_identity,
)
from tests.scripts import run_script
from tests.test_faults import _evaluate

pytestmark = pytest.mark.app  # runs evaluations: not in the fast layer (docs/testing.md)

# One world setting changed at a time: each names other maps (or other sensing) under the same map seeds.
OTHER_WORLDS = {
    "seed=5": "seed",
    "scenario=walls": "scenario.obstacles",
    "grid.n_targets=[2]": "grid.n_targets",
    "grid.n_distributions=[4]": "grid.n_distributions",
    "env.world.k=3": "world.k",
    "env.world.prob_variance_scale=5": "world.prob_variance_scale",
}
# Every script that puts folders side by side, with the arguments after the folders.
SCRIPTS = {
    "compare.py": [],
    "report.py": [],
    "beyond.py": [],
    "table3.py": [],
    "figures.py": [],
    "claims.py": [],
}


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """surfing and coverage on the tiny slice (the same worlds), and surfing in each of OTHER_WORLDS."""
    root = tmp_path_factory.mktemp("comparable")
    made = {
        "surfing": _evaluate(root / "surfing", "controller=surfing"),
        "coverage": _evaluate(root / "coverage", "controller=coverage"),
    }
    for i, override in enumerate(OTHER_WORLDS):
        made[override] = _evaluate(root / f"other{i}", "controller=surfing", override)
    return made


@pytest.mark.parametrize("override", OTHER_WORLDS)
def test_folders_of_other_worlds_are_incomparable_naming_both_and_the_setting(folders, override):
    with pytest.raises(Incomparable) as err:
        check_comparable([folders["surfing"], folders[override]])
    message = str(err.value)
    assert "\n" not in message and OTHER_WORLDS[override] in message
    assert str(folders["surfing"]) in message and str(folders[override]) in message


def test_folders_of_the_same_worlds_are_comparable_and_the_note_says_what_differs(folders):
    check_comparable([folders["surfing"], folders["coverage"]])
    note = comparison_note([folders["surfing"], folders["coverage"]])
    assert "seed 7000000" in note and note.endswith("they differ in: controller")
    assert comparison_note([folders["surfing"], folders["surfing"]]).endswith("nothing recorded")


def test_a_folder_written_before_scenarios_were_recorded_ran_the_papers(folders, tmp_path):
    copy = shutil.copytree(folders["surfing"], tmp_path / "old")
    record = (copy / "evaluation.yaml").read_text()
    (copy / "evaluation.yaml").write_text(record.split("scenario:")[0] + "world:" + record.split("\nworld:")[1])
    assert world_identity(copy) == world_identity(folders["surfing"])
    with pytest.raises(Incomparable, match=r"scenario\.obstacles"):
        check_comparable([copy, folders["scenario=walls"]])


@pytest.mark.parametrize("script", SCRIPTS)
@pytest.mark.parametrize("override", OTHER_WORLDS)
def test_every_script_refuses_folders_of_other_worlds_in_one_line_before_output(folders, tmp_path, script, override):
    out = tmp_path / "out"
    mine, theirs = folders["surfing"], folders[override]
    result = run_script(script, str(mine), str(theirs), *SCRIPTS[script], "--out", str(out))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    line = result.stderr.strip().splitlines()[-1]
    assert line.startswith(f"error: {theirs} and {mine} hold results of other worlds")
    assert OTHER_WORLDS[override] in line
    assert not out.exists()


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_script_refuses_a_damaged_cell_in_one_line_before_output(folders, tmp_path, script):
    copy = shutil.copytree(folders["coverage"], tmp_path / "coverage")
    cell = sorted((copy / "cells").glob("*.parquet"))[-1]
    frame = pd.read_parquet(cell)
    frame["found_fraction"] = 1.5
    frame.to_parquet(cell)
    out = tmp_path / "out"
    result = run_script(script, str(folders["surfing"]), str(copy), *SCRIPTS[script], "--out", str(out))
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert result.stderr.strip().splitlines()[-1].startswith(f"error: {cell}") and not out.exists()


def test_compare_on_the_same_worlds_writes_its_table_under_the_note(folders, tmp_path):
    out = tmp_path / "out"
    result = run_script("compare.py", str(folders["surfing"]), str(folders["coverage"]), "--out", str(out))
    assert result.returncode == 0, result.stderr[-2000:]
    lines = (out / "compare.md").read_text().splitlines()
    assert lines[0] == "# surfing against coverage" and lines[2].endswith("they differ in: controller")
    assert lines[4] == "## surfing − coverage"


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_script_runs_on_folders_of_the_same_worlds(folders, tmp_path, script):
    out = tmp_path / "out"
    result = run_script(script, str(folders["surfing"]), str(folders["coverage"]), *SCRIPTS[script], "--out", str(out))
    assert result.returncode == 0 and "error:" not in result.stderr, result.stderr[-2000:]
    assert any(out.iterdir())
