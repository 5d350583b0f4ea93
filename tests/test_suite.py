"""Frozen scenario suites (searchrl/evaluate/suite.py): the shipped suites' scenarios and cells, one command that
runs, resumes and shards a suite into one folder per scenario, rows that name family, severity and sharpness, and
a suite that refuses to be changed from the command line."""

from __future__ import annotations

import errno
from pathlib import Path

import pandas as pd
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import searchrl.evaluate.suite as suite_module
from searchrl.evaluate.results import load
from searchrl.evaluate.suite import SUITE_RECORD, SuiteConfig, evaluate_suite, suite_scenarios
from searchrl.multirun import exits
from searchrl.shared_schema import CONF_DIR, group_option
from searchrl.world.config import ConfigError
from searchrl.world.scenario import PAPER

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

TINY = {"name": "tiny", "seed": 5, "variance_scales": [1.0], "severities": [1.0],
        "grid": {"world_sizes": [20, 40], "n_targets": [4, 8], "n_distributions": [8, 16], "max_agents": [4, 4],
                 "agents": [1, 4], "maps_per_cell": 2, "repeats": 1},
        "families": {"off_prior": {"targets": {"kind": "off_prior"}},
                     "uninformed": {"prior": {"kind": "uninformed"}}}}  # fmt: skip
FAST = ["progress_bar=false", "threads=1", "bound_draws=200", "bound_cache=null"]


def _suite(name: str) -> dict:
    node = OmegaConf.merge(OmegaConf.structured(SuiteConfig), group_option("suite", name))
    return OmegaConf.to_container(node)


def _run(out: Path, *overrides: str, suite: dict = TINY) -> list[Path]:
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=["suite=prior_error", *FAST, f"out_dir={out}", *overrides])
    cfg.suite = OmegaConf.create(suite)  # a small suite, run as the shipped ones are
    return evaluate_suite(cfg, ["suite=prior_error", *overrides])


def _refusal(out: Path, capsys, *overrides: str, suite: dict = TINY) -> str:
    """The suite refused: exit status 2; its standard error."""
    with pytest.raises(SystemExit) as exit_, exits():
        _run(out, *overrides, suite=suite)
    assert exit_.value.code == 2
    return capsys.readouterr().err


@pytest.mark.parametrize("name, scale", [("prior_error", 1.0), ("prior_error_broad", None)])
def test_the_shipped_suites_pose_every_family_at_every_severity(name, scale):
    suite = _suite(name)
    scenarios = suite_scenarios(suite)
    assert len(scenarios) == 1 + 7 * 3 and len({s.label for s in scenarios}) == len(scenarios)
    right = scenarios[0]
    assert right.family == "paper" and right.severity == 0 and right.targets_follow_prior
    assert right.prior.variance_scale == scale
    assert {s.family for s in scenarios[1:]} == {"off_prior", "shifted", "sharper", "flatter", "misweighted",
                                                 "adversarial", "uninformed"}  # fmt: skip
    assert all(not s.targets_follow_prior and s.prior.variance_scale == scale for s in scenarios[1:])
    assert suite["grid"]["agents"] == [1, 4, 16, 64] and suite["grid"]["maps_per_cell"] >= 50
    if scale is None:
        assert right == PAPER  # the broad suite's right prior is the paper's scenario, bit for bit


def test_a_suites_obstacles_reach_its_grid_and_its_own_scenarios_follow():
    suite = {"families": {"uninformed": {"prior": {"kind": "uninformed"}}}, "severities": [1.0],
             "variance_scales": [None], "obstacles": {"kind": "iid", "density": 0.1, "connected": True},
             "scenarios": [{"obstacles": {"kind": "maze", "corridor": 3, "loops": 0.1}}]}  # fmt: skip
    assert [s.label for s in suite_scenarios(suite)] == ["iid0.1c", "iid0.1c+uninformed1", "maze3l0.1"]
    twice = {"families": {}, "severities": [], "variance_scales": [None], "scenarios": [{}]}  # the paper's, twice
    with pytest.raises(ConfigError) as error:
        suite_scenarios(twice)
    assert (
        str(error.value)
        == "suite.scenarios=['paper', 'paper'] is not allowed: scenarios that differ (each its own label)"
    )


