"""The torch device of a policy's network (searchrl/policies/device.py): evaluation's `device=`, render's and bench
eval's and policy's `--device`. A device asked for and missing, or not a device, is one line naming it with what is
allowed, exit status 2, before any work or file; `cpu` given explicitly is the default's run. Written for any
machine: "missing" is `cuda` where torch sees no CUDA device and `cuda:99` where it sees one."""

from __future__ import annotations

import pytest
import torch
from omegaconf import OmegaConf

from searchrl.bench.__main__ import main as bench
from searchrl.evaluate.results import load
from searchrl.policies.device import check_device, resolve_device
from searchrl.render import main as render
from searchrl.world.config import ConfigError
from tests.test_faults import REFERENCE_B, _evaluate, _refused

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

CHECKPOINT = str(REFERENCE_B / "model.zip")
MISSING = ["gpu7", "cuda:99" if torch.cuda.is_available() else "cuda"]  # malformed; a device torch does not see
SMALL_EPISODE = ["--n", "20", "--agents", "2", "--targets", "2", "--distributions", "4", "--cell", "1"]


def test_check_device_names_the_value_and_what_is_allowed():
    check_device("cpu")
    check_device("auto")
    assert resolve_device("auto").type == ("cuda" if torch.cuda.is_available() else "cpu")
    assert resolve_device("cpu") == torch.device("cpu")
    with pytest.raises(ConfigError, match=r"^--device='gpu7' is not allowed: cpu, cuda, cuda:<index>, mps or auto"):
        check_device("gpu7", "--device")
    with pytest.raises(ConfigError, match=r"^device='cuda:99' is not allowed: (cpu here|a CUDA index below)"):
        check_device("cuda:99")
    with pytest.raises(ConfigError, match=r"^device='meta' is not allowed: cpu, cuda"):
        check_device("meta")  # a torch device, but not one a network runs on here


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
def test_cuda_without_cuda_says_so():
    with pytest.raises(ConfigError, match=r"device='cuda' is not allowed: cpu here: torch sees no CUDA device"):
        check_device("cuda")


@pytest.mark.parametrize("device", MISSING)
def test_evaluation_refuses_a_missing_device_before_any_file(tmp_path, capsys, device):
    out = tmp_path / "eval"
    _refused(capsys, lambda: _evaluate(out, f"checkpoint={CHECKPOINT}", f"device={device}"), f"device={device!r}")
    assert not out.exists()


def test_evaluation_on_the_cpu_named_is_the_default_run_and_records_its_device(tmp_path):
    named = _evaluate(tmp_path / "named", f"checkpoint={CHECKPOINT}", "device=cpu")
    default = _evaluate(tmp_path / "default", f"checkpoint={CHECKPOINT}")
    assert load(named).equals(load(default))
    assert OmegaConf.load(named / "evaluation.yaml").device == "cpu"
    assert (named / "evaluation.yaml").read_text() == (default / "evaluation.yaml").read_text()
    _evaluate(tmp_path / "default", f"checkpoint={CHECKPOINT}", "device=cpu")  # resumes the default's folder


def test_a_heuristic_runs_on_the_cpu(tmp_path, capsys, monkeypatch):
    """With a CUDA device present (pretended: the refusal comes before any use of it), `device=cuda` is refused for
    a heuristic, which has no network; `device=auto` and `cpu` are what it does anyway."""
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    out = tmp_path / "eval"
    _refused(capsys, lambda: _evaluate(out, "device=cuda"), "device='cuda'", "controller=surfing runs on the CPU")
    with pytest.raises(SystemExit) as exit_:
        render(["--device", "cuda", *SMALL_EPISODE, "--out", str(tmp_path / "x.gif")])
    assert exit_.value.code == 2 and "cpu without --checkpoint" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        bench(["eval", "--device", "cuda"])
    assert exit_.value.code == 2 and "cpu without --checkpoint" in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "x.gif").exists()


@pytest.mark.parametrize("device", MISSING)
def test_render_refuses_a_missing_device_before_any_file(tmp_path, capsys, device):
    out = tmp_path / "gifs" / "x.gif"
    args = ["--checkpoint", CHECKPOINT, "--device", device, *SMALL_EPISODE, "--out", str(out)]
    _refused(capsys, lambda: render(args), f"--device={device!r}", "is not allowed")
    assert not out.parent.exists()


def test_render_on_the_cpu_named(tmp_path, capsys):
    out = tmp_path / "x.gif"
    assert render(["--checkpoint", CHECKPOINT, "--device", "cpu", *SMALL_EPISODE, "--out", str(out)]) == 0
    assert out.stat().st_size > 0 and "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("suite", ["eval", "policy"])
@pytest.mark.parametrize("device", MISSING)
def test_bench_refuses_a_missing_device_before_any_measurement(capsys, monkeypatch, suite, device):
    monkeypatch.setattr("searchrl.bench.evaluate.run", lambda *a, **k: pytest.fail("measured"))
    monkeypatch.setattr("searchrl.bench.policy.run", lambda *a, **k: pytest.fail("measured"))
    args = [suite, "--checkpoint", CHECKPOINT, "--device", device]
    _refused(capsys, lambda: bench(args), f"--device={device!r}", "is not allowed")


def test_bench_passes_the_device_it_checked(monkeypatch):
    """eval and policy hand the checked device to their measurement (the measurements themselves take minutes:
    every Table 2 cell, or seconds per engine); a heuristic's eval runs on the CPU."""
    seen: list[tuple[str, object]] = []
    monkeypatch.setattr("searchrl.bench.evaluate.run", lambda *a, **k: seen.append(("eval", a[4])) or [])
    monkeypatch.setattr("searchrl.bench.policy.run", lambda *a, **k: seen.append(("policy", k["device"])) or [])
    assert bench(["eval", "--checkpoint", CHECKPOINT, "--device", "cpu"]) == 0
    assert bench(["policy", "--checkpoint", CHECKPOINT, "--device", "cpu"]) == 0
    assert bench(["eval", "--controller", "random"]) == 0
    assert seen == [("eval", "cpu"), ("policy", "cpu"), ("eval", "cpu")]


def test_bench_policy_on_the_cpu_named(capsys):
    """The SB3 and actor engines both run, on the device named, and say which."""
    assert bench(["policy", "--checkpoint", CHECKPOINT, "--device", "cpu", "--seconds", "0.05", "--json"]) == 0
    rows = [line for line in capsys.readouterr().out.splitlines() if line.startswith("{")]
    assert len(rows) == 5 and all('"device": "cpu"' in row for row in rows)
