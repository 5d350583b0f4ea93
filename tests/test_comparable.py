"""Like with like (searchrl/evaluate/comparable.py): folders of other worlds are never put side by side. Every
analysis script that reads two or more evaluation folders, given a pair that differs in one world setting, refuses
in one line naming both folders and the setting, and writes nothing; given a damaged cell it refuses likewise; on
folders of the same worlds it runs and its table's head says what differs by design."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest
import yaml

from searchrl.evaluate.comparable import (
    GRID_KEYS,
    Incomparable,
    check_comparable,
    comparison_note,
    identity_of,
    world_differences,
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


def test_a_setting_one_side_lacks_is_not_compared_and_the_sensing_label_is():
    ours = identity_of({"seed": 1, "world": {"k": 3.0}}, sensing="bayes")
    assert world_differences(identity_of({"seed": 1}, sensing="bayes"), ours) == []
    assert world_differences(identity_of({"seed": 1}, sensing="paper"), ours) == [("sensing", "paper", "bayes")]
    assert world_differences(identity_of({"seed": 2}), ours) == [("seed", 2, 1)]


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


# Folders written by hand: the check read without an evaluation behind it.
RECORD = {
    "controller": "greedy",
    "model": "b",
    "seed": 7,
    "grid": {"world_sizes": [20], "n_targets": [4], "n_distributions": [8], "max_agents": [2], "agents": None,
             "maps_per_cell": 2, "repeats": 1},
    "world": {"k": 1000.0, "lam": 0.001, "fov": 11, "communication": True},
}  # fmt: skip


def _folder(path, record=RECORD, sensing="bayes"):
    (path / "cells").mkdir(parents=True)
    if record is not None:
        (path / "evaluation.yaml").write_text(record if isinstance(record, str) else yaml.safe_dump(record))
    if sensing is not None:
        rows = pd.DataFrame({"world": [sensing, sensing], "found_fraction": [0.5, 1.0]})
        rows.to_parquet(path / "cells" / "n20_N1.parquet")
    return path


def test_the_identity_holds_the_worlds_and_nothing_of_the_player(tmp_path):
    identity = world_identity(_folder(tmp_path / "a"))
    assert identity["seed"] == 7 and identity["sensing"] == "bayes" and identity["world.k"] == 1000.0
    assert {f"grid.{key}" for key in GRID_KEYS} <= identity.keys()
    assert not {"grid.maps_per_cell", "grid.repeats", "grid.agents", "world.fov", "world.communication",
                "controller", "model"} & identity.keys()  # fmt: skip
    assert identity["scenario.obstacles.kind"] == "iid"  # no scenario recorded: the paper's
    assert world_identity(_folder(tmp_path / "bare", record=None)) == {"sensing": "bayes"}
    assert world_identity(_folder(tmp_path / "bad", record="- a list\n")) == {"sensing": "bayes"}
    assert world_identity(_folder(tmp_path / "no_cells", sensing=None)) == {k: v for k, v in identity.items()
                                                                          if k != "sensing"}  # fmt: skip


def test_one_folder_is_comparable_and_the_message_names_each_side_with_its_value(tmp_path):
    first = _folder(tmp_path / "first")
    check_comparable([first])
    check_comparable([first, _folder(tmp_path / "same", {**RECORD, "controller": "coverage"})])
    other = _folder(tmp_path / "other", {**RECORD, "seed": 8}, sensing="paper")
    with pytest.raises(Incomparable) as err:
        check_comparable([first, tmp_path / "same", other])
    assert str(err.value).startswith(
        f"{other} and {first} hold results of other worlds (seed: 8 in {other}, 7 in {first}; sensing: 'paper' in "
        f"{other}, 'bayes' in {first}): a map seed names one map only under the same seed"
    )


def test_the_note_names_what_differs_by_design_in_the_records_order(tmp_path):
    first = _folder(tmp_path / "first")
    more = {**RECORD, "controller": "policy:x", "inference": "onnx", "grid": {**RECORD["grid"], "maps_per_cell": 9}}
    note = comparison_note([first, _folder(tmp_path / "second", more)])
    assert note == ("Same worlds in every folder (seed 7, scenario paper, one grid); they differ in: controller, "
                    "maps and repeats (paired on the maps both ran)")  # fmt: skip
    third = _folder(tmp_path / "third", {**more, "inference": "torch"})
    assert comparison_note([tmp_path / "second", third]).endswith("they differ in: inference")
