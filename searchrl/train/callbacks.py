"""SB3 callbacks of the training app: team metrics, atomic checkpoints, validation on fixed worlds, and the stop a
SIGTERM or SIGINT asks for (`Preemption`).

Validation plays a policy's episodes on a fixed set of worlds as evaluation plays them (`run_episodes`). World w of
a validation set with seed s is the evaluation's map w of cell 0 under seed s: map seed s + w, episode key
(s, 0, w, 0) (searchrl/controllers/episodes.py). The policy acts through `PolicyController`, the evaluation's
inference path, with actions sampled from the episode's own stream (or argmax), so the same weights give the same
metrics at every validation (common random numbers: a curve's steps are changes of the weights, not of sampling
luck) and a validation's found fraction is what `python -m searchrl.evaluate` reports on the same worlds when its
`device=` is the training's (cpu for both by default). On another device the logits round otherwise and a sampled
action may flip (searchrl/policies/actor.py). Validation acts with a copy of the training policy on the model's
device (`policy_copy`), on every device alike: the policy that trains on keeps its mode and weights, and torch's
global generator, which training samples from, is left where it was.
"""

from __future__ import annotations

import re
import signal
import sys
import threading
from collections import defaultdict
from dataclasses import asdict
from pathlib import Path
from types import FrameType

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import HParam
from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm

from searchrl.controllers.base import RandomWalk
from searchrl.controllers.episodes import play_episodes
from searchrl.controllers.factory import policy_factory
from searchrl.policies.actor import Actor, policy_copy
from searchrl.policies.checkpoint import save_model
from searchrl.train.logs import log_digest
from searchrl.train.schema import TrainConfig
from searchrl.world.config import WorldConfig
from searchrl.world.scenario import PAPER, Scenario

CHECKPOINT_RE = re.compile(r"^step_(\d+)\.zip$")


class TeamMetricsCallback(BaseCallback):
    """Logs the mean of each team metric (L, R, F, M̄, found fraction, collisions, stale) over the world episodes that
    ended during a rollout, as `team/<name>`, once per world episode (the VecEnv reports each on one slot)."""

    def _on_rollout_start(self) -> None:
        self._values: dict[str, list[float]] = defaultdict(list)

    def _on_step(self) -> bool:
        for info in self.locals["infos"]:
            metrics = info.get("team_metrics")
            if metrics:
                for name, value in metrics.items():
                    self._values[name].append(value)
        return True

    def _on_rollout_end(self) -> None:
        for name, values in self._values.items():
            self.logger.record_mean(f"team/{name}", float(np.mean(values)))  # means over rollouts if log_interval > 1
        if self._values:
            self.logger.record_mean("team/episodes", len(next(iter(self._values.values()))))


class Preemption:
    """While entered, SIGTERM and SIGINT ask the run to stop instead of ending it: `signal` holds the first one. A
    cluster sends SIGTERM ahead of its kill (SLURM's `--signal`); the checkpoint callback lets the rollout under way
    and its update finish, stops before the next and saves the model, and the app exits with 128 + the signal's
    number. A second SIGINT interrupts at once.
    Handlers are only installed in the main thread, where Python delivers signals."""

    def __init__(self) -> None:
        self.signal: int | None = None  # the first signal caught
        self.stopped = False  # training ended early for it (a signal in the last rollout of the budget stops nothing)
        self._previous: dict[int, object] = {}

    def __enter__(self) -> Preemption:
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGTERM, signal.SIGINT):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signal is not None and signum == signal.SIGINT:
            raise KeyboardInterrupt  # a second Ctrl-C: stop now, without the checkpoint
        if self.signal is None:
            self.signal = signum
            print(
                f"{signal.Signals(signum).name}: stopping after this rollout's update, with a checkpoint",
                file=sys.stderr,
                flush=True,
            )


