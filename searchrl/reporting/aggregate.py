"""Aggregate scores over many cells and scenarios the way rliable does (Agarwal et al., "Deep Reinforcement Learning
at the Edge of the Statistical Precipice", NeurIPS 2021), on the suite's own units.

A *task* is one (scenario, n, N) cell; a *run* of a controller on a task is one map (its repeats averaged), so every
controller meets the same runs (evaluations of one seed and grid play the same maps). Scores are found fractions,
already on one scale across tasks. Each statistic comes with a 95 % percentile interval from a bootstrap that
resamples the maps within each task (rliable's stratified bootstrap), with a fixed generator:

- `iqm`: the interquartile mean of all (task, map) scores: the mean of the middle 50 %, robust to a few saturated or
  collapsed cells, where the mean is not and the median ignores most scores.
- `performance_profile`: for each threshold τ, the share of (task, map) scores above τ.
- `probability_of_improvement`: P(X > Y) of controller X over Y, per task the chance that a map of X's beats a map
  of Y's (ties count half: the Mann-Whitney statistic over all pairs of maps), averaged over tasks.

rliable itself (1.2, its repository archived) pins an old `arch` for its bootstrap; these few functions in numpy
give the same statistics without it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

TASK = ["scenario", "n", "N"]


def task_scores(episodes: pd.DataFrame) -> dict[str, dict[tuple, np.ndarray]]:
    """{controller: {task: (maps,) found fraction, repeats averaged, in map-seed order}} of `load`'s episodes."""
    per_map = episodes.groupby(["controller", *TASK, "map_seed"])["found_fraction"].mean()
    out: dict[str, dict[tuple, np.ndarray]] = {}
    for (controller, *task), scores in per_map.groupby(level=["controller", *TASK]):
        out.setdefault(str(controller), {})[tuple(task)] = scores.to_numpy()
    return out


def interquartile_mean(values: np.ndarray) -> float:
    """The mean of the middle 50 % of `values` (the bottom and top quarter trimmed, as scipy's trim_mean(0.25))."""
    values = np.sort(np.asarray(values, float).ravel())
    cut = int(np.floor(0.25 * values.size))
    return float(values[cut : values.size - cut].mean())


def bootstrap(
    statistic: Callable[..., float | np.ndarray],
    *controllers: dict[tuple, np.ndarray],
    n_boot: int = 2000,
    seed: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(statistic, low, high) of `statistic(*controllers)` (each {task: maps' scores}) with its 95 % interval: maps
    resampled within each task, the same draw of map indices for every controller (their maps pair)."""
    point = np.asarray(statistic(*controllers), float)
    rng, draws = np.random.default_rng(seed), []
    for _ in range(n_boot):
        index = {task: rng.integers(0, s.size, s.size) for task, s in controllers[0].items()}
        draws.append(statistic(*({t: c[t][index[t]] for t in index} for c in controllers)))
    draws = np.asarray(draws, float)
    return point, np.quantile(draws, 0.025, axis=0), np.quantile(draws, 0.975, axis=0)


def iqm(tasks: dict[tuple, np.ndarray]) -> float:
    return interquartile_mean(np.concatenate(list(tasks.values())))


def performance_profile(tasks: dict[tuple, np.ndarray], thresholds: np.ndarray) -> np.ndarray:
    """(thresholds,) share of all (task, map) scores above each threshold."""
    scores = np.concatenate(list(tasks.values()))
    return (scores[None, :] > np.asarray(thresholds)[:, None]).mean(axis=1)


def probability_of_improvement(x: dict[tuple, np.ndarray], y: dict[tuple, np.ndarray]) -> float:
    """P(X > Y): per task the share of (map of X, map of Y) pairs X wins, ties half; the mean over the tasks both
    have."""
    shared = [task for task in x if task in y]
    if not shared:
        raise ValueError("the two controllers share no task (cell): evaluate them on the same grid")
    wins = []
    for task in shared:
        a, b = x[task][:, None], y[task][None, :]
        wins.append(float(((a > b) + 0.5 * (a == b)).mean()))
    return float(np.mean(wins))


def common_tasks(*controllers: dict[tuple, np.ndarray]) -> list[dict[tuple, np.ndarray]]:
    """The controllers restricted to the tasks all of them have, each task's maps cut to the fewest any has."""
    shared = set.intersection(*(set(c) for c in controllers))
    if not shared:
        raise ValueError("the evaluations share no cell: give folders of one grid and seed")
    sizes = {task: min(c[task].size for c in controllers) for task in shared}
    return [{task: c[task][: sizes[task]] for task in sorted(shared)} for c in controllers]
