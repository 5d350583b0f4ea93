# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # A privileged teacher for the adaptive policy (an experiment, outside the library)
#
# Learning by cheating: the teacher sees what no agent can, how well the prior points at the world's true targets,
# and acts as the better rule for that world: target-greedy (reach 2) where the prior is good, geometric coverage
# where it is not. The quality is MapScore-like (searchrl/world/truth.py) but of the agents' density of targets,
# p·(1 − u/max u), which is what greedy reads (so an uninformed p with the truth's u still counts). The student,
# PPO with the teacher term on the mixed wrong priors, must learn from its own evidence when to trust the prior.
#
#     python analysis/oracle_teacher.py +experiment=term/b scenario=mixed_priors '~imitation.teacher_args.reach' \
#         init=runs/reference/term/b/model.zip imitation.teacher=oracle_switch algo.n_epochs=2 \
#         hydra.run.dir=runs/train/robust/r3_oracle
#
# Any `python -m searchrl.train` arguments; `imitation.teacher_args.threshold` (0.25) is the quality above which
# the teacher trusts the prior.

# %%
from dataclasses import dataclass

import numpy as np

from searchrl.controllers import registry
from searchrl.controllers.base import ControllerConfig
from searchrl.controllers.coverage import GeometricCoverage
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.world.config import WorldConfig
from searchrl.world.state import WorldState
from searchrl.world.streams import WorldStreams
from searchrl.world.truth import prior_quality


# %%
@dataclass
class OracleSwitchConfig(ControllerConfig):
    name: str = "oracle_switch"
    threshold: float = 0.25


class OracleSwitch:
    """Per world, from its reset: target-greedy if the agents' density of targets ranks the true targets' cells
    above `threshold` (prior quality), else geometric coverage."""

    def __init__(self, config: WorldConfig, threshold: float = 0.25, seed: int | WorldStreams = 0) -> None:
        self.threshold = float(threshold)
        self.greedy = FootprintGreedy(config, horizon=3, w_p=0.0, w_u=0.0, w_t=1.0, reach=2.0, seed=seed)
        self.coverage = GeometricCoverage(config)
        self.trust = np.zeros(0, bool)

    def reset(self, state: WorldState, mask: np.ndarray) -> None:
        if self.trust.shape != (state.n_worlds,):
            self.trust, mask = np.zeros(state.n_worlds, bool), np.ones(state.n_worlds, bool)
        self.greedy.reset(state, mask)
        self.coverage.reset(state, mask)
        h = state.halo
        for k in np.flatnonzero(mask):
            n = int(state.size[k])
            inner = (k, slice(h, h + n), slice(h, h + n))
            p, u, free = state.p[inner], state.u[inner], ~state.blocked[inner]
            density = p * np.maximum(0.0, 1.0 - u / u.max())
            targets = state.target_pos[k, : int(state.n_targets[k])]
            self.trust[k] = prior_quality(density, free, targets) >= self.threshold

    def act(self, state, maps, vector, active=None) -> np.ndarray:
        if self.trust.shape != (state.n_worlds,):
            self.reset(state, np.ones(state.n_worlds, bool))
        greedy = self.greedy.act(state, maps, vector, active)
        return np.where(self.trust[:, None], greedy, self.coverage.act(state, maps, vector, active))


# %% The teacher joins the registry for this process only: `imitation.teacher=oracle_switch`
registry.register("oracle_switch", OracleSwitch, OracleSwitchConfig)

# %%
if __name__ == "__main__":
    import hydra

    from searchrl.shared_schema import CONF_DIR
    from searchrl.train.app import main

    # the training app itself, its config found from here (its own decorator looks beside its module)
    hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="train")(main.__wrapped__)()
