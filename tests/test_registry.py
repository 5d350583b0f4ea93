"""One registry of heuristic controllers (searchrl/controllers/registry.py): every entry point reads it, its names are
the ones error messages list, and `greedy_target` is footprint-greedy with the target-greedy settings spelled out."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import ClassVar
from unittest import mock

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from searchrl.controllers import registry
from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.controllers.registry import (
    HEURISTICS,
    allowed,
    heuristic,
    make_controller,
    make_teacher,
    teacher_settings,
    teachers,
)
from searchrl.evaluate.app import evaluate, make_controller_factory
from searchrl.evaluate.results import load
from searchrl.evaluate.schema import register_configs
from searchrl.multirun import exits
from searchrl.shared_schema import CONF_DIR
from searchrl.world import scenario
from searchrl.world.config import ConfigError, MissingFile, WorldConfig, need
from tests.test_evaluate import SLICE

ROOT = Path(__file__).resolve().parents[1]
TARGET_GREEDY = ["controller=greedy", "controller.horizon=3", "controller.w_p=0", "controller.w_u=0",
                 "controller.w_t=1"]  # fmt: skip


def _compose(*overrides: str):
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name="evaluate", overrides=list(overrides))


def test_every_name_has_a_config_file_a_schema_of_its_name_and_a_class_taking_its_settings():
    assert set(HEURISTICS) == {p.stem for p in (ROOT / "conf" / "controller").glob("*.yaml")}
    for name, entry in HEURISTICS.items():
        assert entry.schema.name == name and entry.schema.__module__ == entry.cls.__module__  # beside its class
        assert _compose(f"controller={name}").controller.name == name
        controller = make_controller(name, WorldConfig(), seed=1)
        assert isinstance(controller, entry.cls)


def _imports(path: Path) -> set[str]:
    imported = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            imported |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module or "")
    return imported


def test_controllers_import_no_hydra_and_no_app_layer():
    """Layering: world <- envs <- policies <- controllers <- imitation <- train/evaluate; Hydra and its config
    library stay in the app layer."""
    for path in (ROOT / "searchrl" / "controllers").glob("*.py"):
        app = [m for m in _imports(path) if m.split(".")[0] in ("hydra", "omegaconf")
               or m.startswith(("searchrl.imitation", "searchrl.train", "searchrl.evaluate"))]  # fmt: skip
        assert not app, (path, app)


def _upward(layers: tuple[str, ...], above: tuple[str, ...]) -> list[tuple[str, str]]:
    """(module file, what it imports) for each import of a layer above, in any module of `layers`."""
    return [(str(path.relative_to(ROOT)), m) for layer in layers for path in (ROOT / "searchrl" / layer).glob("*.py")
            for m in sorted(_imports(path)) if m.startswith(above)]  # fmt: skip


def test_the_parts_import_only_the_layers_below_them():
    """The parts the apps build import neither app, and each only the parts below it: world <- envs <- policies <-
    controllers (a trained policy is one) <- imitation (its teachers are controllers) <- train/evaluate."""
    assert not _upward(("envs", "policies", "imitation"), ("searchrl.train", "searchrl.evaluate"))
    assert not _upward(("envs", "policies"), ("searchrl.controllers", "searchrl.imitation"))
    assert not _upward(("envs",), ("searchrl.policies",))


def test_the_layer_check_finds_an_upward_import(tmp_path, monkeypatch):
    planted = tmp_path / "searchrl" / "policies"
    planted.mkdir(parents=True)
    (planted / "buffer.py").write_text("from searchrl.train.logs import log_digest\n")
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert _upward(("policies",), ("searchrl.train",)) == [("searchrl/policies/buffer.py", "searchrl.train.logs")]


def test_the_world_imports_no_rl_library_no_hydra_and_no_layer_above_it():
    above = (
        "searchrl.envs",
        "searchrl.controllers",
        "searchrl.policies",
        "searchrl.imitation",
        "searchrl.train",
        "searchrl.evaluate",
    )
    libraries = ("hydra", "omegaconf", "torch", "stable_baselines3", "sb3_contrib", "gymnasium", "pettingzoo")
    for path in (ROOT / "searchrl" / "world").glob("*.py"):
        bad = [m for m in _imports(path) if m.split(".")[0] in libraries or m.startswith(above)]
        assert not bad, (path, bad)


def test_what_runs_before_the_wait_policy_loads_no_torch():
    """The entry points set torch's OpenMP wait policy before torch loads (libgomp reads it once): what they import
    first, the thread settings and the command-line checks, must not load it, nor numba's OpenMP runtime."""
    code = (
        "import sys, searchrl.threads, searchrl.command_line, searchrl.multirun; "
        "print(sorted({'torch', 'numba'} & set(sys.modules)))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "[]", (out.stdout, out.stderr)


def test_importing_the_package_sets_no_environment_variable():
    """The OpenMP wait policy is the entry points' to set (searchrl/threads.py), not an import's."""
    code = "import os, sys; sys.argv += ['-m']; import searchrl.world.engine; print(os.environ.get('OMP_WAIT_POLICY'))"
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "None", out.stderr


def test_unknown_names_are_refused_listing_the_registry():
    names = allowed()
    assert names == ", ".join(HEURISTICS) and "greedy_target" in names
    with pytest.raises(ConfigError, match=rf"controller='planner' is not allowed: one of {names}"):
        heuristic("planner")
    with pytest.raises(ConfigError, match=rf"one of {names}, or checkpoint=<model.zip>"):
        make_controller_factory(OmegaConf.to_object(_compose("controller=greedy", "controller.name=planner")))
    with pytest.raises(
        ConfigError, match=rf"imitation.teacher='random' is not allowed: one of {', '.join(teachers())}"
    ):
        teacher_settings("random")
    assert teachers() == tuple(n for n in HEURISTICS if n != "random")
    with pytest.raises(ConfigError, match=r"greedy takes no setting 'sweep'"):
        make_controller("greedy", WorldConfig(), settings={"sweep": 1})


def test_greedy_target_composes_to_the_spelled_out_greedy_settings():
    named, spelled = _compose("controller=greedy_target"), _compose(*TARGET_GREEDY)
    as_dict = {k: v for k, v in OmegaConf.to_container(named.controller).items() if k != "name"}
    assert as_dict == {k: v for k, v in OmegaConf.to_container(spelled.controller).items() if k != "name"}
    assert (named.controller.name, spelled.controller.name) == ("greedy_target", "greedy")
    # Its own settings still apply on top, and the schema checks them
    assert _compose("controller=greedy_target", "controller.reach=2").controller.reach == 2.0
    # The same controller: class, label, every setting
    world, label, _, factory, _ = make_controller_factory(OmegaConf.to_object(named))
    _, spelled_label, _, spelled_factory, _ = make_controller_factory(OmegaConf.to_object(spelled))
    a, b = factory(world), spelled_factory(world)
    assert type(a) is type(b) is FootprintGreedy and label == spelled_label == "greedy"
    assert {f.name: getattr(a, f.name) for f in fields(HEURISTICS["greedy"].schema) if f.name != "name"} == {
        f.name: getattr(b, f.name) for f in fields(HEURISTICS["greedy"].schema) if f.name != "name"}  # fmt: skip
    assert (a.horizon, a.w_p, a.w_u, a.w_t) == (3, 0.0, 0.0, 1.0)


def test_imitation_takes_greedy_target_and_greedy_with_teacher_args_alike():
    world = WorldConfig(world_size=20, n_agents=2)
    named = make_teacher(teacher_settings("greedy_target"), world, 0)
    spelled = make_teacher(teacher_settings("greedy", {"horizon": 3, "w_p": 0, "w_u": 0, "w_t": 1}), world, 0)
    keys = [k for k in asdict(HEURISTICS["greedy"].schema()) if k != "name"]
    assert {k: getattr(named, k) for k in keys} == {k: getattr(spelled, k) for k in keys}
    assert make_teacher(teacher_settings("greedy_target", {"reach": 2}), world, 0).reach == 2.0


def test_the_library_never_reads_the_tests_folder():
    """The reference oracle is the library's (searchrl/world/oracle.py): no module imports from tests/ or opens a
    path under it (a doc reference to a test file is fine)."""
    for path in (ROOT / "searchrl").rglob("*.py"):
        text = path.read_text()
        assert not [m for m in _imports(path) if m.split(".")[0] == "tests"], path
        assert '/ "tests"' not in text and '"tests/' not in text, path


@dataclass(frozen=True)
class _StripeObstacles:
    """A toy obstacle generator: row `row` walled but for its first cell."""

    kind: ClassVar[str] = "stripe"
    row: int = 2

    def __call__(self, n: int, room: int, rng: np.random.Generator) -> np.ndarray:
        walls = np.zeros((n, n), bool)
        walls[self.row, 1:] = True
        return walls

    def check(self, config: WorldConfig) -> None:
        need(0 <= self.row < config.world_size[0], "scenario.obstacles.row", self.row, "a row of the smallest world")

    @property
    def label(self) -> str:
        return f"stripe{self.row}"


@dataclass
class _StillConfig(ControllerConfig):
    name: str = "still"
    move: int = 0  # the one action every agent takes


class _Still:
    """A toy heuristic: every agent takes action `move` at every step."""

    def __init__(self, config: WorldConfig, move: int = 0) -> None:
        self.move = move

    def reset(self, state, mask) -> None:
        pass

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        return np.full((state.n_worlds, state.n_agents), self.move, np.int64)


@pytest.mark.app  # runs the evaluation app
def test_a_heuristic_and_an_obstacle_generator_added_through_the_public_api_run_in_evaluate(tmp_path, capsys):
    """Adding either is its class plus one registration: `controller=still` and `scenario.obstacles.kind=stripe`
    then compose, are checked and are evaluated like the shipped ones."""
    with mock.patch.dict(registry.HEURISTICS), mock.patch.dict(scenario.OBSTACLES):
        registry.register("still", _Still, _StillConfig, teacher=False)
        scenario.register_part("obstacles", _StripeObstacles)
        register_configs()  # after registering: `controller=still` needs no conf/controller/still.yaml
        scenario.register_part("obstacles", _StripeObstacles)  # the same part again: accepted
        with pytest.raises(ConfigError, match="stripe"):  # another under its name: refused
            scenario.register_part("obstacles", type("OtherStripe", (_StripeObstacles,), {}))
        # a scenario using it, as a conf/scenario/ file would hold it
        ConfigStore.instance().store(
            group="scenario", name="toy_stripe", node={"obstacles": {"kind": "stripe", "row": 3}}
        )
        overrides = ["controller=still", "controller.move=1", "scenario=toy_stripe"]
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            cfg = compose(config_name="evaluate", overrides=[*SLICE, f"out_dir={tmp_path}", *overrides])
            rows = load(evaluate(cfg, overrides))
            bad = [*SLICE, f"out_dir={tmp_path / 'bad'}", *overrides, "scenario.obstacles.row=99"]
            with pytest.raises(SystemExit), exits():
                evaluate(compose(config_name="evaluate", overrides=bad), bad)
    assert "scenario.obstacles.row=99 is not allowed" in capsys.readouterr().err
    assert (
        set(rows["controller"]) == {"still"} and set(rows["scenario"]) == {"stripe3"} and len(rows) == 3 * 3 * 2
    )  # cells x maps x repeats
    assert rows["blocked"].gt(0).any()  # agents walking north from below row 3 run into the stripe
    assert "still" not in registry.HEURISTICS and "stripe" not in scenario.OBSTACLES  # restored for other tests


def test_settings_given_as_a_mapping_are_typed_by_the_heuristics_dataclass():
    """A teacher's arguments, a planner's base rule and a bench's JSON reach a heuristic as a mapping: each value is
    checked against its field's type, as Hydra checks a `controller=` node, in one line naming it; an int where a
    float is asked becomes that float."""
    from searchrl.world.config import in_context

    rule = make_controller("greedy", WorldConfig(), settings={"w_p": 1, "horizon": 2})
    assert isinstance(rule.w_p, float) and rule.horizon == 2
    for settings, message in [
        ({"w_p": "x"}, "controller.w_p='x' is not allowed: a value of type float"),
        ({"horizon": 2.5}, "controller.horizon=2.5 is not allowed: a value of type int"),
        ({"horizon": True}, "controller.horizon=True is not allowed: a value of type int"),
    ]:
        with pytest.raises(ConfigError) as refused:
            make_controller("greedy", WorldConfig(), settings=settings)
        assert str(refused.value) == message
    with pytest.raises(ConfigError) as refused:
        make_controller("surfing", WorldConfig(), settings={"scales": [4, "a"]})
    assert "controller.scales=[4, 'a'] is not allowed: a value of type list[int]" in str(refused.value)
    with pytest.raises(ConfigError) as refused:
        teacher_settings("greedy", {"horizon": "2"})
    assert str(refused.value) == (
        "imitation.teacher_args={'horizon': '2'} is not allowed for teacher 'greedy': "
        "imitation.teacher_args.horizon='2' is not allowed: a value of type int"
    )
    from dataclasses import dataclass

    from searchrl.registry import typed_settings

    @dataclass
    class Shapes:
        pair: tuple[int, str] = (1, "a")
        flag: bool = False
        weights: dict[str, float] = None

    good = typed_settings(Shapes, {"pair": [2, "b"], "flag": np.bool_(True), "weights": {"w": 1}}, "x")
    assert good == {"pair": (2, "b"), "flag": True, "weights": {"w": 1.0}}
    for bad in ({"pair": (1, 2)}, {"pair": (1, "a", 3)}, {"flag": 1}, {"weights": {"w": "heavy"}}):
        with pytest.raises(ConfigError, match=r"^x\.[a-z]+=.* is not allowed: a value of type "):
            typed_settings(Shapes, bad, "x")

    @dataclass
    class PickyConfig(ControllerConfig):
        name: str = "picky"
        level: int = 0

    class Picky:  # a user's rule that refuses a value with a plain ValueError: said as a refusal all the same
        def __init__(self, config, level: int = 0) -> None:
            if level > 1:
                raise ValueError(f"level={level} is not allowed: 0 or 1")

    with mock.patch.dict(registry.HEURISTICS):
        registry.register("picky", Picky, PickyConfig)
        with pytest.raises(ConfigError, match=r"^picky: level=2 is not allowed: 0 or 1$"):
            make_controller("picky", WorldConfig(), settings={"level": 2})
    with pytest.raises(ConfigError) as refused, in_context("grid cell 3"):  # said in its context, its type kept
        raise MissingFile("model.zip is not there")
    assert type(refused.value) is MissingFile and str(refused.value) == "grid cell 3: model.zip is not there"
