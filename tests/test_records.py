"""What an evaluation folder records and how a cell is laid out, in process and value by value: the record's
settings, its check against a rerun's, the grid's cells and map seeds, the memory budget's batch size, and the
per-world random streams (searchrl/evaluate/record.py, grid.py, runner.py; searchrl/world/streams.py)."""

from __future__ import annotations

import hashlib
from dataclasses import asdict, replace

import numpy as np
import pandas as pd
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import searchrl.evaluate.app  # noqa: F401  (registers the evaluation schemas)
from searchrl.controllers.episodes import episode_streams
from searchrl.evaluate.grid import Cell, map_seed, table2_cells
from searchrl.evaluate.record import (
    RECORD,
    claim_folder,
    evaluation_settings,
    file_sha256,
    option_defaults,
)
from searchrl.evaluate.runner import cell_config, episode_keys, run_cell, worlds_per_batch
from searchrl.shared_schema import CONF_DIR, dotted_leaves
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.streams import WorldStreams, random_source


def _cfg(*overrides: str):
    """The evaluation app's typed settings (EvaluateConfig) of these overrides."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return OmegaConf.to_object(compose(config_name="evaluate", overrides=list(overrides)))


def test_file_sha256_reads_the_whole_file_in_blocks(tmp_path):
    data = np.random.default_rng(0).bytes((1 << 20) + 12345)  # more than one 1 MiB block
    (tmp_path / "model.zip").write_bytes(data)
    assert file_sha256(tmp_path / "model.zip") == hashlib.sha256(data).hexdigest()
    (tmp_path / "empty").write_bytes(b"")
    assert file_sha256(tmp_path / "empty") == hashlib.sha256(b"").hexdigest()


def test_a_heuristics_record_names_it_its_settings_its_world_and_the_whole_grid():
    cfg = _cfg("controller=greedy_target", "+model=c", "seed=5", "grid.repeats=2")
    settings = evaluation_settings(cfg, "greedy", "c")
    assert list(settings) == ["controller", "model", "seed", "grid", "scenario", "controller_args", "world"]
    assert settings["scenario"] == {
        "obstacles": {"kind": "iid", "density": 0.0, "connected": False},
        "prior": {"kind": "mixture", "variance_scale": None},
        "targets": {"kind": "prior"},
    }
    assert (settings["controller"], settings["model"], settings["seed"]) == ("greedy", "c", 5)
    assert settings["grid"] == {"world_sizes": [20, 40, 80, 160], "n_targets": [4, 8, 16, 32],
                                "n_distributions": [8, 16, 32, 64], "max_agents": [32, 64, 128, 256],
                                "agents": None, "maps_per_cell": 100, "repeats": 2}  # fmt: skip
    assert settings["controller_args"]["name"] == "greedy" and settings["controller_args"]["horizon"] == 3
    assert settings["world"] == asdict(cfg.env.world)


def test_a_checkpoints_record_names_its_file_by_hash_and_how_it_acts(tmp_path):
    model = tmp_path / "model.zip"
    model.write_bytes(b"weights")
    cfg = _cfg(f"checkpoint={model}", "deterministic=true")
    settings = evaluation_settings(cfg, "policy:run", "b")
    assert settings["checkpoint_sha256"] == hashlib.sha256(b"weights").hexdigest()
    assert settings["deterministic"] is True and "world" not in settings and "controller_args" not in settings
    assert settings["device"] == "cpu"  # the kind of device its network ran on
    assert option_defaults(cfg) == {"scenario.obstacles.kind": "iid", "scenario.obstacles.density": 0.0,
                                    "scenario.obstacles.connected": False,
                                    "scenario.prior.kind": "mixture", "scenario.prior.variance_scale": None,
                                    "scenario.targets.kind": "prior", "grid.agents": None,
                                    "device": "cpu", "inference": "torch"}  # fmt: skip
    walls = evaluation_settings(_cfg(f"checkpoint={model}", "scenario=walls"), "policy:run", "b")
    assert walls["scenario"]["obstacles"] == {"kind": "iid", "density": 0.2, "connected": True}


def test_a_checkpoints_folder_holds_results_of_one_kind_of_device(tmp_path):
    """A record made before `device` existed ran on the CPU and takes a CPU rerun; a folder recorded on CUDA refuses
    a CPU rerun (and the reverse), naming the device: the two may round logits, so sampled actions, differently."""
    model = tmp_path / "model.zip"
    model.write_bytes(b"weights")
    cfg = _cfg(f"checkpoint={model}")
    settings = evaluation_settings(cfg, "policy:run", "b")
    old = {key: value for key, value in settings.items() if key != "device"}
    (tmp_path / RECORD).write_text(OmegaConf.to_yaml(OmegaConf.create(old)))
    claim_folder(tmp_path, settings, option_defaults(cfg))
    (tmp_path / RECORD).write_text(OmegaConf.to_yaml(OmegaConf.create({**settings, "device": "cuda"})))
    with pytest.raises(ConfigError, match=r"device: 'cuda' there, 'cpu' here"):
        claim_folder(tmp_path, settings, option_defaults(cfg))


def test_a_record_made_before_scenarios_matches_the_paper_and_one_with_an_unknown_setting_is_refused(tmp_path):
    """A record without `scenario` ran the paper's and takes a rerun of it, not of another scenario; one holding a
    setting searchrl does not have (a removed option: greedy's `far`) is refused, naming it."""
    cfg = _cfg("controller=greedy")
    settings = evaluation_settings(cfg, "greedy", "b")
    old = {key: value for key, value in settings.items() if key != "scenario"}
    (tmp_path / RECORD).write_text(OmegaConf.to_yaml(OmegaConf.create(old)))
    claim_folder(tmp_path, settings, option_defaults(cfg))
    walls = _cfg("controller=greedy", "scenario=walls")
    with pytest.raises(ConfigError, match=r"scenario.obstacles.density: '\(absent\)' there, 0.2 here"):
        claim_folder(tmp_path, evaluation_settings(walls, "greedy", "b"), option_defaults(walls))
    old["controller_args"] = {**old["controller_args"], "far": False}
    (tmp_path / RECORD).write_text(OmegaConf.to_yaml(OmegaConf.create(old)))
    with pytest.raises(ConfigError, match=r"controller_args.far: False there, '\(absent\)' here"):
        claim_folder(tmp_path, settings, option_defaults(cfg))


def test_option_defaults_are_the_worlds_and_the_controllers_schema_defaults_flattened():
    defaults = option_defaults(_cfg("controller=greedy"))
    assert defaults["world.world_size"] == list(WorldConfig().world_size)  # tuples as the YAML's lists
    assert defaults["world.k"] == WorldConfig().k and defaults["controller_args.horizon"] == 2
    assert defaults["controller_args.seen"] is False and "controller_args.name" in defaults
    assert not any(key.startswith("controller_args.") for key in option_defaults(_cfg("controller=random"))
                   if key != "controller_args.name")  # fmt: skip


def test_flatten_joins_nested_keys_with_dots():
    assert dotted_leaves({"a": {"b": 1, "c": {"d": [2]}}, "e": "x"}) == {"a.b": 1, "a.c.d": [2], "e": "x"}
    assert dotted_leaves(3, "top") == {"top": 3}


def test_claim_records_then_accepts_the_same_settings_and_names_every_difference(tmp_path, capsys):
    settings = {"controller": "greedy", "seed": 1, "grid": {"repeats": 5, "maps_per_cell": 100}}
    claim_folder(tmp_path, settings)
    assert OmegaConf.to_container(OmegaConf.load(tmp_path / RECORD)) == settings
    claim_folder(tmp_path, settings)  # the same: accepted, the record untouched
    other = {"controller": "greedy", "seed": 2, "grid": {"repeats": 5}, "new": 1}
    with pytest.raises(ConfigError) as err:
        claim_folder(tmp_path, other)
    assert str(err.value) == (
        f"out_dir={str(tmp_path)!r} holds results of other settings (grid.maps_per_cell: 100 there, '(absent)' here;"
        " new: '(absent)' there, 1 here; seed: 1 there, 2 here): give this run another out_dir, or remove that "
        "folder to start it afresh"
    )
    claim_folder(tmp_path, {**settings, "new": 1}, defaults={"new": 1})  # an option added since, at its default
    with pytest.raises(ConfigError, match=r"new: '\(absent\)' there, 2 here"):
        claim_folder(tmp_path, {**settings, "new": 2}, defaults={"new": 1})
    with pytest.raises(ConfigError, match=r"new: '\(absent\)' there, None here"):  # null is a value too
        claim_folder(tmp_path, {**settings, "new": None})
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("record, why", [("", "ValueError"), ("[1, 2]\n", "ValueError"), ("seed: 1\n", "ValueError"),
                                         ("{{{ not yaml", "ParserError")])  # fmt: skip
def test_an_unreadable_record_is_named_and_kept(tmp_path, record, why):
    (tmp_path / RECORD).write_text(record)
    with pytest.raises(ConfigError) as err:
        claim_folder(tmp_path, {"controller": "greedy"})
    assert str(err.value).startswith(f"out_dir={str(tmp_path)!r}: its {RECORD} cannot be read ({why})")
    assert str(err.value).endswith("); restore it, or remove that folder to start it afresh")
    assert (tmp_path / RECORD).read_text() == record


def test_a_folder_of_results_without_a_record_adopts_this_runs(tmp_path, capsys):
    """Cells made before cells recorded their settings: the record is this run's."""
    (tmp_path / "cells").mkdir()
    pd.DataFrame({"found_fraction": [0.5]}).to_parquet(tmp_path / "cells" / "n20_N1.parquet")
    claim_folder(tmp_path, {"controller": "surfing"})
    assert capsys.readouterr().err == f"note: {tmp_path} has results but no {RECORD}; recording this run's settings\n"
    assert (tmp_path / RECORD).read_text() == "controller: surfing\n"


def test_the_grid_doubles_the_team_up_to_each_sizes_limit_and_refuses_bad_lists():
    cells = table2_cells([20, 40], [4, 8], [8, 16], [4, 1])
    assert cells == [Cell(20, 1, 4, 8), Cell(20, 2, 4, 8), Cell(20, 4, 4, 8), Cell(40, 1, 8, 16)]
    assert [c.key for c in table2_cells([20], [4], [8], [8])] == ["n20_N1", "n20_N2", "n20_N4", "n20_N8"]
    bad = [(([20, 40], [4], [8], [1]), "grid lists differ in length: world_sizes=[20, 40], n_targets=[4], "
                                       "n_distributions=[8], max_agents=[1]; give one entry per world size"),
           (([], [], [], []), "grid.world_sizes=[] is not allowed: one or more world sizes (with their other lists)"),
           (([20, 20], [4, 4], [8, 8], [1, 1]), "grid.world_sizes=[20, 20] is not allowed: each size once (a cell is "
                                                "named n<n>_N<N>)"),
           (([20], [4], [8], [0]), "grid entry n=20, targets=4, m=8, max N=0: all must be >= 1"),
           (([0], [4], [8], [1]), "grid entry n=0, targets=4, m=8, max N=1: all must be >= 1"),
           (([20], [0], [8], [1]), "grid entry n=20, targets=0, m=8, max N=1: all must be >= 1"),
           (([20], [4], [0], [1]), "grid entry n=20, targets=4, m=0, max N=1: all must be >= 1"),
           (([20, 40], [4, 8], [8, 16], [4, 3]), "grid.max_agents=[4, 3] is not allowed: each a power of two (N = "
                                                 "1, 2, 4, … up to it), not 3")]  # fmt: skip
    for lists, message in bad:
        with pytest.raises(ValueError) as err:
            table2_cells(*lists)
        assert str(err.value) == message
    assert map_seed(7_000_000, 3, 42) == 7_300_042


def test_a_cell_sets_the_worlds_size_team_targets_and_gaussians_and_nothing_else():
    world = WorldConfig(diagonal=True, n_agents=3)
    config = cell_config(world, Cell(80, 16, 16, 32))
    assert (config.world_size, config.n_targets, config.n_distributions, config.n_agents) == (
        (80, 80), (16, 16), (32, 32), 16)  # fmt: skip
    assert replace(config, world_size=world.world_size, n_targets=world.n_targets,
                   n_distributions=world.n_distributions, n_agents=3) == world  # fmt: skip


def test_the_memory_budget_counts_each_worlds_beliefs_and_maps():
    config = cell_config(WorldConfig(), Cell(40, 4, 8, 16))
    side = 40 + 2 * config.halo
    per_world = 4 * 2 * side * side * 4 + 6 * side * side * 4  # N beliefs of two maps, six more maps, float32
    assert worlds_per_batch(config, per_world * 10 / 2**20) == 10
    assert worlds_per_batch(config, per_world * 10.5 / 2**20) == 10  # whole worlds only
    assert worlds_per_batch(config, (per_world * 10 - 1) / 2**20) == 9
    assert worlds_per_batch(config, 1e-9) == 1  # at least one


def test_each_episode_has_its_own_streams_for_the_world_and_the_controller():
    world, controller = episode_streams(episode_keys(7, 3, [(0, 0), (0, 1), (5, 0)]))
    assert len(world) == len(controller) == 3
    rows = world.random((3, 4))
    assert np.array_equal(rows[2], np.random.default_rng([7, 3, 5, 0, 0]).random(4))
    assert np.array_equal(controller.random((3, 4))[1], np.random.default_rng([7, 3, 0, 1, 1]).random(4))
    alone, _ = episode_streams(episode_keys(7, 3, [(5, 0)]))
    assert np.array_equal(alone.random((1, 4))[0], rows[2])  # the same episode draws the same, whatever its batch


def test_world_streams_draw_row_k_from_world_ks_generator_and_check_the_first_axis():
    streams = WorldStreams([(1, 2), (3,)])
    ints = streams.integers(1, 5, size=(2, 6))
    assert ints.dtype == np.int64 and ints.shape == (2, 6)
    assert np.array_equal(ints[1], np.random.default_rng([3]).integers(1, 5, size=6))
    assert ints.min() >= 1 and ints.max() <= 4
    again = WorldStreams([(1, 2), (3,)])
    assert np.array_equal(
        again.random(2), [np.random.default_rng([1, 2]).random(), np.random.default_rng([3]).random()]
    )
    with pytest.raises(ValueError, match=r"a draw of size \(3, 4\) from 2 world streams: its first axis must be the "
                                         r"number of worlds, 2"):  # fmt: skip
        streams.random((3, 4))
    with pytest.raises(ValueError, match="first axis"):
        streams.integers(0, 2, size=())
    empty = WorldStreams([])
    assert empty.random((0, 3)).shape == (0, 3) and empty.integers(0, 2, (0, 3)).shape == (0, 3)
    assert empty.integers(0, 2, (0, 3)).dtype == np.int64
    assert random_source(streams) is streams
    assert np.array_equal(random_source(4).random(3), np.random.default_rng(4).random(3))


def test_a_record_holds_values_not_the_interpolations_that_gave_them():
    cfg = _cfg("controller=greedy", "grid.repeats=3", "grid.maps_per_cell=${grid.repeats}",
               "controller.horizon=${grid.repeats}", "env.world.max_steps=${grid.maps_per_cell}")  # fmt: skip
    settings = evaluation_settings(cfg, "greedy", "b")
    assert settings["grid"]["maps_per_cell"] == 3 and settings["controller_args"]["horizon"] == 3
    assert settings["world"]["max_steps"] == 3


def test_run_cell_observes_for_the_controller_unless_told_it_needs_no_observation():
    """A policy reads the agents' observations: they are made by default, and skipped (None) when a heuristic
    says it needs none. The steps counted for the progress bar are each live world's agents."""
    from searchrl.controllers.registry import make_controller

    seen, steps = [], []

    class Recording:
        def __init__(self, config, seed):
            self.inner = make_controller("greedy", config, seed=seed)
            self.config = config

        def reset(self, state, mask):
            self.inner.reset(state, mask)

        def act(self, state, maps, vector, active=None):
            seen.append(None if maps is None else (maps.shape, vector.shape))
            return self.inner.act(state, maps, vector, active)

    cell = Cell(20, 2, 4, 8)
    frame = run_cell(Recording, WorldConfig(), cell, 0, maps=2, repeats=1, seed=3, on_steps=steps.append)
    assert seen[0] == ((2, 2, 5, 11, 11), (2, 2, 3)) and None not in seen
    assert steps[0] == 4 and sum(steps) == 2 * frame.L.sum()  # N agents of each world, up to its episode's end
    seen.clear()
    run_cell(Recording, WorldConfig(), cell, 0, maps=2, repeats=1, seed=3, needs_observation=False)
    assert set(seen) == {None}


def test_run_cell_lets_a_policy_act_in_every_running_world_and_keeps_each_columns_type():
    from pathlib import Path

    from searchrl.controllers.policy import PolicyController
    from searchrl.policies.checkpoint import load_actor

    world = WorldConfig()
    actor = load_actor(Path(__file__).resolve().parents[1] / "runs" / "reference" / "b" / "model.zip", world)
    frame = run_cell(lambda config, seed: PolicyController(actor, config, seed=seed), world, Cell(20, 2, 4, 8), 0,
                     maps=3, repeats=1, seed=3)  # fmt: skip
    assert frame.found_fraction.mean() > 0.8  # agents that never moved would find the few targets under them
    assert frame.dtypes.astype(str).to_dict() == {"n": "int64", "N": "int64", "targets": "int64", "map_seed": "int64",
                                                  "repeat": "int64", "found_fraction": "float64", "L": "int64",
                                                  "R": "float64", "F": "int64", "M_bar": "float64",
                                                  "prior_quality": "float64", "blocked": "float64",
                                                  "stale": "float64"}  # fmt: skip
    assert frame.prior_quality.between(-1, 1).all() and frame.blocked.between(0, 1).all()
    assert frame.stale.between(0, 1).all()


def test_play_shows_each_step_the_world_and_the_worlds_it_counts():
    from searchrl.controllers.episodes import play
    from searchrl.controllers.registry import make_controller
    from searchrl.world.config import WorldConfig
    from searchrl.world.engine import SearchWorld

    config = WorldConfig(world_size=(8, 8), n_agents=2, n_targets=(1, 1), n_distributions=(1, 1), max_steps=30)
    world_streams, controller_streams = episode_streams([(3,), (4,)])
    world = SearchWorld.from_maps(config, [3, 4], world_streams)
    seen: list[tuple[bool, np.ndarray]] = []
    play(world, make_controller("random", config, controller_streams),
         on_step=lambda stepped, counted: seen.append((stepped is world, counted.copy())))  # fmt: skip
    assert seen and all(same for same, _ in seen)  # the world as it stands after each step
    assert seen[0][1].all() and len(seen) <= config.max_steps  # both episodes count from the first step
