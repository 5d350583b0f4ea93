"""Resume and warm starts at their edges: the budget a resume accepts, the scenarios a resumed run draws, the
TensorBoard record a resume leaves, and the step-0 validation of a run started from `init=` weights."""

from __future__ import annotations

import shutil
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from omegaconf import OmegaConf
from sb3_contrib import RecurrentPPO
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

from searchrl.envs.vec_env import SearchVecEnv
from searchrl.multirun import exits
from searchrl.train.app import train
from searchrl.train.callbacks import run_episodes
from searchrl.train.plan import make_plan
from tests.test_train import TINY, _compose, _run

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

Observation = dict[str, np.ndarray]


@dataclass
class Finished:
    run: Path  # a finished tiny run: rollouts of 256 agent-steps, checkpoints at 1024 and 2048, validated every 1024
    first_reset: tuple[int | None, Observation]  # the seed and observation of its rollouts' first reset


def _record_resets(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int | None, Observation]]:
    """Every `SearchVecEnv.reset` from now on appends (the seed it resets the worlds with, the observation)."""
    resets: list[tuple[int | None, Observation]] = []
    reset = SearchVecEnv.reset

    def recording(self: SearchVecEnv) -> Observation:
        seed = self._seeds[0] if self._seeds else None
        obs = reset(self)
        resets.append((seed, {key: value.copy() for key, value in obs.items()}))
        return obs

    monkeypatch.setattr(SearchVecEnv, "reset", recording)
    return resets


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Finished:
    run = tmp_path_factory.mktemp("finished") / "run"
    with pytest.MonkeyPatch.context() as mp:
        resets = _record_resets(mp)
        _run(run, ["+model=b", *TINY])
    assert len(resets) == 1  # the worlds reset themselves after that, inside the VecEnv
    return Finished(run, resets[0])


def _killed(run: Path, to: Path, newest: int = 2048) -> Path:
    """A copy of `run` as if killed after its checkpoint at `newest` agent-steps (events and rows past it stay)."""
    shutil.copytree(run, to)
    (to / "model.zip").unlink()
    for path in (to / "checkpoints").glob("step_*.zip"):
        if int(path.stem.removeprefix("step_")) > newest:
            path.unlink()
    return to


def _resume(run: Path, total_timesteps: int) -> Path:
    overrides = [f"resume={run}", f"total_timesteps={total_timesteps}"]
    return train(_compose(overrides), run / "resumed", overrides)


def _steps(run: Path) -> list[int]:
    return pd.read_csv(run / "progress.csv")["time/total_timesteps"].tolist()


# 1. The budget: not below the steps trained, and equal to them is a resume that trains nothing more.
@pytest.mark.parametrize(
    "budget, trained",
    [(2048, 2048), (2047, 2048), (2304, 2304)],  # equal; one step below, which rounds up to equal; one rollout above
)
def test_resume_accepts_a_budget_not_below_the_steps_trained(tmp_path, finished, budget, trained):
    run = _killed(finished.run, tmp_path / "run")
    final = _resume(run, budget)
    assert final == run / "model.zip" and RecurrentPPO.load(final).num_timesteps == trained
    assert OmegaConf.load(run / "config.yaml").total_timesteps == trained
    more = [] if trained == 2048 else [2304, 2304]  # one more rollout's row and the final validation's
    assert _steps(run) == [*range(256, 2049, 256), 2048, *more]
    assert (run / "score.json").exists()


def test_resume_refuses_a_budget_one_rollout_below_the_steps_trained(tmp_path, finished, capsys):
    run = _killed(finished.run, tmp_path / "run")
    capsys.readouterr()
    with pytest.raises(SystemExit) as exit_, exits():
        _resume(run, 1792)
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert exit_.value.code == 2 and "total_timesteps=1792 is not allowed" in line and ">= 2048" in line, line
    assert not (run / "model.zip").exists()


# 2. A resumed run draws new scenarios: reseeded with the run's seed it would replay the first rollouts' worlds.
def _same(a: Observation, b: Observation) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[key], b[key]) for key in a)


def test_resume_draws_new_scenarios_reproducibly(tmp_path, finished, monkeypatch):
    fresh_seed, fresh = finished.first_reset
    assert fresh_seed == 0  # the fresh run seeds its worlds with the run's seed
    resets = _record_resets(monkeypatch)
    for name in ("one", "two"):
        _resume(_killed(finished.run, tmp_path / name), 2304)
    _resume(_killed(finished.run, tmp_path / "earlier", newest=1024), 1280)
    assert len(resets) == 3
    (seed, resumed), (_, again), (_, earlier) = resets
    assert seed != fresh_seed and not _same(resumed, fresh)  # not the fresh run's first worlds again
    assert _same(resumed, again)  # the same checkpoint resumes to the same worlds
    assert not _same(earlier, resumed) and not _same(earlier, fresh)  # another checkpoint, other worlds