def test_a_suite_runs_from_one_command_into_a_folder_per_scenario_and_resumes(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # without out_dir: runs/suite/<suite>/<controller> under it, and its record beside
    # a suite's yaml may leave out what the schema sets (the seed) and use interpolations: folders and record hold
    # the values
    suite = {**{k: v for k, v in TINY.items() if k != "seed"}, "name": "${oc.decode:tiny}"}
    labels = ["var1", "var1+off_prior1", "var1+uninformed1"]
    folders = _run(tmp_path, "controller=coverage", "out_dir=null", suite=suite)
    base = tmp_path / "runs" / "suite" / "tiny" / "coverage"
    assert [f.resolve() for f in folders] == [base / label for label in labels]
    record = OmegaConf.to_container(OmegaConf.load(base / SUITE_RECORD))
    assert record == {"suite": "tiny", "seed": SuiteConfig.seed, "scenarios": labels}
    frame = load(*folders)
    assert len(frame) == 3 * 4 * 2  # scenarios x cells (n 20, 40 x N 1, 4) x maps
    assert set(zip(frame["family"], frame["severity"], strict=True)) == {("paper", 0.0), ("off_prior", 1.0),
                                                                         ("uninformed", 1.0)}  # fmt: skip
    assert (frame["variance_scale"] == 1.0).all() and set(frame["N"]) == {1, 4}
    assert frame.loc[frame["family"] == "paper", "bound"].notna().all()  # the bound holds where the prior is right
    assert frame.loc[frame["family"] != "paper", "bound"].isna().all()
    capsys.readouterr()
    _run(tmp_path, "controller=coverage", "out_dir=null", suite=suite)  # a rerun finds every cell done
    assert capsys.readouterr().err.count("0 of 4 cells to run") == 3


def test_shards_split_the_suites_scenario_cells_once(tmp_path):
    for shard in range(3):
        _run(tmp_path / "shards", "controller=coverage", f"shard={shard}", "num_shards=3")
    _run(tmp_path / "whole", "controller=coverage")
    sharded = load(*sorted((tmp_path / "shards").iterdir()))
    whole = load(*sorted((tmp_path / "whole").iterdir()))
    key = ["scenario", "n", "N", "map_seed"]
    assert (
        sharded.sort_values(key)
        .reset_index(drop=True)[[*key, "found_fraction"]]
        .equals(whole.sort_values(key).reset_index(drop=True)[[*key, "found_fraction"]])
    )


def test_part_of_a_suite_runs_the_whole_suites_folders_and_the_rest_follows(tmp_path, capsys):
    """`suite_scenarios=` runs only the scenarios it names (a pattern), each into the folder, cells and maps the
    whole suite gives it; the whole suite run into the same folder afterwards runs only the rest. A pattern that
    names no scenario is refused in one line before any folder, and so is the setting without a suite."""
    whole = _run(tmp_path / "whole", "controller=coverage")
    part = _run(tmp_path / "part", "controller=coverage", "suite_scenarios=[*off_prior*]")
    assert [p.name for p in part] == ["var1+off_prior1"]
    key = ["n", "N", "map_seed", "repeat"]
    columns = [*key, "found_fraction", "L"]
    mine = load(*part).sort_values(key).reset_index(drop=True)[columns]
    theirs = load(whole[1]).sort_values(key).reset_index(drop=True)[columns]
    assert mine.equals(theirs)
    capsys.readouterr()
    _run(tmp_path / "part", "controller=coverage")
    err = capsys.readouterr().err
    assert err.count("0 of 4 cells to run") == 1 and err.count("4 of 4 cells to run") == 2
    err = _refusal(tmp_path / "bad", capsys, "controller=coverage", "suite_scenarios=[*off_prior*,nothing*]")
    assert err.endswith("error: suite_scenarios='nothing*' is not allowed: a label or pattern of suite tiny's "
                        "scenarios: var1, var1+off_prior1, var1+uninformed1\n"), err[-500:]  # fmt: skip
    assert not (tmp_path / "bad").exists()
    from searchrl.evaluate.app import plan_evaluation

    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="evaluate", overrides=["controller=coverage", "suite_scenarios=[var1]", *FAST])
    with pytest.raises(ConfigError, match=r"^suite_scenarios=\['var1'\] is not allowed: null without suite=<name>$"):
        plan_evaluation(cfg, ["controller=coverage", "suite_scenarios=[var1]"])


@pytest.mark.parametrize(
    "overrides",
    [["grid.maps_per_cell=3"], ["seed=1"], ["scenario=walls"], ["suite.seed=3"], ["seed=1", "grid.repeats=2"]],
)
def test_a_suite_is_frozen(tmp_path, overrides, capsys):
    """Every frozen override is named in the one line of the refusal, before anything is written."""
    err = _refusal(tmp_path, capsys, "controller=coverage", *overrides)
    assert err.endswith(
        f"error: {', '.join(overrides)} cannot apply to suite=tiny: a suite is frozen (its grid, seed and scenarios "
        "are conf/suite/); remove them, or evaluate with grid.* and scenario=… without suite=\n"
    ), err[-1500:]
    assert not any(tmp_path.iterdir())


