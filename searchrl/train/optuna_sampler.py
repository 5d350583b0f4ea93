"""Optuna's TPE sampler with draws seeded per trial, for `hydra/sweeper=optuna_searchrl`: a study can be resumed.

Optuna's own TPESampler(seed=s) seeds its random streams once, when the sweeper starts. Rerunning a sweep command
to add trials to a stored study therefore starts the streams again: while the study is in its random startup
phase, the new trials repeat the first trials' settings. Here trial k draws from streams seeded by (s, k), so each
trial's proposal depends on the seed, its number and the study's history only: a sweep is reproducible, and a
resumed one proposes what an uninterrupted one would have.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from optuna.distributions import BaseDistribution
from optuna.samplers import TPESampler
from optuna.study import Study
from optuna.trial import FrozenTrial


class TrialSeededTPESampler(TPESampler):
    def __init__(self, seed: int = 0, **kwargs: Any) -> None:
        super().__init__(seed=seed, **kwargs)
        self._base_seed = int(seed)
        self._seeded_trial = -1

    def _seed_for(self, trial: FrozenTrial) -> None:
        # TPESampler (optuna 2.10, which hydra-optuna-sweeper requires) keeps its streams in _rng and in its
        # startup RandomSampler's _rng.
        if trial.number != self._seeded_trial:
            self._seeded_trial = trial.number
            self._rng = np.random.RandomState([self._base_seed, trial.number])
            self._random_sampler._rng = np.random.RandomState([self._base_seed, trial.number, 1])

    def sample_relative(
        self, study: Study, trial: FrozenTrial, search_space: dict[str, BaseDistribution]
    ) -> dict[str, Any]:
        self._seed_for(trial)
        return super().sample_relative(study, trial, search_space)

    def sample_independent(
        self, study: Study, trial: FrozenTrial, param_name: str, param_distribution: BaseDistribution
    ) -> Any:
        self._seed_for(trial)
        return super().sample_independent(study, trial, param_name, param_distribution)
