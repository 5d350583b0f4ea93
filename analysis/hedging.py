# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # Tuning the hedging rules on seeds apart from the suite's
#
# The prior-error suite (conf/suite/prior_error.yaml) compares fixed rules with learned policies; a rule's knob
# tuned on the suite's own maps would flatter it. This notebook plays each candidate setting of the two hedging
# rules, greedy on a hedged belief (`controller=greedy_target controller.reach=2 controller.hedge=ε`) and the
# evidence switch (`controller=switch controller.threshold=θ`), on the suite's scenarios at severities 0, 0.5 and 1
# and a subset of its cells, with maps drawn from the tuning seed 3,000,000 (the suite's are 7,000,000, validation's
# 10⁶), and keeps the setting with the highest mean found fraction over every scenario: one setting for all
# families, since the families' names are unknown to a searcher in the field.
#
# Candidate learned policies are measured on the same maps (`--checkpoint label=path/model.zip`, repeatable; with
# `--policies-only` the rules' rows are read back from hedging.csv): how an approach to the adaptive policy is
# chosen without looking at the suite.
#
#     python analysis/hedging.py [--maps 16] [--out DIR]   # -> hedging.csv, hedging.md
#     python analysis/hedging.py --policies-only --checkpoint term_b=runs/reference/term/b/model.zip
#     python analysis/hedging.py --policies-only --switch-policy term_b_switch0.25=runs/reference/term/b/model.zip@0.25

# %%
from pathlib import Path

import numpy as np
import pandas as pd
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from searchrl.atomic import write_atomic, write_text_atomic
from searchrl.controllers.policy import PolicyController
from searchrl.controllers.registry import make_controller
from searchrl.controllers.switch import EvidenceSwitch
from searchrl.evaluate.grid import table2_cells
from searchrl.evaluate.runner import run_cell
from searchrl.evaluate.schema import register_configs
from searchrl.evaluate.suite import SuiteConfig, suite_scenarios
from searchrl.policies.checkpoint import checkpoint_config, load_actor
from searchrl.reporting import cli
from searchrl.shared_schema import group_option
from searchrl.world.config import WorldConfig

parser = cli.parser("Tune the hedging rules' knobs on tuning seeds", dirs=None)
parser.add_argument("--maps", type=int, default=16, help="maps per cell (>= 2)")
parser.add_argument("--checkpoint", action="append", default=[], help="label=path/model.zip: a policy to measure")
parser.add_argument(
    "--switch-policy",
    action="append",
    default=[],
    help="label=path/model.zip@θ: the evidence switch with that policy in place of target-greedy (threshold θ)",
)
parser.add_argument("--policies-only", action="store_true", help="measure the policies only, the rules read back")
parser.add_argument("--cells", default="n40_N1,n40_N4,n40_N16,n80_N1,n80_N4,n80_N16", help="n<n>_N<N>, comma-separated")
parser.add_argument(
    "--rules",
    default=None,
    help="rules to measure, comma-separated (default: every candidate; none with --policies-only)",
)
args, _ = cli.parse(parser)
if args.maps < 2:
    parser.error(f"--maps={args.maps} is not allowed: an integer >= 2")


def switch_policy(given: str) -> tuple[str, str, float]:
    """label, model.zip, θ from `label=path/model.zip@θ`; one line naming the value where it is not that."""
    label, _, rest = given.partition("=")
    path, _, threshold = rest.rpartition("@")
    try:
        theta = float(threshold)
    except ValueError:
        theta = -1.0
    if not label or not Path(path).is_file() or not 0 <= theta <= 1:
        parser.error(f"--switch-policy={given!r} is not allowed: label=path/model.zip@θ, an existing file, 0 <= θ <= 1")
    return label, path, theta


switch_policies = [switch_policy(given) for given in args.switch_policy]
OUT = cli.out_dir(args.out, Path.cwd() / "analysis" / "out" / "hedging")
OUT.mkdir(parents=True, exist_ok=True)
TUNING_SEED = 3_000_000  # apart from training (small), validation (10⁶) and evaluation (7·10⁶) seeds
CONF = Path(__file__).resolve().parents[1] / "conf"

# %%
suite = OmegaConf.to_container(OmegaConf.merge(OmegaConf.structured(SuiteConfig), group_option("suite", "prior_error")))
suite["severities"] = [0.5, 1.0]
scenarios = suite_scenarios(suite)
grid = suite["grid"]
every = table2_cells(grid["world_sizes"], grid["n_targets"], grid["n_distributions"], grid["max_agents"])
cells = [(i, c) for i, c in enumerate(every) if c.key in args.cells.split(",")]
if not cells:
    parser.error(f"--cells={args.cells!r} names no cell of the suite's grid (n 40, 80, 160 x N 1 ... 256)")
register_configs()
with initialize_config_dir(str(CONF), version_base="1.3"):  # the world `+model=b` gives a heuristic's evaluation
    world = WorldConfig.from_dict(OmegaConf.to_container(compose("evaluate", ["+model=b"]).env.world, resolve=True))

