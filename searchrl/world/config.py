"""World configuration: every constant of the search world, validated before any work.

Values the paper fixes (λ, Γ, Table 1 rewards, 256 steps, the training ranges of §4.1) are defaults here;
values it leaves open (k, ξ, τ, η, ρ bound, variance floor, obstacle density, observation scaling) are fields
with a default and a reason in docs/world.md, "Deviations and choices".
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields

import numpy as np

from searchrl.world.footprint import GAMMA


class ConfigError(ValueError):
    """The one refusal of the library: a setting outside what is allowed, or a file or folder it cannot use; the
    message names the value and what is allowed. The entry points print it as one line and exit with `code`
    (searchrl/multirun.py); a multirun fails that job only."""

    code = 2

    @property
    def message(self) -> str:
        return str(self)


class MissingFile(ConfigError, FileNotFoundError):
    """A file a setting names does not exist: a refusal that a caller may also catch as FileNotFoundError."""


@contextmanager
def in_context(context: str) -> Iterator[None]:
    """A refusal raised inside is said after `context` ("grid cell 3 (n=20, N=2): <refusal>"), its type kept."""
    try:
        yield
    except ConfigError as err:
        err.args = (f"{context}: {err}",)
        raise


def need(ok: bool, name: str, value: object, allowed: str) -> None:
    """Raise ConfigError "name=value is not allowed: allowed" unless `ok`: the one wording of every refusal."""
    if not ok:
        raise ConfigError(f"{name}={value!r} is not allowed: {allowed}")


def is_int(value: object) -> bool:
    """A Python or numpy integer, not a bool."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def check_seed(seed: object, name: str = "seed") -> None:
    """ConfigError unless `seed` is None or an integer >= 0 (what np.random.default_rng takes)."""
    need(seed is None or (is_int(seed) and seed >= 0), name, seed, "None or an integer >= 0")


def _is_number(value: object) -> bool:
    return (is_int(value) or isinstance(value, (float, np.floating))) and math.isfinite(value)


# What each annotation of WorldConfig allows, checked for every field before its range.
_KINDS = {
    "int": (is_int, "an integer"),
    "float": (_is_number, "a finite number"),
    "bool": (lambda v: isinstance(v, (bool, np.bool_)), "True or False"),
    "str": (lambda v: isinstance(v, str), "a string"),
    "tuple[int, int]": (
        lambda v: isinstance(v, (tuple, list)) and len(v) == 2 and all(is_int(x) for x in v),
        "a pair of integers (low, high)",
    ),
}


def _check_range(name: str, rng: tuple, low: float, high: float | None = None) -> None:
    need(
        isinstance(rng, (tuple, list)) and len(rng) == 2,
        name,
        rng,
        "expected a pair (low, high)",
    )
    lo, hi = rng
    upper = "" if high is None else f" and high <= {high}"
    need(low <= lo <= hi and (high is None or hi <= high), name, rng, f"need {low} <= low <= high{upper}")


