"""The world's batch kernels on several threads (searchrl/world/parallel.py): the same seed gives the same episodes,
bit for bit, whatever numba's thread count and however the worlds are cut into chunks; `use_threads` sets torch's
and numba's counts; `bench world --threads`; a forked child still steps its worlds."""

from __future__ import annotations

import dataclasses
import itertools
import json
import multiprocessing

import numba
import numpy as np
import pytest
import torch

from searchrl.bench import world as bench_world
from searchrl.bench.__main__ import main as bench_main
from searchrl.controllers import greedy, walls
from searchrl.controllers.greedy import FootprintGreedy
from searchrl.controllers.walls import PathGreedy
from searchrl.threads import use_threads
from searchrl.world import maps, observe, seen, step
from searchrl.world import reset as reset_module
from searchrl.world.config import WorldConfig
from searchrl.world.engine import SearchWorld
from searchrl.world.footprint import SUPPORT
from searchrl.world.parallel import agent_blocks, chunk_span
from searchrl.world.scenario import Scenario
from searchrl.world.streams import WorldStreams

TWO = min(2, numba.config.NUMBA_NUM_THREADS)  # real threads where the machine has them (CI's has two cores)
CONFIGS = {
    "model_b": WorldConfig(world_size=(12, 24), n_targets=(2, 5), n_distributions=(4, 8), n_agents=6, max_steps=25),
    "aged_seen_c": WorldConfig(world_size=(12, 20), n_targets=(2, 4), n_agents=5, communication=False, lam=1.0,
                               k=1.0, explicit_area=11, belief_age=1.0, belief_seen=True, max_steps=20),
    "age_channel_diagonal": WorldConfig(world_size=(12, 20), n_agents=5, diagonal=True, lam=1.0, k=1.0,
                                        belief_age=0.5, belief_age_channel=True, max_steps=20),
}  # fmt: skip
OBSTACLES = Scenario.from_dict({"obstacles": {"kind": "iid", "density": 0.2}})


@pytest.fixture
def chunks(monkeypatch):
    """chunks(t): numba runs TWO threads and the kernels cut their worlds into min(K, t) chunks (t > TWO: several
    chunks a thread, as on a machine with more cores); numba's count is restored afterwards."""
    before = numba.get_num_threads()

    def use(t: int) -> None:
        numba.set_num_threads(1 if t == 1 else TWO)
        for module in (step, observe, seen, maps, reset_module, greedy, walls):  # where the kernels learn their threads
            monkeypatch.setattr(module, "world_threads", lambda t=t: t)

    yield use
    numba.set_num_threads(before)


def _episodes(config: WorldConfig, scenario: Scenario, steps: int = 45, k: int = 7) -> list[np.ndarray]:
    """Everything a run of k auto-resetting worlds shows, step by step: observations, results, metrics, state."""
    world = SearchWorld(config, n_worlds=k, seed=11, scenario=scenario)
    shown = [a.copy() for a in world.reset()]
    rng = np.random.default_rng(5)
    for _ in range(steps):
        tr = world.step(rng.integers(0, config.n_actions, size=(k, config.n_agents)))
        shown += [tr.maps.copy(), tr.vector.copy(), tr.final_maps.copy(), tr.final_vector.copy()]
        shown += [getattr(tr.result, f.name).copy() for f in dataclasses.fields(tr.result)]
        shown += [tr.metrics[key].copy() for key in sorted(tr.metrics)]
    shown += [v.copy() for v in vars(world.state).values() if isinstance(v, np.ndarray)]
    return shown


def _same(a: list[np.ndarray], b: list[np.ndarray]) -> None:
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes()  # bits, NaNs included


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("scenario", [Scenario(), OBSTACLES], ids=["paper", "obstacles"])
def test_the_same_seed_gives_the_same_episodes_bit_for_bit_at_any_thread_count(chunks, name, scenario):
    """7 worlds on 1 thread, then cut in 2, 3 and 7 chunks over numba's threads: steps (auto-reset included),
    observations, metrics and the whole state agree bit for bit (a kernel sharing scratch between threads, or
    reading another chunk's worlds, breaks this)."""
    chunks(1)
    serial = _episodes(CONFIGS[name], scenario)
    for t in (2, 3, 7):
        chunks(t)
        _same(_episodes(CONFIGS[name], scenario), serial)