CANDIDATES = {
    "greedy": ("greedy_target", {"reach": 2.0}),
    **{f"hedge{e:g}": ("greedy_target", {"reach": 2.0, "hedge": e}) for e in (0.1, 0.25, 0.5, 1.0)},
    **{f"switch{t:g}": ("switch", {"threshold": t}) for t in (0.25, 0.5, 0.75)},
    "coverage": ("coverage", {}),
    "sweep": ("sweep", {}),
}


# %%
def measure(label, world, factory, needs_observation):
    rows = []
    for scenario in scenarios:
        for index, cell in cells:
            frame = run_cell(
                factory,
                world,
                cell,
                index,
                args.maps,
                1,
                TUNING_SEED,
                needs_observation=needs_observation,
                scenario=scenario,
            )
            rows.append(
                {
                    "rule": label,
                    "scenario": scenario.label,
                    "family": scenario.family,
                    "severity": scenario.severity,
                    "n": cell.n,
                    "N": cell.n_agents,
                    "found_fraction": frame["found_fraction"].mean(),
                }
            )
    print(label, np.mean([r["found_fraction"] for r in rows]), flush=True)
    return rows


rows = []
if args.rules:
    chosen = args.rules.split(",")
else:
    chosen = [] if args.policies_only else list(CANDIDATES)
unknown = [label for label in chosen if label not in CANDIDATES]
if unknown:
    parser.error(f"rule {unknown[0]!r} is not allowed: one of {', '.join(CANDIDATES)}")
rules = {label: CANDIDATES[label] for label in chosen}
if args.policies_only:  # the rows of an earlier run, but of the policies and rules measured now
    given = [c.partition("=")[0] for c in args.checkpoint + args.switch_policy] + chosen
    rows = pd.read_csv(OUT / "hedging.csv").query("rule not in @given").to_dict("records")
for label, (name, settings) in rules.items():

    def factory(config, streams, name=name, settings=settings):
        return make_controller(name, config, seed=streams, settings=settings)

    rows += measure(label, world, factory, False)


def load_policy(path: str) -> tuple[WorldConfig, object]:
    """The world a checkpoint was trained in and its actor."""
    world_dict, _, _ = checkpoint_config(path)
    policy_world = WorldConfig.from_dict(world_dict)
    return policy_world, load_actor(path, policy_world)


for given in args.checkpoint:
    label, _, path = given.partition("=")
    policy_world, actor = load_policy(path)

    def policy(config, streams, actor=actor):
        return PolicyController(actor, config, seed=streams)

    rows += measure(label, policy_world, policy, True)


class PolicySwitch(EvidenceSwitch):
    """The evidence switch (searchrl/controllers/switch.py) with a policy where it runs target-greedy: the policy
    while the team finds what the prior promised where it swept, geometric coverage once the finds fall behind."""

    def __init__(self, actor, config, threshold, seed):
        super().__init__(config, threshold, seed)
        self.greedy = PolicyController(actor, config, seed=seed)


for label, path, threshold in switch_policies:
    policy_world, actor = load_policy(path)

    def switched(config, streams, actor=actor, threshold=threshold):
        return PolicySwitch(actor, config, threshold, streams)

    rows += measure(label, policy_world, switched, True)
table = pd.DataFrame(rows)
write_atomic(OUT / "hedging.csv", lambda tmp: table.to_csv(tmp, index=False))

# %%
per_family = table.groupby(["rule", "family"])["found_fraction"].mean().unstack("family")
per_family["mean"] = table.groupby("rule")["found_fraction"].mean()
per_family = per_family.sort_values("mean", ascending=False)
lines = [
    f"Mean found fraction on tuning seeds ({args.maps} maps per cell; cells {args.cells}; "
    "severities 0.5 and 1 per family, paper = the prior right), sharp priors (variance scale 1)",
    "",
    "| rule | " + " | ".join(per_family.columns) + " |",
    "|---" * (len(per_family.columns) + 1) + "|",
]
lines += [f"| {rule} | " + " | ".join(f"{v:.3f}" for v in row) + " |" for rule, row in per_family.iterrows()]
# The headroom for adapting: a selector told the scenario and the cell, taking the better of the best rule and
# coverage there (an upper bound for any searcher that chooses between the two from what it observes).
cells_by_rule = table.pivot_table(index=["scenario", "n", "N"], columns="rule", values="found_fraction")
best = per_family.index[0]
if "coverage" in cells_by_rule and best != "coverage":
    both = cells_by_rule[[best, "coverage"]].max(axis=1).mean()
    lines += [
        "",
        f"Told the scenario and cell, the better of {best} and coverage there: {both:.3f} "
        f"({best} alone {per_family.loc[best, 'mean']:.3f}); the best measured rule per scenario and cell: "
        f"{cells_by_rule.max(axis=1).mean():.3f}.",
    ]
write_text_atomic(OUT / "hedging.md", "\n".join(lines) + "\n")
print("\n".join(lines))