class AtomicCheckpointCallback(BaseCallback):
    """Saves `checkpoints/step_<agent-steps>.zip` every `every` agent-steps and at the end of training, each
    written atomically (model weights, optimiser state and step count in SB3's zip, and `run`, the run's identity:
    searchrl/train/run_record.py).

    Saves happen when a rollout starts, i.e. after the previous rollout has been trained on: a checkpoint taken
    mid-rollout would count steps whose update it does not hold, and a resumed run would skip that update. When
    `preemption` has caught a signal, the rollout under way is still collected and trained on; the next one stops
    at its first step (`Preemption.stopped`), and the checkpoint then saved holds every update: nothing trained is
    lost."""

    def __init__(
        self, directory: Path, every: int, keep: int = 3, preemption: Preemption | None = None, run: dict | None = None
    ) -> None:
        super().__init__()
        self.directory, self.every, self.keep, self.run = Path(directory), every, keep, run or {}
        self.preemption = preemption
        self._next = 0
        self._rollout_start = 0

    def _init_callback(self) -> None:
        # self.num_timesteps is only set once training starts; the model's count is right on resume too.
        self._next = (self.model.num_timesteps // self.every + 1) * self.every

    def _on_rollout_start(self) -> None:
        self._rollout_start = self.num_timesteps
        # A signal caught during the last rollout or its update: that update is done, so stop before collecting more.
        if self.preemption is not None and self.preemption.signal is not None:
            self.preemption.stopped = True
        if self.num_timesteps >= self._next and not self.stopped:
            self.save()
            self._next = (self.num_timesteps // self.every + 1) * self.every

    @property
    def stopped(self) -> bool:
        return self.preemption is not None and self.preemption.stopped

    def _on_step(self) -> bool:
        return not self.stopped

    def _on_training_end(self) -> None:
        if self.stopped:  # the one step of the new rollout was never trained on: not counted
            self.model.num_timesteps = self.num_timesteps = self._rollout_start
        self.save()

    def save(self) -> Path:
        """Write this step's checkpoint, then drop all but the newest `keep` (only once the new one is whole)."""
        log = log_digest(self.directory.parent / "progress.csv", self.num_timesteps)  # the run's log so far
        path = save_model(self.model, self.directory / f"step_{self.num_timesteps}.zip", self.run, log)
        for old in sorted(checkpoints(self.directory))[: -self.keep]:
            old[1].unlink(missing_ok=True)
        return path


def checkpoints(directory: Path) -> list[tuple[int, Path]]:
    """(agent-steps, path) of every complete checkpoint in `directory` (temporary files are hidden dot-files)."""
    return [(int(m.group(1)), p) for p in Path(directory).glob("step_*.zip") if (m := CHECKPOINT_RE.match(p.name))]


class ValidationCallback(BaseCallback):
    """Every `every` agent-steps (never if 0, nor in the last rollout) and once for the final model when training
    ends, runs the policy on fixed validation worlds and logs `val/<metric>` (with `at_start`, also before the first
    rollout); the random-walk level on the same worlds is logged with each as `val/random_<metric>` for reference.
    The final validation's row also holds the last update's losses, which SB3 records after its last log row."""

    def __init__(
        self,
        world_config: WorldConfig,
        scenario: Scenario,
        every: int,
        n_worlds: int,
        seed: int,
        deterministic: bool,
        at_start: bool = False,
        preemption: Preemption | None = None,
    ) -> None:
        super().__init__()
        self.preemption = preemption
        self.world_config, self.scenario = world_config, scenario
        self.every, self.n_worlds, self.seed = every, n_worlds, seed
        self.deterministic, self.at_start = deterministic, at_start
        self._next = self._rollout_end = 0
        self.random_level: dict[str, float] = {}

    def _init_callback(self) -> None:
        self._next = (self.model.num_timesteps // self.every + 1) * self.every if self.every > 0 else 0
        self.random_level = run_episodes(self.world_config, self.n_worlds, self.seed, None, scenario=self.scenario)

    def _on_training_start(self) -> None:
        """With `at_start` (a run that starts from a clone or init weights), the starting policy's row at step 0,
        so the curve shows where RL began."""
        if self.at_start and self.model.num_timesteps == 0:
            self.validate()
            self.logger.record("time/total_timesteps", 0)
            self.logger.dump(0)

    def _on_rollout_start(self) -> None:
        self._rollout_end = self.num_timesteps + self.model.n_steps * self.model.n_envs

    def _on_step(self) -> bool:
        if self.every > 0 and self.num_timesteps >= self._next:
            self._next = (self.num_timesteps // self.every + 1) * self.every
            # logged at this rollout's end: in the last rollout that is the final validation's step, whose row
            # holds the final weights' validation; a second row there would count twice in the score
            if self._rollout_end < self.model._total_timesteps:
                self.validate()
        return True

    def _on_training_end(self) -> None:
        if self.preemption is not None and self.preemption.stopped:
            return  # stopped early: the final model's validation belongs to the run's real end
        self.validate()
        self.logger.record("time/total_timesteps", self.num_timesteps)
        self.logger.dump(self.num_timesteps)

    def validate(self) -> dict[str, float]:
        metrics = run_episodes(
            self.world_config, self.n_worlds, self.seed, self.model, self.deterministic, self.scenario
        )
        for name, value in metrics.items():
            self.logger.record(f"val/{name}", value)
        self.logger.record("val/random_found_fraction", self.random_level["found_fraction"])
        return metrics


class HParamsCallback(BaseCallback):
    """The run's settings in TensorBoard's HParams tab, linked to the validation and team found fractions, so runs
    of a sweep compare by their settings there (written with the first log row; CSV and stdout skip it)."""

    def __init__(self, hparams: dict[str, bool | int | float | str]) -> None:
        super().__init__()
        self.hparams = hparams

    def _on_training_start(self) -> None:
        metrics = {"val/found_fraction": 0.0, "team/found_fraction": 0.0}
        self.logger.record("hparams", HParam(self.hparams, metrics), exclude=("stdout", "log", "json", "csv"))

    def _on_step(self) -> bool:
        return True


def run_hparams(settings: TrainConfig, scenario: str) -> dict[str, bool | int | float | str]:
    """The settings a sweep varies, as TensorBoard's hyperparameters: every scalar of `algo`, the model, network,
    critic, teacher term, reward, scenario label and seed (None shown as "none")."""
    s = settings
    chosen = {
        **{f"algo.{k}": v for k, v in asdict(s.algo).items()},
        "model": s.model.name if s.model else None,
        "network.extractor": s.network.extractor,
        "network.lstm_hidden_size": s.network.lstm_hidden_size,
        "critic": s.critic.name,
        "imitation.teacher": s.imitation.teacher,
        "imitation.rl_weight": s.imitation.rl_weight,
        "imitation.rl_schedule": s.imitation.rl_schedule,
        "reward": s.reward.name,
        "scenario": scenario,
        "seed": s.seed,
        "total_timesteps": s.total_timesteps,
    }
    scalars = (bool, int, float, str)
    return {k: "none" if v is None else v for k, v in chosen.items() if v is None or isinstance(v, scalars)}


def run_episodes(
    world_config: WorldConfig,
    n_worlds: int,
    seed: int,
    model: OnPolicyAlgorithm | None,
    deterministic: bool = False,
    scenario: Scenario = PAPER,
) -> dict[str, float]:
    """Mean episode metrics of `model`'s policy (or of a random walk, None) over the validation set of `n_worlds`
    worlds drawn from `seed` under `scenario` (module docstring)."""
    if model is None:
        factory = RandomWalk
    else:
        # Traced as evaluation's is (about 0.2 s), so both act alike to the last bit on the same device.
        factory = policy_factory(Actor(policy_copy(model), device=model.device), deterministic)

    keys = [(seed, 0, w, 0) for w in range(n_worlds)]
    metrics = play_episodes(factory, world_config, [seed + w for w in range(n_worlds)], keys, scenario)
    return {name: float(np.mean(values)) for name, values in metrics.items() if name != "prior_quality"}  # a world's
