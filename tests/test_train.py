"""The training app: tiny runs of every model, reload and predict, resume after a kill, errors, sweeps."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf
from sb3_contrib import RecurrentPPO

from searchrl.multirun import exits
from searchrl.shared_schema import CONF_DIR
from searchrl.train.app import train
from searchrl.train.build import load_algorithm, make_vec_env
from searchrl.train.plan import make_plan

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
# A few thousand agent-steps: 2048, in rollouts of 2 worlds × 4 agents × 32 steps = 256 agent-steps.
TINY = [
    "total_timesteps=2048",
    "env.n_worlds=2",
    "env.world.n_agents=4",
    "env.world.world_size=[12,20]",
    "env.world.n_targets=[2,4]",
    "env.world.n_distributions=[4,8]",
    "network=small",
    "algo.batch_size=128",
    "checkpoint_every=1024",
    "validation.every=1024",
    "validation.n_worlds=2",
    "progress_bar=false",
    "threads=1",
]


def _compose(overrides: list[str]):
    """The config the app composes from this command line."""
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        return compose(config_name="train", overrides=overrides)


def _run(tmp_path: Path, overrides: list[str]) -> Path:
    return train(_compose(overrides), tmp_path, overrides)


# B in the default run; A and C train in test_multirun_sweeps, the diagonal model in tests/test_evaluate.py
@pytest.mark.parametrize("model", [pytest.param(m, marks=pytest.mark.slow) if m != "b" else m
                                   for m in ("a", "b", "c", "diagonal")])  # fmt: skip
def test_tiny_run_trains_saves_reloads_and_predicts(tmp_path, model):
    final = _run(tmp_path, [f"+model={model}", *TINY])
    assert final == tmp_path / "model.zip" and final.exists()
    assert sorted(p.name for p in (tmp_path / "checkpoints").glob("*.zip")) == ["step_1024.zip", "step_2048.zip"]
    if model == "b":  # retention: only the newest keep_checkpoints stay
        _run(tmp_path / "keep", [f"+model={model}", *TINY, "checkpoint_every=256", "keep_checkpoints=2"])
        assert sorted(p.name for p in (tmp_path / "keep" / "checkpoints").iterdir()) == [
            "step_1792.zip",
            "step_2048.zip",
        ]
    assert (tmp_path / "config.yaml").exists() and any((tmp_path / "tensorboard").iterdir())
    rows = list(csv.DictReader(open(tmp_path / "progress.csv")))
    # one row per rollout, then the final model's validation (with the last update's losses) and its score
    assert [int(r["time/total_timesteps"]) for r in rows] == [*range(256, 2049, 256), 2048]
    assert rows[-1]["val/found_fraction"] and rows[-1]["train/value_loss"]
    score = json.loads((tmp_path / "score.json").read_text())
    validated = [
        (int(r["time/total_timesteps"]), float(r["val/found_fraction"])) for r in rows if r["val/found_fraction"]
    ]
    assert [step for step, _ in validated] == [1024, 2048]  # the last rollout's is the final model's, not a second
    assert score["validations"] == 2 and score["score"] == pytest.approx(np.mean([f for _, f in validated]))
    plan = make_plan(_compose([f"+model={model}", *TINY]))
    env = make_vec_env(plan, seed=0)
    loaded = load_algorithm(plan, str(final), env)
    assert loaded.num_timesteps == 2048
    assert loaded.action_space.n == (9 if model == "diagonal" else 5)
    obs = env.reset()
    actions, state = loaded.predict(obs, episode_start=np.ones(env.num_envs, bool))
    assert actions.shape == (8,) and ((actions >= 0) & (actions < loaded.action_space.n)).all()
    assert state[0].shape == (1, 8, 128)  # (layers, slots, lstm_hidden_size) of network=small


def test_mixed_team_sizes_train_in_one_rollout(tmp_path):
    """env.extra_teams adds a group of worlds with N = 6 beside the 2 worlds of N = 4: 2·4 + 1·6 slots."""
    mixed = [*TINY, "env.extra_teams=[{n_agents:6,n_worlds:1}]", "validation.every=0"]
    final = _run(tmp_path, ["+model=b", *mixed])
    plan = make_plan(_compose(["+model=b", *mixed]))
    env = make_vec_env(plan, seed=0)
    assert env.num_envs == 14 and env.get_attr("n_agents", indices=[7, 8]) == [4, 6]
    sized = make_vec_env(
        make_plan(_compose(["+model=b", *TINY, "env.extra_teams=[{n_agents:6,n_worlds:1,world_size:[30,40]}]"]))
    )
    assert [w.config.world_size for w in sized.envs] == [(12, 20), (30, 40)]  # its own n range, others keep theirs
    loaded = load_algorithm(plan, str(final), env)
    assert loaded.num_timesteps >= 2048
    actions, _ = loaded.predict(env.reset(), episode_start=np.ones(14, bool))
    assert actions.shape == (14,)
    rows = list(csv.DictReader(open(tmp_path / "progress.csv")))
    assert rows and rows[-2]["team/found_fraction"]  # the last rollout's row; the final one is the validation's


def test_imitation_warm_start_clones_before_rl(tmp_path):
    """imitation.teacher=surfing clones surfing first: imitation.csv has one row per epoch, imitation.zip is the
    clone, and RL then trains on from it to the usual model.zip."""
    overrides = ["+model=b", *TINY, "validation.every=0", "imitation.teacher=surfing", "imitation.episodes=1",
                 "imitation.epochs=2", "imitation.value_epochs=1", "imitation.batch_sequences=4"]  # fmt: skip
    final = _run(tmp_path, overrides)
    rows = list(csv.DictReader(open(tmp_path / "imitation.csv")))
    assert [(int(r["epoch"]), r["phase"]) for r in rows] == [(1, "policy"), (2, "policy"), (3, "value")]
    assert 0.0 < float(rows[0]["teacher_found_fraction"]) <= 1.0
    clone = RecurrentPPO.load(tmp_path / "imitation.zip")
    trained = RecurrentPPO.load(final)
    assert clone.num_timesteps == 0 and trained.num_timesteps >= 2048
    # The clone is also the run's first checkpoint: a kill before the first RL checkpoint resumes from it.
    first = RecurrentPPO.load(tmp_path / "checkpoints" / "step_0.zip").policy.state_dict()
    for name, value in clone.policy.state_dict().items():
        assert torch.equal(value, first[name]), name


def test_clone_only_run_saves_the_clone_as_its_model(tmp_path):
    """total_timesteps=0 with a teacher runs no RL: model.zip is imitation.zip's policy, at step 0."""
    overrides = ["+model=b", *TINY, "total_timesteps=0", "validation.every=0", "imitation.teacher=greedy",
                 "imitation.episodes=1", "imitation.epochs=1", "imitation.value_epochs=0"]  # fmt: skip
    final = _run(tmp_path, overrides)
    model, clone = RecurrentPPO.load(final), RecurrentPPO.load(tmp_path / "imitation.zip")
    assert model.num_timesteps == 0
    for name, value in clone.policy.state_dict().items():
        assert torch.equal(value, model.policy.state_dict()[name]), name


