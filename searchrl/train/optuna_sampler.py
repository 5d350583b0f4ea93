"""Optuna's TPE sampler with draws seeded per trial, for `hydra/sweeper=optuna_searchrl`: a study can be resumed.

Optuna's own TPESampler(seed=s) seeds its random streams once, when the sweeper starts. Rerunning a sweep command
to add trials to a stored study therefore starts the streams again: while the study is in its random startup
phase, the new trials repeat the first trials' settings. Here trial k draws from streams seeded by (s, k), so each
trial's proposal depends on the seed, its number and the study's history only: a sweep is reproducible, and a
resumed one proposes what an uninterrupted one would have.

A sweep killed outright (kill -9, a node lost) leaves its running trial RUNNING in the stored study for ever. Each
trial is marked with the host and process id of the sweep that proposed it (a system attribute), and the first
proposal of a sweep marks FAIL the RUNNING trials whose sweep was on this host and is gone (`fail_orphans`);
trials of another host's sweep are left alone (their process cannot be seen from here).
"""

from __future__ import annotations

import os
import socket
from typing import Any

import numpy as np
from optuna.distributions import BaseDistribution
from optuna.samplers import TPESampler
from optuna.study import Study
from optuna.trial import FrozenTrial, TrialState

OWNER = "searchrl_sweep"  # trial system attribute: "<host>:<pid>" of the sweep process that proposed the trial


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def fail_orphans(study: Study) -> list[int]:
    """Mark FAIL every RUNNING trial whose sweep ran on this host and is gone, or that no sweep marked (a study
    stored before the mark); returns their numbers."""
    here, failed = socket.gethostname(), []
    for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        owner = trial.system_attrs.get(OWNER)
        host, _, pid = (owner or ":").rpartition(":")
        if owner is None or (host == here and pid.isdigit() and int(pid) != os.getpid() and not _alive(int(pid))):
            study._storage.set_trial_state(trial._trial_id, TrialState.FAIL)
            failed.append(trial.number)
    return failed


class TrialSeededTPESampler(TPESampler):
    def __init__(self, seed: int = 0, **kwargs: Any) -> None:
        super().__init__(seed=seed, **kwargs)
        self._base_seed = int(seed)
        self._seeded_trial = -1
        self._orphans_checked = False

    def _seed_for(self, study: Study, trial: FrozenTrial) -> None:
        # TPESampler (optuna 2.10, which hydra-optuna-sweeper requires) keeps its streams in _rng and in its
        # startup RandomSampler's _rng.
        if trial.number != self._seeded_trial:
            self._seeded_trial = trial.number
            study._storage.set_trial_system_attr(trial._trial_id, OWNER, f"{socket.gethostname()}:{os.getpid()}")
            if not self._orphans_checked:  # the sweep's first proposal: its own trial is marked, the dead are not
                self._orphans_checked = True
                failed = fail_orphans(study)
                if failed:
                    print(f"note: trials {failed} were left RUNNING by a sweep that is gone: marked FAIL")
            self._rng = np.random.RandomState([self._base_seed, trial.number])
            self._random_sampler._rng = np.random.RandomState([self._base_seed, trial.number, 1])

    def sample_relative(
        self, study: Study, trial: FrozenTrial, search_space: dict[str, BaseDistribution]
    ) -> dict[str, Any]:
        self._seed_for(study, trial)
        return super().sample_relative(study, trial, search_space)

    def sample_independent(
        self, study: Study, trial: FrozenTrial, param_name: str, param_distribution: BaseDistribution
    ) -> Any:
        self._seed_for(study, trial)
        return super().sample_independent(study, trial, param_name, param_distribution)
