"""The comparability check (searchrl/evaluate/comparable.py) on folders written by hand: what a folder's worlds are,
which differences refuse, in what words, and what the note says differs by design."""

from __future__ import annotations

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


def test_a_setting_one_side_lacks_is_not_compared_and_the_sensing_label_is():
    ours = identity_of({"seed": 1, "world": {"k": 3.0}}, sensing="bayes")
    assert world_differences(identity_of({"seed": 1}, sensing="bayes"), ours) == []
    assert world_differences(identity_of({"seed": 1}, sensing="paper"), ours) == [("sensing", "paper", "bayes")]
    assert world_differences(identity_of({"seed": 2}), ours) == [("seed", 2, 1)]


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


WALLS = {"obstacles": {"kind": "iid", "density": 0.2, "connected": True}, "prior": {"kind": "mixture"},
         "targets": {"kind": "prior"}}  # fmt: skip


def test_a_recorded_scenario_is_the_folders_and_the_label_of_a_one_row_cell_is_read(tmp_path):
    walls = _folder(tmp_path / "walls", {**RECORD, "scenario": WALLS})
    assert world_identity(walls)["scenario.obstacles.density"] == 0.2
    one = tmp_path / "one"
    (one / "cells").mkdir(parents=True)
    pd.DataFrame({"world": ["paper"]}).to_parquet(one / "cells" / "n20_N1.parquet")
    assert world_identity(one) == {"sensing": "paper"}
    assert comparison_note([walls, _folder(tmp_path / "w2", {**RECORD, "scenario": WALLS})]).startswith(
        "Same worlds in every folder (seed 7, scenario iid0.2c, one grid)"
    )


def test_two_folders_are_compared_and_each_against_the_first(tmp_path):
    first, other = _folder(tmp_path / "first"), _folder(tmp_path / "other", {**RECORD, "seed": 8})
    with pytest.raises(Incomparable, match="seed: 8 in "):
        check_comparable([first, other])
    with pytest.raises(Incomparable, match="seed: 7 in "):
        check_comparable([other, first])


def test_the_note_of_folders_with_no_record_or_no_grid(tmp_path):
    bare, unknown = _folder(tmp_path / "bare", record=None), "Same worlds in every folder (seed ?, scenario paper"
    assert comparison_note([]) == f"{unknown}, one grid); they differ in: nothing recorded"
    assert comparison_note([bare, _folder(tmp_path / "a")]).startswith(unknown)
    repeats = {**RECORD, "grid": {**RECORD["grid"], "repeats": 5}}
    assert comparison_note([_folder(tmp_path / "b"), _folder(tmp_path / "c", repeats)]).endswith(
        "they differ in: maps and repeats (paired on the maps both ran)"
    )
    no_grid = {k: v for k, v in RECORD.items() if k != "grid"}
    note = comparison_note([_folder(tmp_path / "d", no_grid), _folder(tmp_path / "e", no_grid)])
    assert note.endswith("nothing recorded")