@dataclass(frozen=True)
class WorldConfig:
    """All constants of one search world. Ranges are inclusive (low, high) pairs drawn per world at reset."""

    # --- scenario (§4.1): a world draws its side, Gaussian count and target count from these ranges
    world_size: tuple[int, int] = (20, 128)  # n, §4.1.2; an integer n is the range (n, n)
    n_distributions: tuple[int, int] = (16, 32)  # m, §4.1.3
    n_targets: tuple[int, int] = (8, 16)  # j, §4.1.4
    n_agents: int = 8  # N, fixed during training (§4.1.2)
    prob_variance_scale: float = 10.0  # σ² drawn in [variance_floor, 10 n) for p (§4.1.3)
    unc_variance_scale: float = 20.0  # σ² drawn in [variance_floor, 20 n) for u (§4.1.3)
    variance_floor: float = 1.0  # paper: (0, ·); a floor of one cell keeps every Gaussian visible on the grid
    rho_max: float = 0.8  # ρ drawn in (-rho_max, rho_max): bounded away from ±1 so eq. 6 stays finite
    eta: float = 0.1  # baseline share of probability spread evenly over cells (eq. 7)

    # --- sensing (§3.1): Δp = λ k Γ p, with k = k + k_per_n · n for a world of side n ("k a coefficient related
    # to world size n"; the paper gives no formula). k = 1000, k_per_n = 0 (λk = 1) makes sensing the Bayesian
    # non-detection update p <- p (1 - Γ); k = 0, k_per_n = 1 is the paper's reading k = n (conf/world/).
    lam: float = 0.001  # λ, paper value
    k: float = 1000.0
    k_per_n: float = 0.0

    # --- agent model (§3.2, §6.1.2): Φ and communication distinguish models A, B, C
    explicit_area: int = 5  # Φ side: 11 (model A) or 5 (B, C, diagonal)
    fov: int = 11  # Θ side of the observation window
    communication: bool = True  # min-merge of beliefs with neighbours (§5); off for A and C
    comm_range: int = 5  # side of the square communication area (the 5x5 of Γ, §5.1)
    diagonal: bool = False  # 9 actions instead of 5
    # Observation only (not in the paper; 0 = off): the belief channels show an agent's belief of a cell
    # exp(−belief_age·ρ·(t − t₀)) times, t₀ the last step it saw the cell's truth in Φ and ρ = N·ΣΓ / free cells
    # the rate at which an evenly spread team senses a cell. Without merging (model C) a belief off the agent's
    # own path stays the prior; this shows how stale it is (docs/world.md, "Deviations and choices").
    belief_age: float = 0.0
    # With belief_age > 0: show that factor as a sixth channel (the belief channels keep their scale) instead of
    # multiplying the belief channels by it. Scaled views fade to nearly nothing in crowded worlds, where the
    # factor is small almost everywhere; a channel keeps both what the agent believes and how stale it is.
    belief_age_channel: bool = False
    # With belief_age > 0: the freshness also falls by (1 − Γ) under the footprint of every neighbour the agent
    # sees in its field of view, back to 1 where it next sees the truth in Φ (searchrl/world/seen.py). Without
    # merging (model C) this is all an agent can learn of what others cleared, and it is what C's teacher keeps
    # in memory (greedy's `seen`); shown, a clone need not remember it. Costs K·N·S² float32 more when on.
    belief_seen: bool = False

    # --- rewards (Table 1, eq. 5, eq. 17)
    step_reward: float = -0.05
    collision_reward: float = -0.2
    target_reward: float = 10.0
    xi: float = 0.05  # ξ of eq. 5; 2ξ/λ = 100 is the whole map's worth of information
    tau: float = 0.01  # τ of eq. 17

    max_steps: int = 256  # episode length (§4.1.1)

    def __post_init__(self) -> None:
        if is_int(self.world_size):  # world_size=20: every world is 20×20, the range (20, 20)
            object.__setattr__(self, "world_size", (int(self.world_size), int(self.world_size)))
        self.validate()

    @property
    def n_actions(self) -> int:
        return 9 if self.diagonal else 5

    @property
    def bayesian_sensing(self) -> bool:
        """λk = 1 in every world: one footprint scales p and u by (1 − Γ), the non-detection update."""
        return self.k_per_n == 0 and abs(self.lam * self.k - 1.0) < 1e-9

    @property
    def sensing_label(self) -> str:
        """The world's name in result tables: "bayes" (λk = 1), "paper" (k = n), else "k<k>+<k_per_n>n"."""
        if self.bayesian_sensing:
            return "bayes"
        if self.k == 0 and self.k_per_n == 1 and self.lam == 0.001:
            return "paper"
        label = f"k{self.k:g}+{self.k_per_n:g}n"
        return label if self.lam == 0.001 else f"lam{self.lam:g}_{label}"

    def sensing_rate(self, sides: np.ndarray) -> np.ndarray:
        """(K,) float64: c = λ·k of each world, k = k + k_per_n · n for its side n (`sides`, (K,) ints)."""
        return self.lam * (self.k + self.k_per_n * np.asarray(sides, np.float64))

    @property
    def halo(self) -> int:
        """Padding around every map so windows (FOV, Φ, Γ, communication) never leave the array."""
        return max(self.fov, self.explicit_area, self.comm_range, GAMMA.shape[0]) // 2

    def validate(self) -> None:
        for f in fields(self):  # types first: a string, NaN or fractional count never reaches a comparison
            is_kind, kind = _KINDS[f.type]
            if f.name == "world_size":
                kind = f"{kind}, or an integer n (every world n×n)"
            need(is_kind(getattr(self, f.name)), f.name, getattr(self, f.name), kind)
        _check_range("world_size", self.world_size, 5, 2048)
        _check_range("n_distributions", self.n_distributions, 1)
        _check_range("n_targets", self.n_targets, 1)
        need(1 <= self.n_agents <= 4096, "n_agents", self.n_agents, "1 <= n_agents <= 4096")
        for name in ("prob_variance_scale", "unc_variance_scale"):
            need(0 < getattr(self, name) <= 1e6, name, getattr(self, name), "0 < scale <= 1e6 (σ² < scale · n)")
        smallest_scale = min(self.prob_variance_scale, self.unc_variance_scale)
        need(
            0 < self.variance_floor < smallest_scale * self.world_size[0],
            "variance_floor",
            self.variance_floor,
            "0 < variance_floor < min(prob_variance_scale, unc_variance_scale) * smallest world size",
        )
        need(0 <= self.rho_max < 1, "rho_max", self.rho_max, "0 <= rho_max < 1")
        need(0 <= self.eta <= 1, "eta", self.eta, "0 <= eta <= 1")
        need(self.lam > 0, "lam", self.lam, "> 0")
        need(self.k >= 0, "k", self.k, ">= 0")
        need(self.k_per_n >= 0, "k_per_n", self.k_per_n, ">= 0")
        lo, hi = self.world_size
        need(self.k + self.k_per_n * lo > 0, "k", self.k, "k + k_per_n * n > 0 in the smallest world (sensing)")
        largest = self.lam * (self.k + self.k_per_n * hi)
        name, value = ("lam", self.lam) if self.lam != 0.001 else ("k", self.k)  # the one moved from the paper's
        need(
            largest * float(GAMMA.max()) <= 1.0 + 1e-12,
            name,
            value,
            f"lam * (k + k_per_n * n) * max(Γ) <= 1 so no cell loses more than it holds (here {largest:g} at n={hi}"
            f" with lam={self.lam:g}, k={self.k:g}, k_per_n={self.k_per_n:g})",
        )
        for name in ("fov", "explicit_area", "comm_range"):
            v = getattr(self, name)
            need(1 <= v <= 101 and v % 2 == 1, name, v, "an odd integer from 1 to 101")
        need(
            self.explicit_area <= self.fov,
            "explicit_area",
            self.explicit_area,
            f"Φ must fit inside the field of view (fov={self.fov})",
        )
        need(0 <= self.belief_age <= 4, "belief_age", self.belief_age, "0 <= belief_age <= 4 (0: beliefs do not age)")
        need(
            self.belief_age == 0 or self.bayesian_sensing,
            "belief_age",
            self.belief_age,
            "0 unless lam * k = 1 and k_per_n = 0: a belief's age and belief_seen model sensing as p·(1 − Γ)",
        )
        need(
            isinstance(self.belief_age_channel, bool) and (not self.belief_age_channel or self.belief_age > 0),
            "belief_age_channel",
            self.belief_age_channel,
            "True or False, and False unless belief_age > 0 (the channel shows the belief's age)",
        )
        need(
            isinstance(self.belief_seen, bool) and (not self.belief_seen or self.belief_age > 0),
            "belief_seen",
            self.belief_seen,
            "True or False, and False unless belief_age > 0 (it scales the belief's freshness)",
        )
        need(self.max_steps >= 1, "max_steps", self.max_steps, ">= 1")
        need(self.xi >= 0, "xi", self.xi, ">= 0")
        need(self.tau >= 0, "tau", self.tau, ">= 0")
        # Agents and targets need distinct cells in the smallest world (a scenario with obstacles checks its own).
        free = self.world_size[0] ** 2
        need(
            self.n_agents <= free,
            "n_agents",
            self.n_agents,
            f"at most {free} agents fit on the free cells of the smallest world (n={self.world_size[0]})",
        )
        need(
            self.n_agents + self.n_targets[1] <= free,
            "n_targets",
            self.n_targets,
            f"agents and targets start on distinct cells: n_agents + max targets <= {free} free cells"
            f" of the smallest world (n={self.world_size[0]})",
        )

    @classmethod
    def from_dict(cls, values: dict) -> WorldConfig:
        """Build from a plain mapping (Hydra, JSON, a saved run); unknown keys are an error naming them."""
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(values) - known)
        if unknown:
            raise ConfigError(f"unknown world config field(s) {unknown}; allowed: {sorted(known)}")
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()}
        return cls(**kw)
