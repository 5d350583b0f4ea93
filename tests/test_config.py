"""WorldConfig validation: every bad value raises ConfigError naming the offending field."""

from __future__ import annotations

import pytest

from searchrl.world.config import ConfigError, WorldConfig


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"fov": 10}, "fov"),
        ({"fov": 0}, "fov"),
        ({"explicit_area": 4}, "explicit_area"),
        ({"comm_range": 6}, "comm_range"),
        ({"explicit_area": 13, "fov": 11}, "explicit_area"),  # Φ must fit inside the FOV
        ({"lam": 0.002, "k": 1000.0}, "lam"),  # λk·max Γ = 2: lam is off the paper's 0.001, so it is named
        ({"k": 2000.0}, "k"),  # the same product with the paper's lam: k is named
        ({"lam": 0.0}, "lam"),
        ({"k": -1.0}, "k"),
        ({"k": 0.0}, "k"),  # no sensing at all
        ({"k_per_n": -1.0}, "k_per_n"),
        ({"k": 0.0, "k_per_n": 10.0}, "k"),  # λ·10·128 > 1 in the largest world
        ({"k": 0.0, "k_per_n": 1.0, "belief_age": 1.0}, "belief_age"),  # age models λk = 1
        ({"world_size": (-5, 10)}, "world_size"),
        ({"world_size": (12, 10)}, "world_size"),
        ({"world_size": (4, 10)}, "world_size"),
        ({"n_targets": (0, 3)}, "n_targets"),
        ({"n_distributions": (-1, 3)}, "n_distributions"),
        ({"n_agents": 0}, "n_agents"),
        ({"n_agents": -3}, "n_agents"),
        ({"world_size": (5, 10), "n_agents": 26, "n_targets": (1, 1)}, "n_agents"),  # 25 cells for 26 agents
        ({"world_size": (5, 10), "n_agents": 20, "n_targets": (1, 6)}, "n_targets"),  # 26 > 25 start cells
        ({"max_steps": 0}, "max_steps"),
        ({"xi": -0.1}, "xi"),
        ({"tau": -0.1}, "tau"),
        ({"eta": 1.5}, "eta"),
        ({"rho_max": 1.0}, "rho_max"),
        ({"belief_age": -0.5}, "belief_age"),
        ({"belief_age": 5.0}, "belief_age"),
        ({"belief_age_channel": True}, "belief_age_channel"),
        ({"belief_age": 1.0, "belief_age_channel": "yes"}, "belief_age_channel"),
        ({"belief_seen": True}, "belief_seen"),
        ({"belief_age": 1.0, "belief_seen": 1}, "belief_seen"),
    ],
)
def test_bad_values_raise_config_error_naming_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ConfigError, match=rf"^{field}="):
        WorldConfig(**kwargs)


def test_config_error_is_a_value_error_and_config_is_frozen() -> None:
    assert issubclass(ConfigError, ValueError)
    config = WorldConfig()
    with pytest.raises(AttributeError):
        config.fov = 7  # type: ignore[misc]


def test_from_dict_rejects_unknown_keys_and_accepts_lists() -> None:
    with pytest.raises(ConfigError, match="fovv"):
        WorldConfig.from_dict({"fovv": 11})
    assert WorldConfig.from_dict({"world_size": [20, 30]}).world_size == (20, 30)


def test_derived_sizes() -> None:
    assert WorldConfig(diagonal=False).n_actions == 5 and WorldConfig(diagonal=True).n_actions == 9
    assert WorldConfig(fov=11, explicit_area=5, comm_range=5).halo == 5
    assert WorldConfig(fov=7, explicit_area=3, comm_range=3).halo == 3
    assert WorldConfig(fov=3, explicit_area=3, comm_range=3).halo == 2  # Γ's 5×5 still needs two cells


def test_an_integer_world_size_is_an_n_by_n_world_everywhere() -> None:
    """world_size=20 means every world is 20×20: WorldConfig, searchrl.parallel_env, SearchEnv, Hydra's
    env.world.world_size and env.extra_teams' world_size."""
    import numpy as np
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    import searchrl
    import searchrl.train.app
    from searchrl.envs.single_env import SearchEnv
    from searchrl.shared_schema import CONF_DIR
    from searchrl.train.plan import team_groups

    assert WorldConfig(world_size=20).world_size == (20, 20) == WorldConfig(world_size=np.int64(20)).world_size
    assert WorldConfig(world_size=20) == WorldConfig(world_size=(20, 20))
    assert WorldConfig.from_dict({"world_size": 20}).world_size == (20, 20)
    for bad in (True, 20.0, "20", (20,), 4):
        with pytest.raises(ConfigError, match=r"^world_size="):
            WorldConfig(world_size=bad)
    env = searchrl.parallel_env(world_size=20, n_agents=2)
    env.reset(seed=0)
    assert env.config.world_size == (20, 20) and int(env.world_state.size[0]) == 20
    single = SearchEnv(WorldConfig(world_size=20))
    single.reset(seed=0)
    assert int(single._env.world_state.size[0]) == 20
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        teams = "env.extra_teams=[{n_agents:4,n_worlds:1,world_size:40},{n_agents:2,n_worlds:1,world_size:[30,50]}]"
        cfg = compose(config_name="train", overrides=["+model=b", "env.world.world_size=20", teams])
        with pytest.raises(ConfigError, match=r"env.extra_teams\[0\]: world_size='big'"):
            team_groups(
                OmegaConf.to_object(
                    compose(config_name="train", overrides=["env.extra_teams=[{n_agents:4,n_worlds:1,world_size:big}]"])
                )
            )
    groups = team_groups(OmegaConf.to_object(cfg))
    assert [(w.world_size, k) for w, k in groups] == [((20, 20), 16), ((40, 40), 1), ((30, 50), 1)]
