"""The whole-belief context (searchrl/world/context.py): off by default and then absent everywhere; on, the same
image as a plain numpy pooling of each agent's own belief, in the spaces of every env layer, trainable end to end,
and evaluated from a checkpoint."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

from searchrl.envs.parallel_env import SearchParallelEnv
from searchrl.envs.single_env import SearchEnv
from searchrl.envs.vec_env import SearchVecEnv
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.context import observe_context
from searchrl.world.engine import SearchWorld

ROOT = Path(__file__).resolve().parents[1]

CONFIG = WorldConfig(world_size=(10, 14), n_targets=(2, 3), n_agents=4, max_steps=30, context=6)


def _numpy_context(config: WorldConfig, world: SearchWorld) -> np.ndarray:
    """The context by its definition: mean of each bin of the agent's scaled belief, share of the bin in view."""
    state, grid, half = world.state, config.context, config.fov // 2
    out = np.zeros((state.n_worlds, state.n_agents, 3, grid, grid), np.float32)
    for k in range(state.n_worlds):
        n, h = int(state.size[k]), state.halo
        bins = np.arange(n) * grid // n
        cells = np.bincount(bins, minlength=grid)[:, None] * np.bincount(bins, minlength=grid)[None, :]
        for i in range(state.n_agents):
            for channel in (0, 1):
                belief = state.belief[k, i, channel, h : h + n, h : h + n].astype(np.float64)
                sums = np.zeros((grid, grid))
                np.add.at(sums, (bins[:, None], bins[None, :]), belief)
                out[k, i, channel] = np.minimum(sums / cells * state.obs_scale[k, channel], 1.0)
            r, c = state.pos[k, i]
            view = np.zeros((n, n))
            view[max(r - half, 0) : r + half + 1, max(c - half, 0) : c + half + 1] = 1
            sums = np.zeros((grid, grid))
            np.add.at(sums, (bins[:, None], bins[None, :]), view)
            out[k, i, 2] = sums / cells
    return out


def test_off_by_default_and_then_absent_everywhere():
    config = replace(CONFIG, context=0)
    world = SearchWorld(config, 2, seed=0)
    world.reset()
    assert world.context is None and world.step(np.zeros((2, 4), np.int64)).context is None
    assert set(SearchVecEnv(config, 2, seed=0).reset()) == {"map", "vector"}
    assert set(SearchParallelEnv(config).observation_space("agent_0").spaces) == {"map", "vector"}


@pytest.mark.parametrize("grid", [2, 6, 10])
def test_the_kernel_pools_each_agents_own_belief_as_numpy_does(grid):
    config = replace(CONFIG, context=grid, world_size=(10, 23))
    world = SearchWorld(config, 3, seed=1)
    world.reset()
    rng = np.random.default_rng(2)
    for _ in range(12):  # beliefs change under the footprints (and merge in model B)
        tr = world.step(rng.integers(0, 5, size=(3, 4)))
    np.testing.assert_allclose(tr.context, _numpy_context(config, world), rtol=1e-5, atol=1e-7)
    np.testing.assert_array_equal(observe_context(config, world.state), tr.context)  # a fresh buffer, same image
    assert tr.context.min() >= 0 and tr.context.max() <= 1
    assert (tr.context[:, :, 2].sum(axis=(2, 3)) > 0).all()  # every agent sees itself somewhere


def test_sensing_lowers_the_pooled_belief_where_the_agent_has_been():
    config = replace(CONFIG, n_agents=1, world_size=(14, 14), context=2, communication=False)
    world = SearchWorld(config, 1, seed=3)
    world.reset()
    before = world.context.copy()
    for _ in range(10):
        tr = world.step(np.zeros((1, 1), np.int64))  # stay: sense the same cells over and over
    r, c = world.state.pos[0, 0] * 2 // 14
    assert tr.context[0, 0, 0, r, c] < before[0, 0, 0, r, c]


def test_the_context_has_bounds_and_is_checked():
    with pytest.raises(ConfigError, match="context=11"):
        WorldConfig(world_size=(10, 14), context=11)  # more bins than the smallest world has rows
    with pytest.raises(ConfigError, match="context=1"):
        WorldConfig(context=1)


