"""The statistics behind every verdict, at their boundaries: a CI that touches 0, saturation on one side only, the
95 % level, repeats averaged per map, the hard cells, and claim 1's region (n >= 40, N >= 4) in claims.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from searchrl.reporting.stats import (
    HARD_CELLS,
    bootstrap_mean_ci,
    efficiency_summary,
    is_hard,
    paired_margins,
    summarize,
)
from tests.scripts import run_script as _script

pytestmark = pytest.mark.app  # runs an app, a script or PPO updates: not in the fast layer (docs/testing.md)

ROOT = Path(__file__).resolve().parents[1]
CELL = {"model": "b", "n": 40, "N": 4}


def _pair(mine: list[float], base: list[float], **kwargs) -> pd.Series:
    """paired_margins of controller x (per-map found fractions `mine`) against y (`base`) on one cell, one row."""
    rows = []
    for seed, (a, b) in enumerate(zip(mine, base, strict=True)):
        rows += [{**CELL, "controller": "x", "map_seed": seed, "found_fraction": a},
                 {**CELL, "controller": "y", "map_seed": seed, "found_fraction": b}]  # fmt: skip
    (row,) = paired_margins(pd.DataFrame(rows), "x", "y", **kwargs).to_dict("records")
    return pd.Series(row)


# --- 1. "better" / "worse" need the 95 % CI to exclude 0 strictly


def test_a_ci_that_touches_zero_is_a_tie_not_a_verdict():
    """One map of 20 differs (+0.5), the rest tie exactly: a third of the resamples miss that map, so the lower
    bound is exactly 0.0. The rule is `low > 0` for better and `high < 0` for worse: touching 0 is a tie."""
    row = _pair([0.5] * 19 + [1.0], [0.5] * 20)
    assert row["low"] == 0.0 and row["high"] == pytest.approx(0.075) and row["diff"] == pytest.approx(0.025)
    assert row["verdict"] == "tie"
    swapped = _pair([0.5] * 20, [0.5] * 19 + [1.0])
    assert swapped["high"] == 0.0 and swapped["low"] == pytest.approx(-0.075) and swapped["verdict"] == "tie"
    # Both sides find everything on every map: the CI is [0, 0], a saturated tie, never "better" or "worse".
    same = _pair([1.0] * 20, [1.0] * 20)
    assert (same["low"], same["diff"], same["high"]) == (0.0, 0.0, 0.0) and same["verdict"] == "saturated"
    # Just off 0 on either side: a margin of 1/1024 on every map is a verdict.
    ahead = _pair([0.5 + 2**-10] * 20, [0.5] * 20)
    assert ahead["low"] == pytest.approx(2**-10) and ahead["verdict"] == "better"
    behind = _pair([0.5] * 20, [0.5 + 2**-10] * 20)
    assert behind["high"] == pytest.approx(-(2**-10)) and behind["verdict"] == "worse"


# --- 2. "saturated" needs both sides at or above the threshold


def test_saturated_needs_both_sides_at_the_threshold():
    """A tie is "saturated" when min(mine, base) >= `saturated`: at the threshold on both sides it is; with one side
    below (either one) it stays a tie."""
    both = _pair([1.0, 0.5] * 10, [0.5, 1.0] * 10, saturated=0.75)  # dyadic: both means are exactly 0.75
    assert (both["mine"], both["base"]) == (0.75, 0.75) and both["low"] < 0 < both["high"]
    assert both["verdict"] == "saturated"
    one = _pair([1.0, 0.5] * 10, [0.5, 0.875] * 10, saturated=0.75)
    assert (one["mine"], one["base"]) == (0.75, 0.6875) and one["low"] < 0 < one["high"] and one["verdict"] == "tie"
    other = _pair([0.5, 0.875] * 10, [1.0, 0.5] * 10, saturated=0.75)
    assert (other["mine"], other["base"]) == (0.6875, 0.75) and other["verdict"] == "tie"


def test_the_default_saturation_threshold_is_0995():
    both = _pair([1.0, 0.992] * 10, [0.992, 1.0] * 10)
    assert both["mine"] == pytest.approx(0.996) and both["base"] == pytest.approx(0.996)
    assert both["low"] < 0 < both["high"] and both["verdict"] == "saturated"
    one = _pair([1.0, 0.992] * 10, [0.988, 1.0] * 10)  # 0.996 against 0.994: one side below 0.995
    assert one["mine"] == pytest.approx(0.996) and one["base"] == pytest.approx(0.994)
    assert one["low"] < 0 < one["high"] and one["verdict"] == "tie"
    swapped = _pair([0.988, 1.0] * 10, [1.0, 0.992] * 10)
    assert swapped["low"] < 0 < swapped["high"] and swapped["verdict"] == "tie"
    below = _pair([1.0, 0.988] * 10, [0.988, 1.0] * 10)  # both 0.994
    assert below["verdict"] == "tie"


# --- 3. the intervals are 95 % intervals


def test_the_bootstrap_ci_is_the_95_percent_percentile_interval():
    """On a fixed sample and seed the bounds are the 2.5 % and 97.5 % quantiles of the 2000 resampled means."""
    sample = np.random.default_rng(1).random(30)
    mean, low, high = bootstrap_mean_ci(sample)
    means = sample[np.random.default_rng(0).integers(0, 30, size=(2000, 30))].mean(axis=1)
    assert mean == sample.mean()
    assert (low, high) == pytest.approx((np.quantile(means, 0.025), np.quantile(means, 0.975)), rel=1e-12, abs=0)
    assert low < np.quantile(means, 0.05) and high > np.quantile(means, 0.95)  # wider than a 90 % interval


def test_the_ci_half_width_is_196_standard_errors():
    """400 values, half 0 and half 1: the standard error of the mean is 0.5 / 20 = 0.025, so a 95 % interval is
    about ±1.96 of it (a 90 % one ±1.64), whichever path computes it: the bootstrap itself, summarize over maps
    and paired_margins over paired maps."""
    values = np.repeat([0.0, 1.0], 200)
    se = 0.5 / np.sqrt(values.size)
    mean, low, high = bootstrap_mean_ci(values)
    assert (mean, low, high) == pytest.approx((0.5, 0.45, 0.5525))  # 2.0 and 2.1 standard errors
    _, wide_low, wide_high = bootstrap_mean_ci(values, n_boot=20_000)
    assert 1.9 <= (wide_high - wide_low) / 2 / se <= 2.02
    episodes = pd.DataFrame({**CELL, "controller": "x", "map_seed": np.arange(values.size), "found_fraction": values})
    summary = summarize(episodes).iloc[0]
    assert (summary["mean"], summary["low"], summary["high"]) == pytest.approx((0.5, 0.45, 0.5525))
    zero = episodes.assign(controller="y", found_fraction=0.0)
    margin = paired_margins(pd.concat([episodes, zero]), "x", "y").iloc[0]
    assert (margin["diff"], margin["low"], margin["high"]) == pytest.approx((0.5, 0.45, 0.5525))
    assert 1.9 <= (margin["high"] - margin["low"]) / 2 / se <= 2.1


# --- 4. repeats are averaged per map before pairing


def test_paired_margins_average_each_maps_repeats_before_pairing():
    """Maps with 2 or 3 repeats of differing values: each map's repeats average to 0.5 (mine) and 0.25 (base), so
    every paired difference is 0.25 and the CI collapses onto it; any other way of reducing the repeats (the first,
    the largest, the median, pooling episodes, pairing repeats with repeats) gives other numbers."""
    rows = []
    for seed in range(20):
        mine, base = ([0.0, 1.0], [0.0, 0.0, 0.75]) if seed % 2 else ([0.125, 0.375, 1.0], [0.5, 0.0])
        rows += [{**CELL, "controller": "x", "map_seed": seed, "repeat": r, "found_fraction": v}
                 for r, v in enumerate(mine)]  # fmt: skip
        rows += [{**CELL, "controller": "y", "map_seed": seed, "repeat": r, "found_fraction": v}
                 for r, v in enumerate(base)]  # fmt: skip
    row = paired_margins(pd.DataFrame(rows), "x", "y").iloc[0]
    assert row["maps"] == 20 and row["verdict"] == "better"
    assert (row["mine"], row["base"], row["diff"], row["low"], row["high"]) == (0.5, 0.25, 0.25, 0.25, 0.25)


# --- 5. the hard cells


def test_hard_cells_are_exactly_the_twelve_at_and_below_each_boundary():
    """On the paper's grid (n 20..160, N 1..32/64/128/256): n = 40 with N <= 2, n = 80 with N <= 8, n = 160 with
    N <= 32, the boundary included and the next N out; no n = 20 cell, and a world size not listed is never hard."""
    grid = pd.DataFrame([(n, 2**k) for n, top in ((20, 5), (40, 6), (80, 7), (160, 8)) for k in range(top + 1)],
                        columns=["n", "N"])  # fmt: skip
    hard = grid[is_hard(grid)]
    assert list(zip(hard.n, hard.N, strict=True)) == [(40, 1), (40, 2), (80, 1), (80, 2), (80, 4), (80, 8), (160, 1),
                                                      (160, 2), (160, 4), (160, 8), (160, 16), (160, 32)]  # fmt: skip
    assert HARD_CELLS == {40: 2, 80: 8, 160: 32}
    edges = pd.DataFrame({"n": [40, 40, 40, 80, 80, 80, 160, 160, 160, 20, 20, 320],
                          "N": [1, 2, 3, 7, 8, 9, 31, 32, 33, 1, 2, 1]})  # fmt: skip
    assert is_hard(edges).tolist() == [True, True, False, True, True, False, True, True, False, False, False, False]


def test_efficiency_summary_averages_over_the_hard_cells_only():
    """Found fraction i / 64 in the i-th cell of a row per (n, N) at and around the boundaries; bound 1 except
    where noted: the hard means are those of the hard rows, and the unsaturated cells those with bound < 0.995."""
    cells = [(40, 2), (40, 4), (80, 8), (80, 16), (160, 32), (160, 64), (20, 1)]
    summary = pd.DataFrame({"controller": "x", "model": "b", "n": [n for n, _ in cells], "N": [a for _, a in cells],
                            "mean": [i / 64 for i in range(len(cells))],
                            "bound": [0.5, 0.995, 0.5, 1.0, 0.5, 0.99, 1.0]})  # fmt: skip
    summary["efficiency"] = summary["mean"] / summary["bound"]
    row = efficiency_summary(summary).loc[("x", "b")]
    assert row["hard found"] == (0 + 2 + 4) / 3 / 64 and row["hard bound"] == 0.5
    assert row["hard efficiency"] == pytest.approx((0 + 4 + 8) / 3 / 64)
    assert row["unsaturated cells"] == 4  # 0.5, 0.5, 0.5 and 0.99; 0.995 is not below 0.995
    assert row["their efficiency"] == pytest.approx((0 / 0.5 + 2 / 0.5 + 4 / 0.5 + 5 / 0.99) / 4 / 64)


# --- 6. claim 1's region in claims.py, and the same cells through compare.py

# (n, N): (policy's per-map found fractions, surfing's, maps). Region n >= 40 and N >= 4; (20, 4) and (40, 2) lie
# just outside it and are the worst cells, so a region that took them in would change every count and the worst.
SYNTHETIC = {
    (40, 4): ([0.6, 0.61, 0.62, 0.63] * 5, [0.5] * 20, 20),  # better
    (80, 8): ([0.6, 0.4] * 10, [0.5] * 20, 20),  # tie
    (80, 16): ([0.988, 1.0] * 10, [1.0, 0.988] * 10, 20),  # tie: both 0.994, just below saturation
    (160, 4): ([1.0] * 20, [1.0] * 20, 20),  # saturated: CI [0, 0]
    (160, 256): ([0.4] * 20, [0.5] * 20, 20),  # worse by 0.1, the worst in the region
    (40, 64): ([0.7] * 19, [0.5] * 19, 19),  # too few maps
    (20, 4): ([0.2] * 20, [0.5] * 20, 20),  # worse by 0.3, outside (n = 20)
    (40, 2): ([0.3] * 20, [0.5] * 20, 20),  # worse by 0.2, outside (N = 2)
}


@pytest.fixture(scope="module")
def synthetic_dirs(tmp_path_factory) -> dict[str, Path]:
    """Evaluation folders `policy` (controller policy:b) and `surfing`, two repeats per map (equal values)."""
    base = tmp_path_factory.mktemp("verdicts")
    dirs = {}
    for side, controller in ((0, "policy:b"), (1, "surfing")):
        folder = base / ("policy" if side == 0 else "surfing")
        (folder / "cells").mkdir(parents=True)
        for (n, agents), values in SYNTHETIC.items():
            found, maps = values[side], values[2]
            pd.DataFrame({"controller": controller, "model": "b", "n": n, "N": agents,
                          "map_seed": np.repeat(np.arange(maps) + 1000 * n + agents, 2), "repeat": [0, 1] * maps,
                          "found_fraction": np.repeat(found, 2), "L": 256}).to_parquet(
                folder / "cells" / f"n{n}_N{agents}.parquet")  # fmt: skip
        dirs[folder.name] = folder
    return dirs


def test_claim_1_counts_the_cells_of_its_region_only(synthetic_dirs, tmp_path):
    out = _script("claims.py", str(synthetic_dirs["policy"]), str(synthetic_dirs["surfing"]), "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr[-3000:]
    margins = pd.read_csv(tmp_path / "margins.csv")
    verdicts = dict(zip(zip(margins.n, margins.N, strict=True), margins.verdict, strict=True))
    assert verdicts == {(20, 4): "worse", (40, 2): "worse", (40, 4): "better", (40, 64): "too few maps",
                        (80, 8): "tie", (80, 16): "tie", (160, 4): "saturated", (160, 256): "worse"}  # fmt: skip
    assert margins.maps.tolist() == [20, 20, 20, 19, 20, 20, 20, 20]
    claims = (tmp_path / "claims.md").read_text()
    section = claims.split("## 1. DRL beats information surfing (cells with n ≥ 40 and N ≥ 4)\n\n")[1]
    region, rest = section.split("\nCells of that region where a policy does not find more than surfing")
    assert region == ("- b: better on 1 of 6 cells, tie 2, saturated 1, worse 1, too few maps 1; smallest margin "
                      "-0.100 [-0.100, -0.100] at n = 160, N = 256\n")  # fmt: skip
    table, everywhere = rest.split("\nAll cells:\n\n")
    rows = [line.split(" | ") for line in table.splitlines() if line.startswith("| n")]
    assert [(cell[2:], entry.removesuffix(" |").rsplit("] ", 1)[1]) for cell, entry in rows] == [
        ("n40 N64", "too few maps"), ("n80 N8", "tie"), ("n80 N16", "tie"), ("n160 N4", "saturated"),
        ("n160 N256", "worse")]  # fmt: skip
    assert "| n160 N256 | -0.100 [-0.100, -0.100] worse |" in table
    assert everywhere.startswith("- b: better on 1 of 8 cells, tie 2, saturated 1, worse 3, too few maps 1; "
                                 "smallest margin -0.300 [-0.300, -0.300] at n = 20, N = 4\n")  # fmt: skip
    # Where the policy trails surfing (all cells, outside the region too): every episode found 0.2/0.3/0.4 < 1.
    trailing = claims.split("Cells where a policy trails surfing: share of episodes that find every target, mean L:")
    assert len(trailing) == 2 and trailing[1].count("| policy:b | ") == 3


def test_compare_tallies_the_same_cells(synthetic_dirs, tmp_path):
    out = _script("compare.py", str(synthetic_dirs["policy"]), str(synthetic_dirs["surfing"]), "--out", str(tmp_path))
    assert out.returncode == 0, out.stderr[-3000:]
    text = (tmp_path / "compare.md").read_text()
    assert "## policy − surfing\n\nbetter 1, tie 2, saturated 1, worse 3, too few maps 1 of 8 cells\n" in text
    compared = pd.read_csv(tmp_path / "compare.csv").set_index(["n", "N"])
    assert compared.loc[(80, 16), "verdict"] == "tie" and compared.loc[(160, 4), "verdict"] == "saturated"
    assert compared.loc[(160, 4), ["low", "high"]].tolist() == [0.0, 0.0]