def test_an_empty_out_dir_is_refused_not_taken_for_the_default(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default folder would be runs/suite/... under it
    assert _refusal(tmp_path / "unused", capsys, "controller=coverage", "out_dir=").endswith(
        "error: out_dir='' is not allowed: a folder (leave it out for runs/suite/<suite>/<controller or policy>)\n"
    )
    assert not any(tmp_path.iterdir())


def test_each_scenario_checks_the_command_lines_overrides(tmp_path, capsys):
    assert _refusal(tmp_path, capsys, "controller=coverage", "env.world.n_agents=4").endswith(
        "error: env.world.n_agents cannot apply to an evaluation: the grid sets N, n, targets and Gaussians per cell "
        "(grid.*), one team per world, and deterministic is for checkpoints; remove them\n"
    )
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    "error, line",
    [
        (OSError(errno.ENOSPC, "No space left on device", "suite.yaml"),
         "No space left on device writing suite.yaml: free space (or ask for quota) and run the same command again"),
        (IsADirectoryError(errno.EISDIR, "Is a directory", "suite.yaml"),
         "suite=tiny: [Errno 21] Is a directory: 'suite.yaml'"),
    ],
)  # fmt: skip
def test_a_fault_writing_the_suites_record_is_one_line(tmp_path, capsys, monkeypatch, error, line):
    def fail(*_):
        raise error

    monkeypatch.setattr(suite_module, "write_text_atomic", fail)
    assert _refusal(tmp_path, capsys, "controller=coverage").endswith(f"error: {line}\n")


def test_a_bad_family_is_named_before_any_folder(tmp_path, capsys):
    bad = {**TINY, "families": {**TINY["families"], "psychic": {"targets": {"kind": "psychic"}}}}
    err = _refusal(tmp_path, capsys, "controller=coverage", suite=bad)
    assert "scenario.targets.kind='psychic' is not allowed" in err
    assert not any(tmp_path.iterdir())


@pytest.mark.slow  # an evaluation folder's fault injection is in the default run
def test_a_suite_folder_repairs_or_refuses_each_damaged_file_and_loses_nothing(tmp_path, capsys):
    """Each file of a finished suite folder (its suite.yaml, each scenario's record and cells) in turn deleted,
    truncated, overwritten or swapped for another suite run's (seed 6): the rerun repairs it (the folder then loads
    as the undamaged one) or refuses in one line, leaving every other file as it was; nothing mixes the two."""
    import shutil

    from tests.test_faults import DAMAGES, _damaged_copies, _rerun

    one = {**TINY, "families": {"off_prior": TINY["families"]["off_prior"]}}  # two scenarios: enough of each file
    clean_folders = _run(tmp_path / "clean", "controller=coverage", suite=one)
    _run(tmp_path / "other", "controller=coverage", suite={**one, "seed": 6})
    clean, other = tmp_path / "clean", tmp_path / "other"
    want = load(*clean_folders)
    files = sorted(p.relative_to(clean) for p in clean.rglob("*") if p.is_file() and ".locks" not in p.parts)
    outcomes = {}
    for rel, name, folder in _damaged_copies(clean, other, files, tmp_path / "damaged"):
        kept = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file() and p != folder / rel}
        outcome = _rerun(capsys, lambda f=folder: _run(f, "controller=coverage", suite=one))
        outcomes[f"{rel} {name}"] = outcome
        changed = [p for p, content in kept.items() if ".locks" not in p.parts and p.read_bytes() != content]
        assert changed in ([], [folder / "suite.yaml"]) if outcome == "repaired" else not changed, (rel, name)
        if outcome == "repaired":
            got = load(*(folder / f.name for f in clean_folders))
            pd.testing.assert_frame_equal(got, want)
        shutil.rmtree(folder)
    swapped_cells = [k for k in outcomes if k.endswith(".parquet swapped")]
    assert swapped_cells and all(outcomes[k] == "refused" for k in swapped_cells)  # another suite's maps: never mixed
    assert all(outcomes[f"suite.yaml {n}"] == "repaired" for n in DAMAGES)  # the record is the suite's definition
    assert all(v == "repaired" for k, v in outcomes.items() if not k.endswith("swapped")), outcomes
