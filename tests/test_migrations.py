"""searchrl/migrations.py: a record of each older form is upgraded once on read, a current one passes unchanged,
and the readers (a checkpoint's run config, a resumed run's) see only the current form."""

from __future__ import annotations

import shutil
from pathlib import Path

from omegaconf import OmegaConf

from searchrl.migrations import RUN_CONFIG_UPGRADES, reward_node, upgrade_run_config
from searchrl.policies.checkpoint import run_config
from searchrl.train.schema import saved_config
from tests.registries import isolated_registries

ROOT = Path(__file__).resolve().parents[1]
LAB_RUN = ROOT / "runs" / "lab" / "own_kl05_b"  # a run made when a reward was a name: `reward: own_found`


def test_a_reward_given_by_name_becomes_its_node_and_a_current_record_passes_unchanged():
    assert reward_node({"seed": 1, "reward": "paper"}) == {"seed": 1, "reward": {"name": "paper"}}
    current = {"seed": 1, "reward": {"name": "found_only", "weight": 2.0}}
    assert upgrade_run_config(current) == current and upgrade_run_config({"seed": 1}) == {"seed": 1}
    assert upgrade_run_config(upgrade_run_config({"reward": "paper"})) == {"reward": {"name": "paper"}}
    assert reward_node in RUN_CONFIG_UPGRADES


def test_the_readers_of_a_run_see_the_upgraded_record(tmp_path):
    assert OmegaConf.load(LAB_RUN / "config.yaml").reward == "own_found"  # the file as it was written
    run = tmp_path / "run"
    (run / "checkpoints").mkdir(parents=True)
    shutil.copy(LAB_RUN / "config.yaml", run / "config.yaml")
    (run / "model.zip").write_bytes(b"")
    assert OmegaConf.to_container(run_config(run / "model.zip").reward) == {"name": "own_found"}
    with isolated_registries("analysis"):  # it imports the run's extensions (analysis.team_reward), as resume does
        saved = saved_config(run / "config.yaml")
    assert OmegaConf.to_container(saved.reward) == {"name": "own_found"}
    assert OmegaConf.load(run / "config.yaml").reward == "own_found"  # read, never rewritten


def test_a_cell_made_before_the_world_and_scenario_columns_gains_them():
    import pandas as pd

    from searchrl.migrations import upgrade_cell

    old = pd.DataFrame({"controller": ["surfing"], "model": ["b"], "n": [20], "found_fraction": [0.5]})
    asked = []
    new = upgrade_cell(old.copy(), lambda: asked.append(1) or "k=1")
    assert list(new.columns[:4]) == ["controller", "model", "world", "scenario"] and asked == [1]
    assert (new.world == "k=1").all() and (new.scenario == "paper").all()
    current = new.copy()
    assert upgrade_cell(current, lambda: asked.append(2) or "other").equals(new) and asked == [1]  # not read again