def test_init_copies_policy_weights_only(tmp_path, capsys):
    """init=<zip> starts a fresh run (step 0, fresh optimiser) from another run's weights; a zip of another
    network is refused with the reason."""
    from searchrl.train.build import init_weights, make_algorithm

    source = _run(tmp_path / "source", ["+model=b", *TINY, "validation.every=0"])
    plan = make_plan(_compose(["+model=b", *TINY]))
    model = make_algorithm(plan, make_vec_env(plan))
    init_weights(model, str(source), plan.policy_record())
    loaded = RecurrentPPO.load(source)
    for name, value in loaded.policy.state_dict().items():
        torch.testing.assert_close(model.policy.state_dict()[name], value)
    assert model.num_timesteps == 0 and not model.policy.optimizer.state_dict()["state"]
    wider = make_plan(_compose(["+model=b", *TINY, "network.lstm_hidden_size=16"]))
    other = make_algorithm(wider, make_vec_env(wider))
    with pytest.raises(ValueError, match="does not fit this run's policy"):
        init_weights(other, str(source), wider.policy_record())


@pytest.mark.slow  # resume after a kill is in the default run
def test_resume_of_an_initialised_run_needs_no_init_file(tmp_path):
    """A run started with init= resumes from its own checkpoint even after the init file is gone."""
    source = _run(tmp_path / "source", ["+model=b", *TINY, "validation.every=0"])
    copy = tmp_path / "init.zip"
    copy.write_bytes(source.read_bytes())
    run = tmp_path / "run"
    _run(run, ["+model=b", *TINY, "validation.every=0", f"init={copy}"])
    copy.unlink()
    overrides = [f"resume={run}", "total_timesteps=2304"]
    final = train(_compose(overrides), run / "resumed", overrides)
    assert RecurrentPPO.load(final).num_timesteps == 2304  # one rollout (256 agent-steps) past the 2048 trained


