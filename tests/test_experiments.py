"""Recipes as config: every shipped policy (runs/reference/<folder>/) is reproduced by one override,
`python -m searchrl.train +experiment=<name>` (conf/experiment/<name>.yaml), and that file composes to the run's
recorded config.yaml on every setting that decides what is trained."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import searchrl.train.app  # noqa: F401  (registers the training schemas)
from searchrl.controllers.registry import resolved
from searchrl.policies.slim import weights_sha256
from searchrl.shared_schema import CONF_DIR, recipes
from searchrl.train.plan import make_plan
from searchrl.train.schema import TrainConfig, saved_config
from searchrl.world.scenario import Scenario

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "runs" / "reference"
RECIPES = CONF_DIR / "experiment"


def shipped_folder(recipe: str) -> str | None:
    """The folder under runs/reference/ that a recipe (its path under conf/experiment/, no suffix) makes: its own
    path, the clones' at the top (clone/b -> b); None for a research recipe (research/), which ships nothing."""
    if recipe.startswith("research/"):
        return None
    return recipe.removeprefix("clone/")


EXPERIMENTS = {name: shipped_folder(name) for name in recipes() if shipped_folder(name) is not None}
# Settings that do not decide what is trained, so a rerun may change them: speed and place (threads, device),
# display (progress_bar, log_interval: rows of the log, not updates), what is kept on disk (checkpoint_every,
# keep_checkpoints), the folder a killed run continues from (resume) and how the run's score is read off its
# validations (validation.score_last). `init` does decide (the start weights).
NOT_TRAINING = {"threads", "device", "progress_bar", "log_interval", "checkpoint_every", "keep_checkpoints", "resume",
                "validation.score_last"}  # fmt: skip
# Settings added to the code after some policy shipped, absent from its config.yaml, with why their schema default
# is what that run did (a section covers the settings under it where a shipped config lacks the whole section).
ADDED_LATER = {
    "env.replicas": "1: every group's worlds once, the only layout before the field",
    "env.world.k_per_n": "k = k + k_per_n·n per world; 0 keeps k = 1000 (λk = 1), the sensing of every shipped run",
    "env.world.belief_age": "0: the belief channels show the belief as it is, with no age",
    "env.world.belief_age_channel": "false: five channels, no age channel",
    "env.world.belief_seen": "false: the neighbours seen do not scale what is shown",
    "env.extra_teams": "[]: every world has env.world.n_agents, the only rollout before",
    "env.extra_teams.world_size": "null: a group's worlds draw env.world.world_size, as before the field",
    "imitation": "teacher null: no warm start (the RL runs predate imitation)",
    "imitation.lr_schedule": "constant: the only imitation rate before the field",
    "imitation.rl_weight": "0: plain PPO after the clone, the only RL before the field",
    "imitation.rl_schedule": "constant: unused with rl_weight 0",
    "imitation.rl_anneal_steps": "unused by the constant and linear schedules, the only ones before the field",
    "imitation.critic_warmup": "0: PPO updates the policy from the first rollout, as before the field",
    "init": "null: fresh weights, the only start before the field",
    "network.extractor": "search_cnn: the paper's network, the only one before the field",
    "network.grid": "16: read only by an extractor with a whole-map view, none before the field",
    "reward": "paper: the world's own reward, the only one before the field",
    "extensions": "[]: no user's modules, only searchrl's parts, as before the field",
    "critic": "shared: the value head on the actor's features, the only critic before the field",
    "logger": "default: progress.csv and TensorBoard, the only logs before the field",
    "scenario": "the paper's: no obstacle, targets placed from the prior, every world drawn before scenarios",
}
# Shipped start weights that moved after a run recorded their path: {recorded `init`: (where the same weights are
# now, the sha256 of their `policy.pth`, why they moved)}. A recorded `init` is read through this table, and the
# checkpoint there must hold those weights (the shipped files were slimmed since: searchrl/policies/slim.py).
MOVED = {
    "runs/reference/term/b/model.zip": (
        "runs/reference/ablations/b_term_epochs4/model.zip",
        "7847b0ef71d7a81831a7ed9823273cd5351be432f15294ca3393c084e3c203dd",
        "B's four-epoch RL policy, the start of walls/term_b and robust/b; term/b is the two-epoch recipe's since",
    ),
}


def _flat(node: Any, prefix: str = "") -> dict[str, Any]:
    """{dotted key: value}, list items by index (`env.extra_teams.0.world_size`); empty ones are values."""
    if isinstance(node, dict) and node:
        items = node.items()
    elif isinstance(node, list) and node:
        items = enumerate(node)
    else:
        return {prefix[:-1]: node}
    return {k: v for key, sub in items for k, v in _flat(sub, f"{prefix}{key}.").items()}