# 3. TensorBoard, like progress.csv, shows each step once after a resume.
def _tensorboard(run: Path) -> dict[str, list[tuple[int, float]]]:
    """(step, value) of every scalar as TensorBoard reads the folder (it purges what a restart marks as gone)."""
    events = EventAccumulator(str(run / "tensorboard"), size_guidance={"scalars": 0})
    events.Reload()
    return {tag: [(e.step, e.value) for e in events.Scalars(tag)] for tag in events.Tags()["scalars"]}


def test_tensorboard_drops_the_killed_segments_events_past_the_checkpoint(tmp_path, finished):
    assert [step for step, _ in _tensorboard(finished.run)["time/fps"]] == [*range(256, 2049, 256)]
    run = _killed(finished.run, tmp_path / "run", newest=1024)  # its events from 1280 to 2048 are in the files
    _resume(run, 2048)
    scalars = _tensorboard(run)
    assert [step for step, _ in scalars["time/fps"]] == [*range(256, 2049, 256)]  # each rollout once
    rows = pd.read_csv(run / "progress.csv")  # trimmed back to the checkpoint, then logged again
    assert rows["time/total_timesteps"].tolist() == [*range(256, 2049, 256), 2048]
    for tag, points in scalars.items():
        if tag == "time/total_timesteps":  # SB3 keeps it out of TensorBoard but for the final validation's row
            continue
        logged = rows.dropna(subset=[tag])
        assert Counter(step for step, _ in points) == Counter(logged["time/total_timesteps"]), tag
    resumed = [value for step, value in scalars["train/value_loss"] if step > 1024]  # the resumed segment's
    assert resumed == pytest.approx(rows[rows["time/total_timesteps"] > 1024]["train/value_loss"].dropna().tolist())


# 4. A run started from init= weights validates them before its first rollout (and its resume does not again).
def test_an_init_run_validates_its_starting_weights_at_step_0(tmp_path, finished):
    source = finished.run / "model.zip"
    overrides = ["+model=b", *TINY, "total_timesteps=256", f"init={source}"]
    run = tmp_path / "init"
    _run(run, overrides)
    rows = pd.read_csv(run / "progress.csv")
    assert rows["time/total_timesteps"].tolist() == [0, 256, 256]  # step 0, the rollout, the final validation
    cfg = _compose(overrides)
    v = cfg.validation
    expected = run_episodes(
        make_plan(cfg).world, int(v.n_worlds), int(v.seed), RecurrentPPO.load(source), v.deterministic
    )
    assert {name: rows[f"val/{name}"].iloc[0] for name in expected} == pytest.approx(expected)  # the init weights
    _resume(run, 512)
    assert _steps(run) == [0, 256, 256, 512, 512]  # one step-0 row: a resume starts from its checkpoint


def test_a_run_resumed_from_its_clone_does_not_validate_step_0_again(tmp_path):
    """A run killed right after its clone resumes from checkpoints/step_0.zip: the clone's step-0 row stays, once."""
    run = tmp_path / "clone"
    clone = ["imitation.teacher=greedy", "imitation.episodes=1", "imitation.epochs=1", "imitation.value_epochs=0"]
    _run(run, ["+model=b", *TINY, "total_timesteps=0", *clone])
    (run / "model.zip").unlink()  # as if killed after the clone's checkpoint and its validation
    assert _steps(run) == [0] and [p.name for p in (run / "checkpoints").glob("*.zip")] == ["step_0.zip"]
    _resume(run, 256)
    assert _steps(run) == [0, 256, 256]


def test_a_run_folder_made_before_scenarios_resumes(tmp_path):
    """tests/golden/run_05d7673: a tiny teacher-term run killed after its checkpoint at 1024 agent-steps, made at
    05d7673 (its config.yaml migrated once: the settings removed since taken out; its checkpoint's policy_kwargs
    still name the network's old context widths, which no load reads). It resumes to 2048 under the paper's scenario
    and its checkpoint evaluates."""
    from searchrl.policies.checkpoint import load_actor
    from searchrl.world.config import WorldConfig
    from searchrl.world.scenario import PAPER

    run = tmp_path / "run"
    shutil.copytree(Path(__file__).resolve().parent / "golden" / "run_05d7673", run)
    old = OmegaConf.load(run / "config.yaml")
    assert "scenario" not in old
    model = _run(run, [f"resume={run}", "total_timesteps=2048"])
    assert RecurrentPPO.load(model).num_timesteps == 2048
    saved = OmegaConf.load(run / "config.yaml")
    assert saved.scenario == PAPER.to_dict()  # the paper's, every part written out
    world = WorldConfig.from_dict(OmegaConf.to_container(old.env.world))
    assert load_actor(run / "checkpoints" / "step_1024.zip", world).n_actions == 5
