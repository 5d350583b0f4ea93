"""A model.zip from anyone cannot run code: every use of a checkpoint loads it without unpickling anything of it.

SB3's `load` unpickles (cloudpickle) the entries of a model.zip's `data` that are not JSON: its policy class,
policy_kwargs, spaces, schedules, buffers. Each test here writes a payload, a pickle whose loading makes a folder
(a visible side effect), into one of those entries or one of the zip's tensor files, checks that plain SB3 does run
it where it would, and that the loaders either load the weights or refuse in one line, and never run it
(searchrl/policies/checkpoint.py). The apps (evaluate, render, `init=`, `resume=`) on such files: tests/test_faults.py.
"""

from __future__ import annotations

import ast
import base64
import io
import json
import os
import shutil
import zipfile
from pathlib import Path

import cloudpickle
import pytest
import torch
from sb3_contrib import RecurrentPPO

from searchrl.policies.checkpoint import REBUILT, load_actor, load_checkpoint
from searchrl.world.config import WorldConfig

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ROOT / "runs" / "reference" / "term" / "b"  # an RL policy: its zip pickles the episode-info buffers too
TENSORS = ("policy.pth", "policy.optimizer.pth", "pytorch_variables.pth")


class Payload:
    """Unpickled, it makes the folder `marker`: what a malicious file would do, visibly."""

    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return os.mkdir, (self.marker,)


def poisoned(run: Path, to: Path, marker: Path, entries: tuple[str, ...] = (), tensor: str | None = None,
             name: str = "model.zip") -> Path:  # fmt: skip
    """A copy of the run folder `run` whose `name` has the payload in each of `entries` of its data (added where
    the file lacks one) and in its tensor file `tensor`."""
    shutil.copytree(run, to, ignore=shutil.ignore_patterns("*.lock", ".lock"))
    path = to / name
    with zipfile.ZipFile(path) as archive:
        members = {info.filename: archive.read(info) for info in archive.infolist()}
    data = json.loads(members["data"])
    for entry in entries:
        pickled = base64.b64encode(cloudpickle.dumps(Payload(marker))).decode()
        data[entry] = {":type:": "<class 'object'>", ":serialized:": pickled}
    members["data"] = json.dumps(data).encode()
    if tensor:
        buffer = io.BytesIO()
        torch.save({"weights": Payload(marker)}, buffer)
        members[tensor] = buffer.getvalue()
    with zipfile.ZipFile(path, "w") as archive:
        for member, content in members.items():
            archive.writestr(member, content)
    return path


def test_the_payload_is_live_for_plain_sb3(tmp_path):
    """The test's payload does run where SB3 unpickles: what the loaders below must never do."""
    marker = tmp_path / "ran"
    path = poisoned(SHIPPED, tmp_path / "run", marker, entries=("policy_kwargs",))
    with pytest.raises(Exception):  # noqa: B017 (the payload returns None for policy_kwargs; SB3 then fails)
        RecurrentPPO.load(path)
    assert marker.exists()


@pytest.mark.parametrize("entry", REBUILT)
def test_no_pickled_entry_is_unpickled(tmp_path, entry):
    """Each entry a searchrl model pickles is rebuilt: the weights load, the actor acts, the payload never runs."""
    marker = tmp_path / "ran"
    path = poisoned(SHIPPED, tmp_path / "run", marker, entries=(entry,))
    world = WorldConfig.from_dict(_world(SHIPPED))
    actor = load_actor(path, world)
    shipped = load_checkpoint(SHIPPED / "model.zip", device="cpu").policy.state_dict()
    for key, value in load_checkpoint(path, device="cpu").policy.state_dict().items():
        assert torch.equal(value, shipped[key]), key
    assert actor.n_actions == world.n_actions and not marker.exists()


def _world(run: Path) -> dict:
    from searchrl.policies.checkpoint import checkpoint_config

    return checkpoint_config(run / "model.zip")[0]


@pytest.mark.parametrize("path", sorted((ROOT / "runs" / "reference").rglob("model.zip")), ids=lambda p: p.parent.name)
def test_every_shipped_policy_loads_the_weights_plain_sb3_loads(path):
    """load_checkpoint builds each shipped policy from its config alone; plain SB3 (a trusted file) agrees."""
    ours, plain = load_checkpoint(path, device="cpu"), RecurrentPPO.load(path, device="cpu")
    assert ours.policy.state_dict().keys() == plain.policy.state_dict().keys()
    assert all(torch.equal(v, plain.policy.state_dict()[k]) for k, v in ours.policy.state_dict().items())
    assert ours.observation_space == plain.observation_space and ours.action_space == plain.action_space


@pytest.mark.parametrize("tensor", TENSORS)
def test_tensors_are_read_as_weights_only(tmp_path, tensor):
    marker = tmp_path / "ran"
    path = poisoned(SHIPPED, tmp_path / "run", marker, tensor=tensor)
    with pytest.raises(ValueError, match=r"cannot be read as a recurrent_ppo model .*Weights only load failed") as err:
        load_checkpoint(path, device="cpu")
    assert "\n" not in str(err.value) and not marker.exists()


def test_a_pickled_entry_searchrl_does_not_rebuild_is_refused(tmp_path):
    marker = tmp_path / "ran"
    path = poisoned(SHIPPED, tmp_path / "run", marker, entries=("learning_rate",))
    with pytest.raises(ValueError, match="holds a pickled 'learning_rate' entry that searchrl does not rebuild"):
        load_actor(path, WorldConfig.from_dict(_world(SHIPPED)))
    assert not marker.exists()


# Calls that would read a model.zip by unpickling: only searchrl/policies/checkpoint.py may open one (without it).
SAFE_LOADERS = {"json", "OmegaConf", "yaml", "np", "numpy"}  # modules whose .load reads no pickle (np's by default)


def checkpoint_openers(source: str, name: str = "<source>") -> list[str]:
    """`name:line call` for each call that could unpickle a file: an SB3 class's `X.load(...)`,
    `load_from_zip_file`, `json_to_data`, a pickle or cloudpickle load, and `torch.load` without
    `weights_only=True`."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.Call):
            continue
        call = ast.unparse(node.func)
        owner, _, attr = call.rpartition(".")
        weights_only = any(k.arg == "weights_only" and ast.unparse(k.value) == "True" for k in node.keywords)
        if (
            (attr == "load" and owner and owner not in SAFE_LOADERS and not (owner == "torch" and weights_only))
            or attr in {"load_from_zip_file", "json_to_data"}
            or (owner in {"pickle", "cloudpickle"} and attr in {"load", "loads"})
        ):
            found.append(f"{name}:{node.lineno} {call}(...)")
    return found


def test_only_the_checkpoint_module_opens_checkpoints():
    """The notebooks and the package reach a model.zip through load_checkpoint / load_actor alone."""
    sources = [*sorted((ROOT / "searchrl").rglob("*.py")), *sorted((ROOT / "analysis").glob("*.py"))]
    found = [f for path in sources if path.name != "checkpoint.py"
             for f in checkpoint_openers(path.read_text(), str(path.relative_to(ROOT)))]  # fmt: skip
    assert not found, found
    planted = (
        "RecurrentPPO.load(p)\ntype(m).load(p)\ntorch.load(f)\ntorch.load(f, weights_only=True)\npickle.loads(b)\n"
    )
    assert [f.split(" ")[1] for f in checkpoint_openers(planted)] == [
        "RecurrentPPO.load(...)", "type(m).load(...)", "torch.load(...)", "pickle.loads(...)"]  # fmt: skip