CROWDED = {  # merges every step, and enough agents for blocks of both the merge and the observation
    "model_b": WorldConfig(world_size=(20, 24), n_targets=(2, 4), n_agents=128, max_steps=25),
    "aged_seen": WorldConfig(world_size=(20, 24), n_targets=(2, 4), n_agents=128, max_steps=25, belief_age=0.5,
                             belief_seen=True),
}  # fmt: skip


@pytest.mark.parametrize("name", list(CROWDED))
@pytest.mark.parametrize("k", [1, 2])
def test_fewer_worlds_than_threads_share_their_agents_and_give_the_same_episodes(chunks, k, name):
    """One or two crowded worlds on 1 thread, then on more threads than worlds (2, 3, 7): each world's merge and
    observation are cut into blocks of agents shared among the threads (`parallel.agent_blocks` > 1), and steps,
    observations and state agree bit for bit (a block writing before the other blocks have read, into another's
    slot of the buffer, or observing the wrong agents, breaks this)."""
    config = CROWDED[name]
    chunks(1)
    serial = _episodes(config, Scenario(), steps=40, k=k)
    for t in (t for t in (2, 3, 7) if t > k):
        assert agent_blocks(k, config.n_agents, t, step.MERGE_BLOCK_AGENTS) > 1
        assert agent_blocks(k, config.n_agents, t, observe.OBSERVE_BLOCK_AGENTS) > 1
        chunks(t)
        _same(_episodes(config, Scenario(), steps=40, k=k), serial)


def test_per_world_streams_give_the_same_episodes_at_any_thread_count(chunks):
    """Evaluation's worlds (one stream each, never reset): the same at 1 and 2 threads, and as batches of one."""
    config = CONFIGS["aged_seen_c"]
    seeds, keys = [3, 4, 5, 6, 7], [(0, s) for s in range(5)]

    def run(worlds: list[tuple[list[int], list]]) -> list[np.ndarray]:
        out = []
        for map_seeds, world_keys in worlds:
            world = SearchWorld.from_maps(config, map_seeds, WorldStreams(world_keys))
            rng = np.random.default_rng(1)
            for _ in range(config.max_steps):
                tr = world.step(rng.integers(0, config.n_actions, size=(len(map_seeds), config.n_agents)))
            out += [tr.maps, world.state.belief_seen, world.state.ep_return, world.state.ep_info]
        return out

    chunks(1)
    serial = run([(seeds, keys)])
    chunks(2)
    _same(run([(seeds, keys)]), serial)


@pytest.mark.parametrize(
    "config, rule, settings",
    [(CONFIGS["model_b"], FootprintGreedy, {"horizon": 3, "w_p": 0, "w_u": 0, "w_t": 1, "reach": 2, "contested": 0.5}),
     (CONFIGS["aged_seen_c"], FootprintGreedy, {"seen": True, "age": 1.0, "hedge": 0.2}),
     (CONFIGS["model_b"], PathGreedy, {"radius": 4})],
    ids=["target_reach_contested", "seen_age_hedge", "path_greedy"],
)  # fmt: skip
def test_greedy_moves_are_the_same_at_any_thread_count(chunks, config, rule, settings):
    """Footprint-greedy and path-greedy (the teachers that label every training step) move 7 worlds alike on 1
    thread and cut in 2, 3 and 7 chunks: their kernels share out the worlds, each chunk with its own scratch."""

    def moves() -> list[np.ndarray]:
        world = SearchWorld(config, n_worlds=7, seed=4, scenario=OBSTACLES)
        maps, vector = world.reset()
        teacher = rule(config, seed=9, **settings)
        teacher.reset(world.state, np.ones(7, bool))
        out = []
        for _ in range(config.max_steps + 5):  # past a world's end: its reset restarts the teacher's memory
            actions = np.asarray(teacher.act(world.state, maps, vector), np.int64)
            tr = world.step(actions)
            maps, vector = tr.maps, tr.vector
            teacher.reset(world.state, tr.result.done)
            out.append(actions.copy())
        return out

    chunks(1)
    serial = moves()
    assert len({a.tobytes() for a in serial}) > 1
    for t in (2, 3, 7):
        chunks(t)
        _same(moves(), serial)