def _composed(name: str, overrides: tuple[str, ...] | None = None) -> dict[str, Any]:
    """The config of `+experiment=<name>`, or of the command line `overrides` as the app composes it."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=list(overrides or [f"+experiment={name}"]))
    make_plan(cfg)  # the recipe is a valid run for the current code (teacher arguments included)
    return OmegaConf.to_container(cfg, resolve=True)


def _resolved(config: dict[str, Any]) -> dict[str, Any]:
    """`config` with its teacher written out (the registry's `resolved`): `greedy_target` with reach 2 and `greedy`
    with target-greedy's settings and reach 2 are the same teacher; and its scenario as the run reads it
    (`Scenario.from_dict`: a run made before scenarios, or before a part existed, drew the paper's)."""
    config = {**config, "scenario": Scenario.from_dict(config.get("scenario")).to_dict()}
    imitation = config.get("imitation") or {}
    if imitation.get("teacher") is not None:
        teacher, args = resolved(imitation["teacher"], imitation.get("teacher_args"))
        config = {**config, "imitation": {**imitation, "teacher": teacher, "teacher_args": args}}
    return config


def _kept(flat: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in flat.items() if k.split(".")[0] not in NOT_TRAINING and k not in NOT_TRAINING}


def test_every_experiment_reproduces_a_shipped_folder_and_every_folder_has_one():
    shipped = sorted(str(p.parent.relative_to(REFERENCE)) for p in REFERENCE.rglob("model.zip"))
    assert sorted(EXPERIMENTS.values()) == shipped
    readme = (REFERENCE / "README.md").read_text()
    for name, folder in EXPERIMENTS.items():
        text = (RECIPES / f"{name}.yaml").read_text()
        assert text.startswith("# @package _global_\n"), name
        assert text.splitlines()[1].startswith(f"# runs/reference/{folder}:"), name  # its comment names the folder
        assert f"+experiment={name}" in readme, name


@pytest.mark.parametrize("name", sorted(EXPERIMENTS))
def test_experiment_composes_to_the_shipped_config(name):
    composed = _kept(_flat(_resolved(_composed(name))))
    loaded = saved_config(REFERENCE / EXPERIMENTS[name] / "config.yaml")  # as `resume=` reads it
    recorded = _kept(_flat(_resolved(OmegaConf.to_container(loaded))))
    # A setting the shipped run records that the code no longer has: a rerun would drop it without a word.
    gone = sorted(set(recorded) - set(composed))
    assert not gone, f"recorded by runs/reference/{EXPERIMENTS[name]}, lacking from the recipe or the code: {gone}"
    # What a rerun of the shipped run gets: its config.yaml with every setting it lacks at the schema default (as
    # `resume=` reads it), so the recipe must leave each setting added since at its default.
    shipped = _kept(
        _flat(_resolved(OmegaConf.to_container(OmegaConf.merge(OmegaConf.structured(TrainConfig), loaded))))
    )
    if shipped.get("init") in MOVED:
        shipped["init"] = MOVED[shipped["init"]][0]
    assert set(composed) == set(shipped), sorted(set(composed) ^ set(shipped))
    differ = {k: (composed[k], shipped[k]) for k in sorted(shipped)
              if composed[k] != shipped[k] or type(composed[k]) is not type(shipped[k])}  # fmt: skip
    assert not differ, f"composed != shipped, (composed, shipped): {differ}"
    # Each default standing in for a missing setting is one stated to keep the old behaviour.
    unstated = sorted(k for k in set(shipped) - set(recorded) if not _added_later(k, recorded))
    assert not unstated, f"settings absent from the shipped config.yaml and not in ADDED_LATER: {unstated}"


@pytest.mark.parametrize("recorded", sorted(MOVED))
def test_a_moved_start_holds_the_same_weights(recorded):
    now, sha256, _ = MOVED[recorded]
    assert weights_sha256(ROOT / now) == sha256, f"{now} does not hold the weights the runs recorded as {recorded}"


def _added_later(key: str, recorded: dict[str, Any]) -> bool:
    """`key` (or the whole section holding it, where the shipped config lacks that section) is in ADDED_LATER."""
    parts = [p for p in key.split(".") if not p.isdigit()]  # env.extra_teams.0.world_size -> env.extra_teams.world_size
    if ".".join(parts) in ADDED_LATER:
        return True
    sections = (".".join(parts[:n]) for n in range(1, len(parts)))
    return any(s in ADDED_LATER and not any(k.startswith(f"{s}.") or k == s for k in recorded) for s in sections)


@pytest.mark.app  # starts the training app
def test_the_command_line_composes_an_experiment():
    """`python -m searchrl.train +experiment=clone/c --cfg job` prints the recipe without training."""
    cmd = [sys.executable, "-m", "searchrl.train", "+experiment=clone/c", "--cfg", "job"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    printed = yaml.safe_load(out.stdout)
    assert printed == _composed("clone/c")


@pytest.mark.parametrize("model", ["a", "b", "c", "diagonal"])
def test_a_model_alone_is_the_papers_recipe_in_that_models_world(model):
    """`python -m searchrl.train +model=<m>` trains as the paper does (conf/train.yaml's values, RecurrentPPO from
    scratch) in model m's world, what `+model=<m>` also means to evaluation; the shipped recipes are experiments
    (`+experiment=term/<m>`), and the command line wins over a recipe."""
    paper = _composed("", ("+model=" + model,))
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        bare = OmegaConf.to_container(compose(config_name="train"), resolve=True)
    assert {k: v for k, v in paper.items() if k not in ("model", "env")} == {
        k: v for k, v in bare.items() if k not in ("model", "env")
    }
    assert paper["init"] is None and paper["imitation"]["teacher"] is None and paper["total_timesteps"] == 18400000
    assert paper["model"]["name"] == model and paper["env"]["world"] == _composed(f"rl/{model}")["env"]["world"]
    shipped = _composed("", (f"+experiment=term/{model}", "total_timesteps=1000"))
    assert shipped["total_timesteps"] == 1000 and shipped["init"] == f"runs/reference/{model}/model.zip"