def test_env_layers_show_it_and_pass_their_api_checks():
    parallel_api_test(SearchParallelEnv(CONFIG), num_cycles=40)
    parallel_seed_test(lambda: SearchParallelEnv(CONFIG), num_cycles=20)
    check_env(SearchEnv(CONFIG), skip_render_check=True)
    env = SearchVecEnv(CONFIG, n_worlds=2, seed=0)
    obs = env.reset()
    assert obs["context"].shape == (8, 3, 6, 6) and env.observation_space["context"].contains(obs["context"][0])
    world = SearchWorld(CONFIG, 2, seed=0)
    world.reset()
    np.testing.assert_array_equal(obs["context"], world.context.reshape(8, 3, 6, 6))
    for _ in range(CONFIG.max_steps):
        obs, _rewards, dones, infos = env.step(np.zeros(8, np.int64))
        if dones.any():
            terminal = infos[int(np.flatnonzero(dones)[0])]["terminal_observation"]
            assert terminal["context"].shape == (3, 6, 6)
            break
    else:
        pytest.fail("no episode ended")


def test_a_context_policy_trains_evaluates_and_a_local_checkpoint_is_refused_in_a_context_world(tmp_path):
    from hydra import compose, initialize_config_dir

    from searchrl.controllers.policy import load_actor
    from searchrl.evaluate.__main__ import CONF_DIR as EVAL_CONF
    from searchrl.evaluate.__main__ import evaluate
    from searchrl.evaluate.results import load
    from tests.test_train import TINY, _run

    model = _run(tmp_path / "run", ["+model=b", *TINY, "env.world.context=4", "total_timesteps=512",
                                    "validation.every=256", "imitation.teacher=greedy", "imitation.episodes=1",
                                    "imitation.epochs=1", "imitation.value_epochs=1"])  # fmt: skip
    with initialize_config_dir(config_dir=str(EVAL_CONF), version_base="1.3"):
        overrides = [f"checkpoint={model}", "grid.world_sizes=[20]", "grid.n_targets=[4]", "grid.n_distributions=[8]",
                     "grid.max_agents=[2]", "grid.maps_per_cell=2", "grid.repeats=1", "progress_bar=false",
                     "threads=1", "bound_draws=100", "bound_cache=null", f"out_dir={tmp_path / 'eval'}"]  # fmt: skip
        cfg = compose(config_name="evaluate", overrides=overrides)
    episodes = load(evaluate(cfg, overrides[:1]))
    assert len(episodes) == 4 and episodes.found_fraction.between(0, 1).all()
    with pytest.raises(ValueError, match="whole-belief context"):
        load_actor(model, replace(CONFIG, context=0))
    # analysis/context_probe.py asks the policy again with the context blanked or swapped, the episode unchanged
    probe = _probe(str(model), "--cells", "n40_N2", "--worlds", "2", "--out", str(tmp_path / "probe"))
    assert probe.returncode == 0, probe.stderr[-2000:]
    table = (tmp_path / "probe" / "context_probe.md").read_text()
    row = next(line for line in table.splitlines() if line.startswith("| n40_N2 |"))
    shares = [float(v) for v in row.strip("|").split("|")[1:]]
    assert len(shares) == 8 and all(0 <= v <= 1 for v in shares)


def _probe(*args: str) -> subprocess.CompletedProcess:
    """Run analysis/context_probe.py from the repository root."""
    return subprocess.run([sys.executable, "analysis/context_probe.py", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=300)  # fmt: skip


def test_the_context_probe_names_a_local_checkpoint_and_bad_cells_in_one_line():
    local = _probe("runs/reference/b/model.zip", "--cells", "n40_N2")
    assert local.returncode == 2 and "env.world.context=0" in local.stderr.strip().splitlines()[-1]
    cells = _probe("runs/reference/b/model.zip", "--cells", "n30_N2")
    assert cells.returncode == 2 and "n30_N2" in cells.stderr.strip().splitlines()[-1]
