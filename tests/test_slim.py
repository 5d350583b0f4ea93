"""Shipped checkpoints without optimiser moments or last rollout: the same weights, loadable as they are, and every
shipped `model.zip` slim (a folder of 1.6 MB files, not 6 MB ones)."""

from __future__ import annotations

import io
import zipfile
from dataclasses import asdict
from pathlib import Path

import pytest
import torch
from omegaconf import OmegaConf

from searchrl.policies.checkpoint import load_checkpoint, policy_record, run_config
from searchrl.policies.slim import is_slim, main, slim_checkpoint, weights_sha256

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "runs" / "reference").rglob("model.zip"))


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny RecurrentPPO after one update: optimiser moments and a last rollout in its zip."""
    from sb3_contrib import RecurrentPPO

    from searchrl.envs.vec_env import SearchVecEnv
    from tests.test_teacher_term import EXTRACTOR, WORLD, _model

    model = _model(RecurrentPPO, SearchVecEnv(WORLD, n_worlds=2, seed=0))
    model.learn(48)
    path = tmp_path_factory.mktemp("run") / "model.zip"
    model.save(path)
    run = {"env": {"world": asdict(WORLD)}, "network": {**EXTRACTOR, "lstm_hidden_size": 16},
           "algo": {"name": "recurrent_ppo", "learning_rate": model.learning_rate, "clip_range": 0.2}}  # fmt: skip
    OmegaConf.save(OmegaConf.create(run), path.parent / "config.yaml")  # what load_checkpoint builds the model from
    return path


def test_slimming_keeps_the_weights_and_the_file_loads(trained, tmp_path):
    out = slim_checkpoint(trained, tmp_path / "slim.zip")
    assert not is_slim(trained) and is_slim(out)
    assert weights_sha256(out) == weights_sha256(trained)
    assert out.stat().st_size < trained.stat().st_size
    full, slim = (load_checkpoint(p, policy_record(run_config(trained), trained), device="cpu") for p in (trained, out))
    for name, value in full.policy.state_dict().items():
        assert torch.equal(slim.policy.state_dict()[name], value), name
    assert slim.num_timesteps == full.num_timesteps and not slim.policy.optimizer.state
    with zipfile.ZipFile(out) as a, zipfile.ZipFile(trained) as b:
        assert a.namelist() == b.namelist()


def _as_saved_on_a_gpu(path: Path, out: Path) -> Path:
    """`path` with its optimiser's tensors tagged `cuda:0`, as a checkpoint written by a training on a GPU is: torch's
    loader then refuses it on a machine without CUDA unless told where to map it."""
    with zipfile.ZipFile(path) as archive:
        members = {name: archive.read(name) for name in archive.namelist()}
    inner = io.BytesIO(members["policy.optimizer.pth"])
    with zipfile.ZipFile(inner) as pth:
        parts = {info: pth.read(info.filename) for info in pth.infolist()}
    retagged = io.BytesIO()
    with zipfile.ZipFile(retagged, "w") as pth:
        for info, content in parts.items():
            if info.filename.endswith("data.pkl"):  # the storages' location, a protocol-2 string: X, length, bytes
                content = content.replace(b"X\x03\x00\x00\x00cpu", b"X\x06\x00\x00\x00cuda:0")
            pth.writestr(info, content)
    members["policy.optimizer.pth"] = retagged.getvalue()
    with zipfile.ZipFile(out, "w") as archive:
        for name, content in members.items():
            archive.writestr(name, content)
    return out


@pytest.mark.skipif(torch.cuda.is_available(), reason="a GPU's checkpoint is read as it is where CUDA is")
def test_a_checkpoint_written_on_a_gpu_is_slimmed_and_resumed_on_a_cpu(trained, tmp_path):
    gpu = _as_saved_on_a_gpu(trained, tmp_path / "gpu.zip")
    with zipfile.ZipFile(gpu) as archive, pytest.raises(RuntimeError, match="CUDA"):
        torch.load(io.BytesIO(archive.read("policy.optimizer.pth")), weights_only=True)  # the fixture is what it says
    assert not is_slim(gpu)
    out = slim_checkpoint(gpu, tmp_path / "slim.zip")
    assert is_slim(out) and weights_sha256(out) == weights_sha256(trained)
    model = load_checkpoint(gpu, policy_record(run_config(trained), trained), device="cpu")  # resume= on a CPU machine
    assert model.policy.optimizer.state and all(
        t.device.type == "cpu" for s in model.policy.optimizer.state.values() for t in s.values() if torch.is_tensor(t)
    )


def test_the_command_refuses_a_missing_path_in_one_line(tmp_path, capsys):
    assert main([str(tmp_path / "nope.zip")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.parametrize("path", SHIPPED, ids=[str(p.parent.relative_to(ROOT / "runs" / "reference")) for p in SHIPPED])
def test_every_shipped_checkpoint_is_slim(path):
    assert is_slim(path), f"{path} holds optimiser state or a last rollout: python -m searchrl.policies.slim {path}"
