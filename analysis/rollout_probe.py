# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # The rollout planner at several budgets, measured with little noise (a probe, outside the library)
#
# Found fractions of one episode vary by 0.15-0.2 around a map's mean (where the targets fall, which detections
# succeed), so a gain of a few hundredths takes hundreds of maps to see. This probe plays B's teacher and the
# rollout planner (`controller=rollout`) at each budget (samples × horizon) on the same maps and streams, and
# scores each episode twice: its found fraction, and its **expected found fraction**, the chance that a target drawn
# as a reset draws it (§4.1.4: from the prior p, kept with probability 1 − u/max u) is detected along the path the
# team took, Σ w·(p0 − p_end) / Σ w·p0 with w = 1 − u0/max u0 (with λk = 1, p_end/p0 is exactly the chance a target
# in a cell escaped every footprint). Neither the teacher nor the planner reads a find (the planner reads which
# cells hold found targets, a small effect), so over targets drawn from the prior the two scores have one mean,
# and the expected one is free of the detection and placement noise. It is read when the episode ends, so where a
# team finds every target early (cells a rule nearly saturates) it favours the side that does not: there only the
# found fraction is a verdict. Paired per map: planner − teacher, the mean
# and its 95 % t-interval over maps; the cost: seconds per episode and agent decisions per second on one core.
#
#     python -m analysis.rollout_probe --cells 40x2,80x4 --maps 10 --budgets 1:0,1:32,4:0 \
#         --out analysis/out/rollout_probe
#
# A budget `M:H` is `controller.samples=M controller.horizon=H` (H = 0: to the episode's end).

# %%
import json
import time
from pathlib import Path

import numba
import numpy as np
import pandas as pd
from scipy import stats

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.bench.world import case_config
from searchrl.controllers.episodes import play_episodes
from searchrl.controllers.factory import heuristic_factory
from searchrl.reporting import cli
from searchrl.reporting.stats import markdown

parser = cli.parser("The rollout planner at several budgets against B's teacher", dirs=None)
parser.add_argument("--cells", default="40x2,80x4", help="n x N, comma-separated (Table 2's side n)")
parser.add_argument("--maps", type=int, default=10, help="maps per cell, >= 2")
parser.add_argument("--budgets", default="1:0,1:32,4:0", help="samples:horizon, comma-separated")
parser.add_argument("--settings", default="{}", help="other planner settings as JSON, e.g. '{\"confidence\": 1}'")
args, _ = cli.parse(parser)
OUT = cli.out_dir(args.out, Path("analysis") / "out" / "rollout_probe")
CELLS, BUDGETS = [], []
for cell in args.cells.split(","):
    n, _, team = cell.partition("x")
    if not (n.isdigit() and int(n) in (20, 40, 80, 160) and team.isdigit() and int(team) >= 1):
        cli.stop(f"--cells {cell!r} is not allowed: n x N with n one of 20, 40, 80, 160 and N >= 1, e.g. 40x2")
    CELLS.append((int(n), int(team)))
for budget in args.budgets.split(","):
    samples, _, horizon = budget.partition(":")
    if not (samples.isdigit() and int(samples) >= 1 and horizon.isdigit()):
        cli.stop(f"--budgets {budget!r} is not allowed: samples:horizon, samples >= 1, horizon >= 0, e.g. 4:32")
    BUDGETS.append((int(samples), int(horizon)))
try:
    EXTRA = json.loads(args.settings)
    assert isinstance(EXTRA, dict)
except (ValueError, AssertionError):
    cli.stop(f"--settings {args.settings!r} is not allowed: a JSON object of planner settings")
if args.maps < 2:
    cli.stop(f"--maps {args.maps} is not allowed: 2 or more (an interval needs two)")
numba.set_num_threads(1)
SEED = 7_000_000  # maps base + 100000·(10n + N) + map: none of the evaluation's (base + 100000·cell index + map)


