"""Frozen scenario suites: `python -m searchrl.evaluate suite=<name> controller=<name> | checkpoint=<model.zip>`.

A suite (conf/suite/<name>.yaml, schema `SuiteConfig`) fixes everything that decides its episodes but the
controller: the grid cells (world sizes and team sizes), maps per cell, repeats, the evaluation seed, and its
scenarios, made from families of prior error (or of obstacles) × severities × prior sharpness (`suite_scenarios`).
Each scenario is a normal evaluation folder, `<out_dir>/<scenario label>/` (default out_dir
`runs/suite/<suite>/<controller or policy path>`), so a suite resumes, shards (`shard=`/`num_shards=` split its
(scenario, cell) pairs) and is recorded and loaded like any evaluation. A suite is frozen: the command line may not
change its grid, seed or scenarios; every scenario of every cell is checked before any folder is written.
`suite_scenarios=` runs part of it (labels or patterns, e.g. `'[*+*1,*1p?]'` for prior_error's severity 1): the
same folders, cells and maps the whole suite gives those scenarios, so the rest can follow into the same out_dir.
"""

from __future__ import annotations

import copy
import fnmatch
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from omegaconf import DictConfig, OmegaConf

from searchrl.atomic import storage_message, write_text_atomic
from searchrl.evaluate.app import claim_evaluation, fail, plan_evaluation, run_evaluation
from searchrl.evaluate.checks import given_out_dir
from searchrl.evaluate.schema import EvaluateConfig, GridConfig
from searchrl.shared_schema import override_keys
from searchrl.world.config import ConfigError, need
from searchrl.world.scenario import Scenario, scenario_grid

FROZEN = ("suite", "grid", "scenario", "seed")  # what a suite fixes: the command line may not set them
SUITE_RECORD = "suite.yaml"  # in a controller's suite folder: the suite's name, seed and scenario labels


@dataclass
class SuiteConfig:
    name: str = "suite"  # its folder under runs/suite/
    grid: GridConfig = field(default_factory=GridConfig)
    seed: int = 7_000_000
    # The prior's sharpness: p's Gaussians have σ² below variance_scale · n (null: the world's, 10); 1 is sharp
    variance_scales: list[Any] = field(default_factory=lambda: [None])
    severities: list[float] = field(default_factory=lambda: [0.25, 0.5, 1.0])  # each family's; 0 is run once
    # name -> the scenario parts the family sets ({targets: {kind: shifted}}); its severity set per point
    families: dict[str, Any] = field(default_factory=dict)
    obstacles: dict[str, Any] | None = None  # the obstacles of every family's scenario (null: none)
    scenarios: list[Any] = field(default_factory=list)  # more scenarios, each a mapping as conf/scenario/ holds


def suite_scenarios(suite: dict[str, Any]) -> list[Scenario]:
    """The suite's scenarios in order (`scenario_grid`): per variance scale, the prior right (severity 0, the
    paper's placement), then each family at each severity; then its explicit `scenarios`. ConfigError naming a bad
    family or value."""
    scenarios = scenario_grid(suite["families"], suite["severities"], suite["variance_scales"], suite.get("obstacles"))
    scenarios += [Scenario.from_dict(values) for values in suite.get("scenarios") or []]
    labels = [s.label for s in scenarios]
    need(len(set(labels)) == len(labels), "suite.scenarios", labels, "scenarios that differ (each its own label)")
    return scenarios


def chosen_scenarios(scenarios: list[Scenario], patterns: list[str] | None, name: str) -> list[Scenario]:
    """The scenarios whose labels match one of `patterns` (fnmatch; None: every one), in the suite's order;
    ConfigError naming a pattern that matches none."""
    if patterns is None:
        return scenarios
    labels = [s.label for s in scenarios]
    for pattern in patterns:
        allowed = f"a label or pattern of suite {name}'s scenarios: {', '.join(labels)}"
        need(bool(fnmatch.filter(labels, pattern)), "suite_scenarios", pattern, allowed)
    return [s for s in scenarios if any(fnmatch.fnmatchcase(s.label, p) for p in patterns)]


def suite_default_dir(cfg: EvaluateConfig, name: str) -> Path:
    """runs/suite/<suite>/<controller> or runs/suite/<suite>/policy/<run path under runs/>."""
    if cfg.checkpoint is not None:
        from searchrl.policies.checkpoint import checkpoint_label

        return Path("runs/suite") / name / "policy" / checkpoint_label(cfg.checkpoint)
    return Path("runs/suite") / name / cfg.controller.name


def evaluate_suite(cfg: DictConfig, overrides: list[str]) -> list[Path]:
    """Evaluate this shard's part of every scenario of `cfg.suite`; returns the scenario folders."""
    plans = []
    try:
        frozen = [
            o
            for o, k in zip(overrides, override_keys(overrides), strict=True)
            if k.split(".")[0] in FROZEN and not o.startswith("suite=")
        ]
        if frozen:
            raise ConfigError(
                f"{', '.join(frozen)} cannot apply to suite={cfg.suite.name}: a suite is frozen (its "
                "grid, seed and scenarios are conf/suite/); remove them, or evaluate with grid.* and "
                "scenario=… without suite="
            )
        suite = OmegaConf.to_container(OmegaConf.merge(OmegaConf.structured(SuiteConfig), cfg.suite), resolve=True)
        typed = OmegaConf.to_object(cfg)
        base = given_out_dir(typed, "runs/suite/<suite>/<controller or policy>") or suite_default_dir(
            typed, suite["name"]
        )
        scenarios = suite_scenarios(suite)
        chosen = chosen_scenarios(scenarios, typed.suite_scenarios, suite["name"])
        for offset, scenario in enumerate(scenarios):  # offset: a scenario's place in the whole suite
            if scenario not in chosen:
                continue
            one = copy.deepcopy(cfg)
            one.suite, one.suite_scenarios, one.seed = None, None, suite["seed"]
            one.grid = OmegaConf.merge(OmegaConf.structured(GridConfig), suite["grid"])
            one.scenario, one.out_dir = scenario.to_dict(), str(base / scenario.label)
            plan = plan_evaluation(one, [o for o in overrides if not o.startswith("suite=")])
            plan.shard_offset = offset
            plans.append(plan)
        for plan in plans:
            claim_evaluation(plan)
        # what the suite is, beside its scenario folders: a table of part of it can say what it lacks
        record = {"suite": suite["name"], "seed": suite["seed"], "scenarios": [s.label for s in scenarios]}
        write_text_atomic(base / SUITE_RECORD, OmegaConf.to_yaml(OmegaConf.create(record)))
    except OSError as err:  # a refusal (ConfigError) passes as it is
        fail(storage_message(err) or f"suite={cfg.suite.name}: {err}")
    return [run_evaluation(plan) for plan in plans]
