"""`extensions=`: a package outside searchrl (tests/extension_example/) registers an observation part and a network
that reads it, a heuristic and an obstacle law with a scenario, and the apps train, evaluate and sweep with them
from the command line, as a user would; nothing in searchrl names them."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from searchrl.command_line import from_command_line

pytestmark = pytest.mark.app  # runs the apps as commands

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "tests.extension_example"
TINY = ["+model=b", "total_timesteps=512", "env.n_worlds=2", "env.world.n_agents=4", "env.world.world_size=[12,20]",
        "env.world.n_targets=[2,4]", "env.world.n_distributions=[4,8]", "network=small", "algo.batch_size=128",
        "checkpoint_every=512", "validation.every=0", "validation.n_worlds=2", "progress_bar=false",
        "threads=1"]  # fmt: skip
SLICE = ["grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]", "grid.max_agents=[2]",
         "grid.maps_per_cell=2", "grid.repeats=1", "progress_bar=false", "threads=1", "bound_draws=100",
         "bound_cache=null"]  # fmt: skip


def _app(app: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", f"searchrl.{app}", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)  # fmt: skip


def test_the_command_line_names_the_modules():
    assert from_command_line(["x=1", "extensions=[a.b, 'c']", "+extensions=d"]) == ["a.b", "c", "d"]
    assert from_command_line(["extensions=[]", "extensions=null"]) == []


def test_train_evaluate_and_sweep_with_a_users_parts(tmp_path):
    """Each part with a setting of its own from the command line: the network's width, its observation part's
    scale, the critic's grid (its own copy of the part), the reward's weight and the heuristic's margin; recorded,
    and read back by evaluation."""
    parts = f"extensions=[{PACKAGE}.swept,{PACKAGE}.pillars,{PACKAGE}.found_only]"
    run = tmp_path / "run"
    small = [a for a in TINY if a != "network=small"] + ["network=swept_cnn", "network.conv_channels=[16,32,64]",
             "network.vector_size=16", "network.fc_sizes=[128,128]", "network.lstm_hidden_size=128"]  # fmt: skip
    out = _app("train", *small, parts, "network.width=24", "network.scale=0.5", "scenario=pillars",
               "reward=found_only", "reward.weight=2", "critic=swept_critic", "critic.grid=4",
               f"hydra.run.dir={run}")  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    record = yaml.safe_load((run / "config.yaml").read_text())
    assert record["network"]["extractor"] == "swept_cnn" and record["network"]["width"] == 24
    assert record["critic"] == {"name": "swept_critic", "grid": 4, "scale": 1.0}  # its own copy of the part
    assert record["network"]["scale"] == 0.5 and record["reward"] == {"name": "found_only", "weight": 2.0}
    # its checkpoint needs the same extensions: the folder's word is not enough to import code
    out = _app("evaluate", f"checkpoint={run / 'model.zip'}", *SLICE, f"out_dir={tmp_path / 'bare'}")
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert "network.extractor='swept_cnn' is not allowed" in out.stderr and f"{PACKAGE}.swept" in out.stderr
    assert not (tmp_path / "bare").exists()
    # a width of 24 read back from config.yaml, or its tensors misfit
    out = _app("evaluate", f"checkpoint={run / 'model.zip'}", *SLICE, parts, "scenario=pillars",
               f"out_dir={tmp_path / 'policy'}")  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    rule = _app("evaluate", "controller=eastward", "controller.margin=2", "+model=b", *SLICE, "scenario=pillars",
                f"extensions=[{PACKAGE}.eastward,{PACKAGE}.pillars]", f"out_dir={tmp_path / 'rule'}")  # fmt: skip
    assert rule.returncode == 0, rule.stderr[-2000:]
    assert yaml.safe_load((tmp_path / "rule" / "evaluation.yaml").read_text())["controller_args"]["margin"] == 2
    for folder, controller in (("policy", "policy:run"), ("rule", "eastward")):
        rows = pd.concat(pd.read_parquet(p) for p in (tmp_path / folder / "cells").glob("*.parquet"))
        assert set(rows.controller) == {controller} and set(rows.scenario) == {"pillars4"} and len(rows) == 4


NOT = "is not allowed:"
TYPOS = [  # (app, arguments, what the one line names) for a misspelt name or setting of each kind of part
    ("train", ["network=swept_cn"], f"network=swept_cn {NOT} conf/network/ has no 'swept_cn' (did you mean "
     "network=swept_cnn"),
    ("plan", ["network.extractor=swept_cn"], f"network.extractor='swept_cn' {NOT} one of search_cnn, own_map_cnn, "
     "swept_cnn (did you mean 'swept_cnn'?)"),
    ("train", ["network=swept_cnn", "network.widht=24"], f"network.widht=24 {NOT} no such setting (did you mean "
     "network.width"),
    ("train", ["network=swept_cnn", "network.scael=2"], f"network.scael=2 {NOT} no such setting (did you mean "
     "network.scale"),
    ("train", ["network=swept_cnn", "network.width=wide"], f"network.width=wide {NOT} Value 'wide' of type 'str' "
     "could not be converted to Integer"),
    ("train", ["reward=found_onyl"], f"reward=found_onyl {NOT} no reward 'found_onyl' is registered (did you mean "
     "reward=found_only"),
    ("train", ["reward=found_only", "reward.wieght=2"], f"reward.wieght=2 {NOT} no such setting (did you mean "
     "reward.weight"),
    ("evaluate", ["controller=eastwrd"], f"controller=eastwrd {NOT} conf/controller/ has no 'eastwrd' (did you mean "
     "controller=eastward"),
    ("evaluate", ["controller=eastward", "controller.margn=2"], f"controller.margn=2 {NOT} no such setting (did you "
     "mean controller.margin"),
]  # fmt: skip


def test_a_misspelt_name_or_setting_of_each_kind_is_refused_in_one_line_with_the_nearest(tmp_path):
    """One process runs each command line's checks (the entry points' own, before Hydra): each refused in one line
    naming the value and the nearest name, nothing written."""
    script = (
        "import sys\n"
        "from searchrl.command_line import check_group_choices, check_jobs_compose, import_from_command_line\n"
        "from hydra import compose, initialize_config_dir\n"
        "from searchrl.shared_schema import CONF_DIR\n"
        "from searchrl.train.plan import make_plan\n"
        "from searchrl.world.config import ConfigError\n"
        "from searchrl.train.schema import register_configs as train_configs\n"
        "from searchrl.evaluate.schema import register_configs as evaluate_configs\n"
        f"import_from_command_line(['extensions=[{PACKAGE}.swept,{PACKAGE}.found_only,{PACKAGE}.eastward]'])\n"
        "train_configs(); evaluate_configs()\n"
        f"for app, args in {[(app, args) for app, args, _ in TYPOS]!r}:\n"
        "    argv = ['+model=b', *args]\n"
        "    try:\n"
        "        if app == 'plan':  # a name given as a value: the plan refuses it, before any work\n"
        "            with initialize_config_dir(str(CONF_DIR), version_base='1.3'):\n"
        "                make_plan(compose(config_name='train', overrides=argv))\n"
        "        else:\n"
        "            check_group_choices(argv); check_jobs_compose(argv, app)\n"
        "        print('accepted')\n"
        "    except ConfigError as refused:\n"
        "        print('refused'); print(refused, file=sys.stderr)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
    assert out.stdout.split() == ["refused"] * len(TYPOS), out.stderr[-3000:]
    lines = out.stderr.strip().splitlines()
    assert len(lines) == len(TYPOS)
    for line, (_, _, named) in zip(lines, TYPOS, strict=True):
        assert named in line, line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow  # two more trainings
def test_a_sweep_registers_the_parts_in_every_job(tmp_path):
    parts = f"extensions=[{PACKAGE}.swept,{PACKAGE}.pillars]"
    sweep = _app("train", "-m", *TINY, parts, "network.extractor=swept_cnn", "scenario=pillars", "seed=0,1",
                 "hydra/launcher=joblib", f"hydra.sweep.dir={tmp_path / 'sweep'}")  # fmt: skip
    assert sweep.returncode == 0, sweep.stderr[-2000:]
    assert len(list((tmp_path / "sweep").glob("*/model.zip"))) == 2


def test_a_registered_reward_is_what_the_env_pays():
    """The env pays the reward object's value of each step's result; the world and its metrics are unchanged."""
    import numpy as np

    from searchrl.envs.rewards import RewardConfig, make_reward
    from searchrl.envs.vec_env import SearchVecEnv
    from searchrl.world.config import WorldConfig
    from searchrl.world.engine import SearchWorld
    from tests.extension_example.found_only import FoundOnly

    world = WorldConfig(n_agents=3, world_size=(12, 12), n_targets=(4, 4), n_distributions=(4, 4), max_steps=20)
    env, twin = SearchVecEnv(world, 2, seed=0, reward=FoundOnly()), SearchWorld(world, 2, seed=0)
    env.reset(), twin.reset()
    rng = np.random.default_rng(0)
    found = 0
    for _ in range(50):  # episodes end at 20 steps or sooner: resets included
        actions = rng.integers(0, 5, 6)
        paid = env.step(actions)[1]
        result = twin.step(actions.reshape(2, 3)).result
        np.testing.assert_array_equal(paid, FoundOnly()(world, result).reshape(-1))
        found += int(result.targets_found.sum())
    assert found > 0  # the test saw the reward's target term
    with pytest.raises(ValueError, match=r"reward='papr' is not allowed: .* .did you mean 'paper'"):
        make_reward(RewardConfig("papr"))


def test_a_module_that_cannot_be_imported_is_refused_in_one_line(tmp_path):
    out = _app("train", *TINY, f"extensions=[{PACKAGE}.nothing]", f"hydra.run.dir={tmp_path / 'x'}")
    assert out.returncode == 2 and out.stderr.count("\n") == 1
    assert f"'{PACKAGE}.nothing' cannot be imported" in out.stderr
    assert not (tmp_path / "x").exists()


def test_the_commands_of_extending_md_run_as_written(tmp_path):
    """docs/extending.md's commands, each part with one setting of its own: each composes and passes its app's
    plan (every setting checked by the part's schema) with the extensions it names, as the entry point runs them."""
    from hydra import compose, initialize_config_dir

    from searchrl.command_line import from_command_line, import_modules
    from searchrl.evaluate.app import plan_evaluation
    from searchrl.evaluate.schema import register_configs as evaluate_configs
    from searchrl.shared_schema import CONF_DIR
    from searchrl.train.plan import make_plan
    from searchrl.train.schema import register_configs as train_configs
    from tests.registries import isolated_registries
    from tests.test_docs import bash_commands

    commands = [c for c in bash_commands((ROOT / "docs" / "extending.md").read_text()) if "searchrl." in c]
    assert len(commands) == 2 and all("extensions=" in c for c in commands)
    with isolated_registries("tests.extension_example"):
        for command in commands:
            app, args = command.split()[2].removeprefix("searchrl."), command.split()[3:]
            import_modules(from_command_line(args))
            train_configs(), evaluate_configs()
            with initialize_config_dir(str(CONF_DIR), version_base="1.3"):
                cfg = compose(
                    config_name=app, overrides=[*args, f"out_dir={tmp_path / 'e'}"] if app == "evaluate" else args
                )
            if app == "train":
                settings = make_plan(cfg).settings
                assert (settings.network.width, settings.network.scale, settings.reward.weight) == (24, 0.5, 2.0)
            else:
                assert plan_evaluation(cfg, args).settings.controller.margin == 2
    assert not (tmp_path / "e").exists()