# %%
class Recorder:
    """Wraps a controller: keeps each world's prior (p, u) at its reset, for the expected found fraction."""

    def __init__(self, inner, prior: dict) -> None:
        self.inner, self.config, self.prior = inner, inner.config, prior

    def reset(self, state, mask) -> None:
        if "p" not in self.prior or self.prior["p"].shape != state.p.shape:
            self.prior["p"], self.prior["u"] = state.p.copy(), state.u.copy()
        self.prior["p"][mask], self.prior["u"][mask] = state.p[mask], state.u[mask]
        self.inner.reset(state, mask)

    def act(self, state, maps, vector, active=None):
        return self.inner.act(state, maps, vector, active)


def episodes(n: int, n_agents: int, name: str, settings: dict) -> pd.DataFrame:
    """One episode per map: found fraction, expected found fraction, steps; and the seconds they took."""
    config = case_config(n, n_agents)
    seeds = [SEED + 100_000 * (10 * n + n_agents) + m for m in range(args.maps)]
    keys = [[SEED, n, n_agents, m] for m in range(args.maps)]
    prior, expected = {}, {}
    factory = heuristic_factory(name, settings)

    def on_done(state, first, playing) -> None:
        for k in np.flatnonzero(first):
            p0, u0 = prior["p"][k], prior["u"][k]
            w = np.where(state.blocked[k], 0.0, 1.0 - u0 / u0.max())
            expected[int(playing[k])] = float((w * (p0 - state.p[k])).sum() / (w * p0).sum())

    start = time.perf_counter()
    out = play_episodes(
        lambda c, s: Recorder(factory(c, s), prior), config, seeds, keys, needs_observation=False, on_done=on_done
    )
    seconds = time.perf_counter() - start
    return pd.DataFrame(
        {
            "n": n,
            "N": n_agents,
            "map": range(args.maps),
            "found": out["found_fraction"],
            "expected": [expected[m] for m in range(args.maps)],
            "L": out["L"],
            "seconds": seconds / args.maps,
        }
    )


# %%
rows, summary = [], []
for n, n_agents in CELLS:
    teacher = episodes(n, n_agents, "greedy_target", {"reach": 2.0}).assign(budget="teacher")
    rows.append(teacher)
    for samples, horizon in BUDGETS:
        label = f"{samples}:{horizon}"
        mine = episodes(n, n_agents, "rollout", {"samples": samples, "horizon": horizon, **EXTRA}).assign(budget=label)
        rows.append(mine)
        entry = {
            "n": n,
            "N": n_agents,
            "budget": label,
            "maps": args.maps,
            "teacher_found": teacher.found.mean(),
            "planner_found": mine.found.mean(),
        }
        for score in ("found", "expected"):
            diff = mine[score].to_numpy() - teacher[score].to_numpy()
            half = stats.t.ppf(0.975, len(diff) - 1) * diff.std(ddof=1) / np.sqrt(len(diff))
            entry |= {
                f"{score}_gain": diff.mean(),
                f"{score}_low": diff.mean() - half,
                f"{score}_high": diff.mean() + half,
            }
        entry["s_per_episode"] = mine.seconds.iloc[0]
        entry["decisions_per_s"] = mine.L.sum() * n_agents / (mine.seconds.iloc[0] * args.maps)
        summary.append(entry)
        print(
            f"{n}x{n_agents} {label}: expected {entry['expected_gain']:+.4f} [{entry['expected_low']:+.4f}, "
            f"{entry['expected_high']:+.4f}], {entry['s_per_episode']:.1f} s an episode",
            flush=True,
        )

# %%
OUT.mkdir(parents=True, exist_ok=True)
table = pd.DataFrame(summary)
write_atomic(OUT / "episodes.csv", lambda tmp: pd.concat(rows).to_csv(tmp, index=False))
write_atomic(OUT / "probe.csv", lambda tmp: table.to_csv(tmp, index=False))
text = markdown(table.set_index(["n", "N", "budget"]), digits=4)
write_text_atomic(OUT / "probe.md", text)
print(text)
