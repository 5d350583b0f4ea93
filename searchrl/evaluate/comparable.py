"""Which evaluation folders may be put side by side: results of the same worlds, whatever played them.

Two folders are paired map by map (searchrl/reporting/stats.py's `paired_margins`, `baseline=`, every analysis
script). A map is named by its seed, and a seed names the same map only under the same settings: the evaluation's
`seed`, its scenario (obstacles, prior family, target placement), the grid's lists (a cell's maps are seeded by its
index in them, and its targets and Gaussians are theirs) and the world's map and sensing settings. Those are a
folder's **worlds** (`world_identity`); folders whose worlds differ are refused in one line that names both sides
and what differs (`check_comparable`), never paired. What may differ is what plays the worlds: the controller or
checkpoint, its model (A, B, C, diagonal), the inference path and device, and how many maps and repeats each
holds (pairs are made on the maps both ran); `comparison_note` says which of those differ, for a table's head.

A setting only one side records (a checkpoint's folder keeps its world in the run, a folder written before a
setting existed) is not compared; the sensing label every cell row carries is.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pyarrow.parquet as pq
from omegaconf import OmegaConf

from searchrl.evaluate.grid import cell_files
from searchrl.shared_schema import dotted_leaves
from searchrl.world.scenario import Scenario

# The grid's lists: which maps each cell holds (its index seeds them) and its targets and Gaussians.
GRID_KEYS = ("world_sizes", "n_targets", "n_distributions", "max_agents")
# The world's settings that make its maps and its sensing (a heuristic's folder records them; a policy's run does).
# Communication, the move set, the view and the rewards are the model's and the controller's: they may differ.
MAP_AND_SENSING = (
    "prob_variance_scale",
    "unc_variance_scale",
    "variance_floor",
    "rho_max",
    "eta",
    "lam",
    "k",
    "k_per_n",
    "explicit_area",
    "max_steps",
)
# What may differ between compared folders, as an evaluation.yaml names it: said in a table's head.
PLAYERS = ("controller", "model", "checkpoint_sha256", "inference", "device", "deterministic")


class Incomparable(ValueError):
    """Two evaluation folders hold results of other worlds; the message is one line naming both and the difference."""


def _record(out_dir: str | Path) -> dict[str, Any]:
    try:
        record = OmegaConf.to_container(OmegaConf.load(Path(out_dir) / "evaluation.yaml"))
    except Exception:  # none, or a damaged one: the folder's other checks name it; its rows still say something
        return {}
    return record if isinstance(record, dict) else {}


def identity_of(record: dict[str, Any], sensing: str | None = None) -> dict[str, Any]:
    """{dotted setting: value} of the worlds an evaluation record (evaluation.yaml, or the settings an evaluation is
    about to record) describes; `sensing` is its rows' sensing label where known."""
    identity: dict[str, Any] = {}
    if "seed" in record:
        identity["seed"] = record["seed"]
    if "grid" in record:  # a record made before scenarios existed ran the paper's
        identity["scenario"] = Scenario.from_dict(record.get("scenario")).to_dict()
        identity["grid"] = {key: record["grid"][key] for key in GRID_KEYS if key in record["grid"]}
    if isinstance(record.get("world"), dict):
        identity["world"] = {key: record["world"][key] for key in MAP_AND_SENSING if key in record["world"]}
    if sensing is not None:
        identity["sensing"] = sensing
    return dotted_leaves(identity)


def world_identity(out_dir: str | Path) -> dict[str, Any]:
    """The worlds an evaluation folder holds results of (`identity_of` its record and its first cell's rows)."""
    cells = cell_files(out_dir)
    sensing = None
    if cells and "world" in pq.read_schema(cells[0]).names:
        sensing = str(pq.read_table(cells[0], columns=["world"]).column("world")[0])
    return identity_of(_record(out_dir), sensing)


def world_differences(theirs: dict[str, Any], ours: dict[str, Any]) -> list[tuple[str, Any, Any]]:
    """(setting, their value, our value) for each setting both identities hold that differs."""
    return [(key, theirs[key], ours[key]) for key in sorted(theirs.keys() & ours.keys()) if theirs[key] != ours[key]]


def check_comparable(out_dirs: Sequence[str | Path]) -> None:
    """Incomparable unless every folder holds results of the first one's worlds."""
    if len(out_dirs) < 2:
        return
    first = world_identity(out_dirs[0])
    for other in out_dirs[1:]:
        differ = world_differences(world_identity(other), first)
        if differ:
            named = "; ".join(f"{key}: {a!r} in {other}, {b!r} in {out_dirs[0]}" for key, a, b in differ)
            raise Incomparable(
                f"{other} and {out_dirs[0]} hold results of other worlds ({named}): a map seed names one map only "
                "under the same seed, scenario, grid and world; evaluate both alike to compare them"
            )


def comparison_note(out_dirs: Sequence[str | Path]) -> str:
    """One line for a table's head: the worlds the folders share, and what differs between them by design."""
    records = [_record(d) for d in out_dirs]
    differ = [key for key in PLAYERS if len({str(r[key]) for r in records if key in r}) > 1]
    shapes = {(r.get("grid", {}).get("maps_per_cell"), r.get("grid", {}).get("repeats")) for r in records}
    if len(shapes) > 1:
        differ.append("maps and repeats (paired on the maps both ran)")
    first = records[0] if records else {}
    scenario = Scenario.from_dict(first.get("scenario")).label
    what = ", ".join(differ) or "nothing recorded"
    seed = first.get("seed", "?")
    return f"Same worlds in every folder (seed {seed}, scenario {scenario}, one grid); they differ in: {what}"
