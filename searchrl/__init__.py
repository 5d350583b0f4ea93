"""searchrl: decentralized multi-agent search with deep reinforcement learning."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from searchrl.envs.parallel_env import SearchParallelEnv


def parallel_env(
    config: Any = None, render_mode: str | None = None, scenario: Any = None, **world: Any
) -> SearchParallelEnv:
    """A PettingZoo ParallelEnv over one search world: pass a `WorldConfig`, or its fields as keywords; `scenario` a
    `searchrl.world.scenario.Scenario` or its mapping ({"obstacles": {"kind": "iid", "density": 0.2}}), the paper's
    when None."""
    from searchrl.envs.parallel_env import SearchParallelEnv
    from searchrl.world.config import WorldConfig
    from searchrl.world.scenario import Scenario

    if config is not None and world:
        raise TypeError("pass either a WorldConfig or its fields as keywords, not both")
    scenario = scenario if isinstance(scenario, Scenario) else Scenario.from_dict(scenario)
    return SearchParallelEnv(config if config is not None else WorldConfig(**world), render_mode, scenario)