def test_a2c_trains(tmp_path):
    algo = "a2c"
    tiny = [o for o in TINY if algo != "a2c" or "batch_size" not in o]  # A2C has no minibatches
    final = _run(tmp_path, ["+model=c", f"algo={algo}", *tiny])
    assert final.exists()


def test_same_seed_same_run_on_one_thread(tmp_path):
    params = []
    for name in ("one", "two"):
        final = _run(tmp_path / name, ["+model=b", *TINY])  # validation on: it samples from torch's RNG too
        params.append(RecurrentPPO.load(final).policy.state_dict())
    for key, value in params[0].items():
        torch.testing.assert_close(value, params[1][key], rtol=0, atol=0)


def _adam_steps(path: Path) -> int:
    optimizer = RecurrentPPO.load(path).policy.optimizer
    return int(next(iter(optimizer.state.values()))["step"])


def test_resume_after_kill_loses_nothing(tmp_path):
    run_dir = tmp_path / "run"
    cmd = [sys.executable, "-m", "searchrl.train", "+model=b", *TINY, "total_timesteps=1000000",
           "checkpoint_every=1024", "validation.every=0", f"hydra.run.dir={run_dir}"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (run_dir / "checkpoints" / "step_2048.zip").exists():
            assert proc.poll() is None, proc.stderr.read().decode()
            assert time.monotonic() < deadline, "no checkpoint within 120 s"
            time.sleep(0.05)
    finally:  # killed whatever happened above: the run would train a million agent-steps
        with contextlib.suppress(ProcessLookupError):  # ended already
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert not (run_dir / "model.zip").exists()
    assert not list((run_dir / "checkpoints").glob(".*"))  # no partial file where a checkpoint should be
    # A run saved by an older version lacks newer fields: resume must fill them from the schema.
    saved = (run_dir / "config.yaml").read_text()
    (run_dir / "config.yaml").write_text("\n".join(x for x in saved.splitlines() if "keep_checkpoints" not in x))
    before = (run_dir / "checkpoints" / "step_2048.zip").stat().st_mtime_ns

    final = _run(tmp_path / "unused", [f"resume={run_dir}", "total_timesteps=4096"])
    assert final == run_dir / "model.zip"
    resumed = RecurrentPPO.load(final)
    assert resumed.num_timesteps == 4096
    # 4096 / 256 = 16 rollouts, each 4 epochs × 2 minibatches of 128: optimiser state carried across the kill.
    assert _adam_steps(final) == 16 * 4 * 2
    steps = [int(r["time/total_timesteps"]) for r in csv.DictReader(open(run_dir / "progress.csv"))]
    assert steps == [*range(256, 4097, 256), 4096]  # no gap and no duplicate row; then the final validation
    assert (run_dir / "checkpoints" / "step_2048.zip").stat().st_mtime_ns == before  # not saved again
    record = OmegaConf.load(run_dir / "config.yaml")  # the run's record holds the budget it was trained to
    assert record.total_timesteps == 4096 and record.keep_checkpoints == 3 and record.resume is None
    assert sorted(p.name for p in (run_dir / "checkpoints").glob("*.zip")) == [
        "step_2048.zip", "step_3072.zip", "step_4096.zip"]  # fmt: skip


def test_bad_input_fails_before_work(tmp_path, capsys):
    """One line, exit status 2, no run folder: through the command line once, then through the app in-process."""
    cmd = [sys.executable, "-m", "searchrl.train", "+model=surfing", f"hydra.run.dir={tmp_path}/x"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stderr.count("\n") == 1 and "heuristic controller" in out.stderr
    assert "searchrl.evaluate controller=surfing" in out.stderr and not (tmp_path / "x").exists()

    def refused(*args: str) -> str:
        capsys.readouterr()
        with pytest.raises(SystemExit) as stop, exits():
            train(_compose(list(args)), tmp_path / "x", list(args))
        assert stop.value.code == 2
        return capsys.readouterr().err

    assert "trainable models: a, b, c, diagonal" in refused()
    assert "fov=4" in refused("+model=c", "env.world.fov=4")
    assert "algo.batch_size=0" in refused("+model=c", "algo.batch_size=0")
    assert "error: validation.every=-1 is not allowed: >= 0 agent-steps" in refused("+model=c", "validation.every=-1")
    assert "error: validation.score_last=0 is not allowed: >= 1" in refused("+model=c", "validation.score_last=0")
    assert "no config.yaml" in refused("+model=c", f"resume={tmp_path}")
    (tmp_path / "bad" / "checkpoints").mkdir(parents=True)
    (tmp_path / "bad" / "config.yaml").write_text("seed: not-a-number\n")
    (tmp_path / "bad" / "checkpoints" / "step_256.zip").write_bytes(b"")
    assert "does not fit the current schema" in refused(f"resume={tmp_path / 'bad'}")
    assert not (tmp_path / "x" / "config.yaml").exists()  # Hydra makes the folder; the app writes nothing


@pytest.mark.slow  # a training multirun: tests/test_sweep.py runs one in the default run
@pytest.mark.parametrize("launcher", ["local", "submitit_local"])
def test_multirun_sweeps(tmp_path, launcher):
    cmd = [sys.executable, "-m", "searchrl.train", "-m", f"hydra/launcher={launcher}", "+model=a,c", *TINY,
           "total_timesteps=256", "validation.every=0", f"hydra.sweep.dir={tmp_path}"]  # fmt: skip
    if launcher == "submitit_local":
        cmd += ["hydra.launcher.timeout_min=5", "hydra.launcher.cpus_per_task=1"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    models = sorted(tmp_path.glob("*/model.zip"))
    assert len(models) == 2, [str(p) for p in tmp_path.rglob("*")][:40]
    assert [p.parent.name.split(",")[0] for p in models] == ["0_model=a", "1_model=c"]  # named by their overrides


@pytest.mark.parametrize(
    "override, message",
    [
        ("env.world.fov=3 env.world.explicit_area=3", "env.world.fov=3"),
        ("env.world.unc_variance_scale=0.01", "variance_floor"),
        ("algo.name=a2c", "algo.name='a2c' does not match"),
        ("algo.n_epochs=0", "algo.n_epochs=0"),
        ("network.lstm_hidden_size=0", "network.lstm_hidden_size=0"),
        ("keep_checkpoints=0", "keep_checkpoints=0"),
        ("env.extra_teams=[{n_agents:0,n_worlds:1}]", r"env.extra_teams\[0\]: n_agents=0"),
        ("env.extra_teams=[{n_agents:8,n_worlds:0}]", r"env.extra_teams\[0\].n_worlds=0"),
        ("env.extra_teams=[{n_agents:8,n_worlds:1,world_size:[40,4]}]", r"env.extra_teams\[0\]: world_size"),
        ("init=/nowhere/model.zip", "init='/nowhere/model.zip' is not allowed: an existing model.zip"),
        ("imitation.teacher=planner", "imitation.teacher='planner' is not allowed"),
        ("total_timesteps=0", "total_timesteps=0 is not allowed"),
        ("total_timesteps=-5 imitation.teacher=greedy", "total_timesteps=-5 is not allowed"),
        ("imitation.teacher=surfing imitation.epochs=-1", "imitation.epochs=-1"),
        ("imitation.teacher=greedy imitation.rl_weight=-1", "imitation.rl_weight=-1"),
        ("imitation.rl_weight=1", "imitation.rl_weight=1.0 is not allowed: 0 without imitation.teacher"),
        ("imitation.teacher=greedy imitation.rl_weight=1 imitation.rl_schedule=cosine", "imitation.rl_schedule"),
        ("imitation.critic_warmup=-2", "imitation.critic_warmup=-2"),
        ("algo=a2c imitation.critic_warmup=2", "algo='a2c' is not allowed: one of recurrent_ppo "),
        ("imitation.teacher=greedy +imitation.teacher_args.sweep=2", r"imitation.teacher_args=\{'sweep': 2\}"),
        ("imitation.teacher=greedy +imitation.teacher_args.contested=2", "contested=2"),
        ("imitation.teacher=surfing imitation.learning_rate=0", "imitation.learning_rate=0"),
        ("imitation.teacher=greedy imitation.value_epochs=-1", "imitation.value_epochs=-1"),
        ("imitation.teacher=greedy imitation.lr_schedule=cosine", "imitation.lr_schedule='cosine'.*constant, linear"),
        ("threads=100000", "threads=100000 is not allowed: 1 <= threads <= 1024"),
        ("env.world.lam=2", "lam=2.0 is not allowed: lam"),
    ],
)
def test_check_config_names_the_bad_value(override, message):

    with pytest.raises(ValueError, match=message.replace("(", r"\(")):
        make_plan(_compose(["+model=b", *override.split()]))


def test_slurm_launcher_config_composes():
    cmd = [sys.executable, "-m", "searchrl.train", "hydra/launcher=slurm", "+model=a", "--cfg", "hydra"]
    out = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "SlurmLauncher" in out.stdout and "cpus_per_task: 8" in out.stdout


def test_a_run_trains_validates_and_records_its_scenario(tmp_path, monkeypatch):
    """`scenario=walls`: the rollout's, the teacher's and the validation's worlds all draw walls, and config.yaml
    records the scenario."""
    from searchrl.world import reset

    seen = []
    original = reset.reset_world
    monkeypatch.setattr(reset, "reset_world", lambda *a, **k: seen.append(a[4].label) or original(*a, **k))
    _run(tmp_path, ["+model=b", *TINY, "total_timesteps=256", "scenario=walls", "scenario.obstacles.density=0.1",
                    "imitation.teacher=greedy_target", "imitation.episodes=1", "imitation.epochs=1"])  # fmt: skip
    assert set(seen) == {"iid0.1c"} and len(seen) > 2 * 8  # rollout, teacher and validation worlds
    saved = OmegaConf.load(tmp_path / "config.yaml")
    assert saved.scenario == {
        "obstacles": {"kind": "iid", "density": 0.1, "connected": True},
        "prior": {"kind": "mixture", "variance_scale": None},
        "targets": {"kind": "prior"},
    }


def test_a_machine_replicates_every_group_of_worlds_and_minibatches_are_whole_slots():
    """machine=cpu16 takes each of B's recipe's groups of worlds four times (the team mix stays) and a minibatch
    four times larger; env.replicas below 1 and a minibatch that is not whole slots are refused by name."""
    from searchrl.world.config import ConfigError

    base, big = (make_plan(_compose(["+experiment=term/b", *m])) for m in ([], ["machine=cpu16"]))
    assert [(w.n_agents, 4 * k) for w, k in base.groups] == [(w.n_agents, k) for w, k in big.groups]
    assert big.rollout == 4 * base.rollout and big.settings.algo.batch_size == 4 * base.settings.algo.batch_size
    assert big.settings.threads == 16 and big.settings.device == "cpu"
    refused = {"env.replicas=0": "env.replicas=0 is not allowed",
               "algo.batch_size=1000": "algo.batch_size=1000 is not allowed: a multiple of algo.n_steps"}  # fmt: skip
    for bad, message in refused.items():
        with pytest.raises(ConfigError, match=message):
            make_plan(_compose(["+model=b", bad]))