def test_remember_sightings_of_a_span_touches_those_worlds_only(chunks):
    """greedy's memory call (first..stop of the batch) on several threads: the worlds outside the span keep their
    maps, those inside get what a serial call gives them."""
    config = CONFIGS["aged_seen_c"]
    world = SearchWorld(config, n_worlds=6, seed=2)
    world.reset()
    w, state = world.state.arrays(), world.state
    shape = state.belief_seen.shape
    start_seen = np.random.default_rng(0).random(shape).astype(np.float32)
    results = []
    for t in (1, 3):
        chunks(t)
        seen_maps, known = start_seen.copy(), np.zeros(shape, np.int32)
        seen.remember_sightings(w, SUPPORT, seen_maps, known, config.fov // 2, config.explicit_area // 2, True, 1, 5)
        assert seen_maps[[0, 5]].tobytes() == start_seen[[0, 5]].tobytes() and not known[[0, 5]].any()
        results.append((seen_maps, known))
    _same(list(results[0]), list(results[1]))


def test_chunks_cover_the_worlds_once_in_order():
    for first, stop in ((0, 7), (3, 4), (2, 64)):
        for n_chunks in range(1, stop - first + 1):
            spans = [chunk_span(c, n_chunks, first, stop) for c in range(n_chunks)]
            assert spans[0][0] == first and spans[-1][1] == stop
            assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))
            assert max(b - a for a, b in spans) - min(b - a for a, b in spans) <= 1


def test_use_threads_sets_torch_and_numba():
    before = torch.get_num_threads(), numba.get_num_threads()
    try:
        assert use_threads(1) == 1 and torch.get_num_threads() == 1 and numba.get_num_threads() == 1
        most = numba.config.NUMBA_NUM_THREADS
        assert use_threads(most + 3, network_on_cpu=False) == most and numba.get_num_threads() == most  # the cap
        assert torch.get_num_threads() == most + 3
        # torch computing on the same cores: the world keeps to one thread (two spinning pools slow the update)
        assert use_threads(2, network_on_cpu=True) == 1 and numba.get_num_threads() == 1
    finally:
        torch.set_num_threads(before[0])
        numba.set_num_threads(before[1])


def _forked_steps(queue) -> None:
    world = SearchWorld(CONFIGS["model_b"], n_worlds=4, seed=0)
    world.reset()
    for _ in range(3):
        tr = world.step(np.ones((4, 6), np.int64))
    queue.put(tr.maps.tobytes())


def test_a_forked_child_steps_its_worlds():
    """After the parent's threads ran a parallel region, a forked child (multiprocessing's fork) still steps worlds,
    the same as the parent (GNU OpenMP would kill it if it opened a parallel region: it runs them on one thread)."""
    before = numba.get_num_threads()
    numba.set_num_threads(TWO)
    try:
        context = multiprocessing.get_context("fork")
        parent, queue = context.Queue(), context.Queue()
        _forked_steps(parent)  # the parent's parallel regions first
        child = context.Process(target=_forked_steps, args=(queue,))
        child.start()
        child.join(120)
        assert child.exitcode == 0 and queue.get(timeout=5) == parent.get(timeout=5)
    finally:
        numba.set_num_threads(before)


def test_bench_world_measures_each_thread_count_in_one_run(monkeypatch, capsys):
    monkeypatch.setattr(bench_world, "CASES", (("n20_N4_K8", 20, 4, 8),))
    monkeypatch.setattr(bench_world, "_load_oracle", lambda: None)
    """`--threads 1,2` and repeated flags alike, each count once, measured in the same run; bad counts refused."""
    assert bench_main(["world", "--threads", f"1,{TWO}", "--threads", "1", "--seconds", "0.05", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["case"], r["threads"]) for r in rows] == [("n20_N4_K8", t) for t in dict.fromkeys([1, TWO])]
    assert all(r["engine"] == "batched" and r["agent_steps_per_s"] > 0 for r in rows)
    for row in rows:  # where each window's time went: the four parts, all of it, none twice
        shares = [row[f"{part}_share"] for part in bench_world.PARTS]
        assert all(share > 0 for share in shares[:3]) and sum(shares) == pytest.approx(1, abs=5e-4), row
    for bad, message in (("0", "--threads=0 is not allowed: 1 <= threads <= "),
                         ("1,x", "--threads=1,x is not allowed: thread counts separated by commas")):  # fmt: skip
        with pytest.raises(SystemExit):
            bench_main(["world", "--threads", bad])
        assert message in capsys.readouterr().err
