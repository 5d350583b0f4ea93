"""The fast inference actor and the policy controller: same distribution as SB3, seeded sampling, skipped rows."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hydra import compose, initialize_config_dir

import searchrl.train.app  # noqa: F401  (registers the training schemas)
from searchrl.controllers.policy import PolicyController
from searchrl.policies.actor import Actor, sample_actions
from searchrl.shared_schema import CONF_DIR
from searchrl.train.build import make_algorithm, make_vec_env
from searchrl.train.plan import make_plan
from searchrl.world.observe import observe
from searchrl.world.reset import reset_world
from searchrl.world.state import allocate
from searchrl.world.step import step

SMALL = ["env.n_worlds=3", "env.world.n_agents=4", "env.world.world_size=[12,20]", "network=small", "threads=1",
         "algo.batch_size=128"]  # fmt: skip


def _model(algo: str, *overrides: str):
    small = [o for o in SMALL if algo != "a2c" or "batch_size" not in o]  # A2C has no minibatches
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose(config_name="train", overrides=["+model=b", f"algo={algo}", *small, *overrides])
    torch.manual_seed(0)
    plan = make_plan(cfg)
    model = make_algorithm(plan, make_vec_env(plan, seed=0))
    with torch.no_grad():  # SB3 initialises the head with gain 0.01: make the distribution peaked
        model.policy.action_net.weight.mul_(2000)
    return plan, model


def _sb3_probs(policy, obs: dict, lstm, starts: np.ndarray):
    """SB3's own action probabilities (and next LSTM state) for one step."""
    with torch.no_grad():
        tensors = {k: torch.as_tensor(v) for k, v in obs.items()}
        if lstm is None:
            return policy.get_distribution(tensors).distribution.probs.numpy(), None
        dist, lstm = policy.get_distribution(tensors, lstm, torch.as_tensor(starts, dtype=torch.float32))
        return dist.distribution.probs.numpy(), lstm


@pytest.mark.parametrize("algo", ["recurrent_ppo", "a2c"])
def test_actor_gives_the_policys_own_distribution(algo):
    """Over an episode with resets inside it, the traced actor's softmax equals SB3's get_distribution."""
    plan, model = _model(algo)
    policy = model.policy
    policy.set_training_mode(False)
    actor = Actor(policy)
    assert isinstance(actor._extract, torch.jit.ScriptModule)  # the optimised path, not the eager fallback
    env = make_vec_env(plan, seed=1)
    obs = env.reset()
    slots = env.num_envs
    rng = np.random.default_rng(0)
    ours = actor.initial_state(slots)
    theirs = None if ours is None else tuple(torch.zeros(ours.shape[1:]) for _ in range(2))
    starts = np.ones(slots, bool)
    for _ in range(12):
        expected, theirs = _sb3_probs(policy, obs, theirs, starts)
        if ours is not None:
            ours = ours * torch.from_numpy(~starts)[None, None, :, None]
        logits, ours = actor.logits(obs["map"], obs["vector"], ours)
        probs = torch.softmax(torch.from_numpy(logits), 1).numpy()
        assert probs.max() > 0.5  # a peaked distribution, so a wrong input or state shows
        np.testing.assert_allclose(probs, expected, rtol=1e-4, atol=1e-6)
        obs, _, _, _ = env.step(rng.integers(0, 5, slots))
        starts = rng.random(slots) < 0.2  # resets inside the sequence


def test_sample_actions_follows_the_probabilities_and_the_seed():
    logits = np.log(np.array([[0.1, 0.2, 0.3, 0.4, 1e-9]] * 40_000, np.float32))
    actions = sample_actions(logits, np.random.default_rng(3).random(len(logits)))
    freq = np.bincount(actions, minlength=5) / len(actions)
    np.testing.assert_allclose(freq, [0.1, 0.2, 0.3, 0.4, 0.0], atol=0.01)
    # the CDF inverted at each uniform: [0, 0.1) -> 0, [0.1, 0.3) -> 1, [0.3, 0.6) -> 2, [0.6, 1) -> 3
    uniforms = np.array([0.0, 0.09, 0.11, 0.29, 0.31, 0.59, 0.61, 0.999999])
    assert sample_actions(logits[: len(uniforms)], uniforms).tolist() == [0, 0, 1, 1, 2, 2, 3, 3]
    assert (sample_actions(logits[:3], None) == 3).all()


def _three_worlds():
    """(world config, actor of an untrained recurrent policy, state of 3 freshly reset worlds)."""
    plan, model = _model("recurrent_ppo")
    config = plan.world
    state = allocate(config, 3)
    for w in range(3):
        reset_world(config, state, w, np.random.default_rng(w))
    return config, Actor(model.policy), state


def test_controller_skips_inactive_worlds_and_keeps_their_memory():
    """Acting for a subset of worlds gives those worlds the same actions as acting for all, and leaves the
    LSTM state of the skipped worlds as it was."""
    config, actor, state = _three_worlds()
    k = 3
    full, part = (PolicyController(actor, config, deterministic=True) for _ in range(2))
    for c in (full, part):
        c.reset(state, np.ones(k, bool))
    active = np.array([True, False, True])
    rng = np.random.default_rng(0)
    for t in range(5):
        maps, vector = observe(config, state)
        kept = part._state[:, :, 4:8].clone()
        a_full = full.act(state, maps, vector)
        a_part = part.act(state, maps, vector, active=active if t else None)
        if t:
            assert (a_part[active] == a_full[active]).all() and (a_part[~active] == 0).all()
            np.testing.assert_array_equal(part._state[:, :, 4:8], kept)
        step(config, state, a_full, rng)


def test_controller_resets_only_the_marked_worlds_and_samples_by_seed():
    config, actor, state = _three_worlds()
    k = 3
    controller = PolicyController(actor, config, deterministic=True)
    controller.reset(state, np.ones(k, bool))
    rng = np.random.default_rng(0)
    for _ in range(4):  # build up LSTM state
        step(config, state, controller.act(state, *observe(config, state)), rng)
    before = controller._state.clone()
    controller.reset(state, np.array([False, True, False]))
    fresh = PolicyController(actor, config, deterministic=True)
    fresh.reset(state, np.ones(k, bool))
    maps, vector = observe(config, state)
    acted, first = controller.act(state, maps, vector), fresh.act(state, maps, vector)
    assert (acted[1] == first[1]).all()  # world 1 starts afresh: same as a new controller
    np.testing.assert_array_equal(controller._state[:, :, 4:8], fresh._state[:, :, 4:8])
    assert not np.allclose(controller._state[:, :, :4], fresh._state[:, :, :4])  # the others kept their memory
    assert not np.array_equal(before[:, :, :4], controller._state[:, :, :4])  # and carried it forward

    def sampled(seed: int) -> np.ndarray:
        c = PolicyController(actor, config, seed=seed)
        c.reset(state, np.ones(k, bool))
        return np.stack([c.act(state, maps, vector) for _ in range(20)])

    assert (sampled(5) == sampled(5)).all() and not (sampled(5) == sampled(6)).all()
