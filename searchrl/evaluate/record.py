"""What an evaluation folder holds results of: `<out_dir>/evaluation.yaml`.

An evaluation resumes by skipping cells whose parquet file exists, so a second run into the same folder with other
settings (another `controller.horizon`, a retrained `model.zip` at the same path, another `seed` or grid) would
silently keep the first run's cells beside its own. The first run into a folder records the settings that decide
its episodes; every later run compares its own with them and stops, naming what differs, before any work.
Settings that do not change an episode (shard, num_shards, threads, batch_mb, progress_bar) are not recorded.
A checkpoint's `device` is, as its kind (cpu, cuda, mps; not the index of a card): CUDA rounds the logits otherwise
than the CPU (searchrl/policies/actor.py), an action may then flip (31 of 32 episodes of a slice alike on an H200),
and a folder mixing both would hold cells no one command reproduces; so is its `inference` path on the CPU (ONNX
Runtime rounds otherwise than torch). A record made before `device` ran on the CPU, one made before `inference` with
torch.
"""

from __future__ import annotations

import hashlib
import json
import sys
from dataclasses import asdict, fields, is_dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow.parquet as pq
from omegaconf import OmegaConf

from searchrl.atomic import write_text_atomic
from searchrl.evaluate.grid import cell_files
from searchrl.migrations import EVALUATION_RECORD_ADDED, POLICY_RECORD_ADDED
from searchrl.policies.device import resolve_device
from searchrl.shared_schema import dotted_leaves
from searchrl.world.config import ConfigError, WorldConfig
from searchrl.world.scenario import Scenario

if TYPE_CHECKING:
    from searchrl.evaluate.schema import EvaluateConfig

RECORD = "evaluation.yaml"
GRID_KEYS = ("world_sizes", "n_targets", "n_distributions", "max_agents", "agents", "maps_per_cell", "repeats")


def file_sha256(path: str | Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def evaluation_settings(cfg: EvaluateConfig, label: str, model_name: str) -> dict[str, Any]:
    """The settings that decide a folder's episodes. A checkpoint is named by the hash of its file (its world and
    network come with it); a heuristic by its parameters and the world settings it runs in. The grid lists are
    recorded whole: a cell's maps are seeded by its index in them, so another list gives other maps per cell."""
    settings: dict[str, Any] = {
        "controller": label,
        "model": model_name,
        "seed": cfg.seed,
        "grid": {key: asdict(cfg.grid)[key] for key in GRID_KEYS},
        "scenario": Scenario.from_dict(cfg.scenario).to_dict(),
    }
    if cfg.checkpoint is not None:
        settings["checkpoint_sha256"] = file_sha256(cfg.checkpoint)
        settings["deterministic"] = cfg.deterministic
        settings["device"] = resolve_device(cfg.device).type  # auto recorded as what it ran on
        settings["inference"] = cfg.inference
    else:
        # Named by the label: a preset (controller=greedy_target) records the controller it sets (greedy) and every
        # setting, as the same settings spelled out do, so either may resume the other's folder.
        settings["controller_args"] = {**asdict(cfg.controller), "name": label}
        settings["world"] = asdict(cfg.env.world)
    return settings


def option_defaults(cfg: EvaluateConfig) -> dict[str, Any]:
    """Flattened defaults of the heuristic's own schema (`controller_args.<name>`) and of the world (`world.<name>`):
    an option added to a controller or the world after a folder was recorded is absent there, and at its default
    it plays the episodes the record describes. What a record made before a setting existed ran with is
    searchrl/migrations.py's."""
    defaults = dotted_leaves(EVALUATION_RECORD_ADDED)
    if cfg.checkpoint is not None:
        return defaults | POLICY_RECORD_ADDED
    world = {f.name: list(f.default) if isinstance(f.default, tuple) else f.default for f in fields(WorldConfig)}
    defaults |= dotted_leaves({"world": world})
    schema = type(cfg.controller)
    if is_dataclass(schema):
        defaults.update(dotted_leaves({"controller_args": OmegaConf.to_container(OmegaConf.structured(schema))}))
    return defaults


# The key of a cell frame's `attrs` (kept in its parquet file's metadata) that holds the settings it ran under.
CELL_SETTINGS = "searchrl"


def cell_settings(path: str | Path) -> dict[str, Any] | None:
    """The settings a cell's parquet file records (CELL_SETTINGS), None for a cell written before cells recorded
    them; ValueError if the file cannot be read as a parquet file."""
    try:
        metadata = pq.read_schema(path).metadata or {}
        attrs = json.loads(metadata.get(b"PANDAS_ATTRS", b"{}"))
    except Exception as err:  # pyarrow's errors for a damaged file have no common base but Exception
        raise ValueError(f"{path} cannot be read as a cell's results ({type(err).__name__})") from None
    settings = attrs.get(CELL_SETTINGS) if isinstance(attrs, dict) else None
    return settings if isinstance(settings, dict) else None


def setting_differences(theirs: dict[str, Any], ours: dict[str, Any], defaults: dict[str, Any]) -> list[str]:
    """`key: A there, B here` for each flattened setting that differs; one a side lacks matches the other side's
    value when that is its default (a setting added since the side was recorded)."""
    theirs, ours = dotted_leaves(theirs), dotted_leaves(ours)
    keys = sorted(theirs.keys() | ours.keys())
    absent = {key: defaults.get(key, "(absent)") for key in keys}
    return [
        f"{key}: {theirs.get(key, '(absent)')!r} there, {ours.get(key, '(absent)')!r} here"
        for key in keys
        if theirs.get(key, absent[key]) != ours.get(key, absent[key])
    ]


def _read_record(out_dir: Path, cells: dict[Path, dict[str, Any] | None]) -> dict[str, Any] | None:
    """The folder's record; ConfigError if it cannot say what the cells hold. A damaged
    record (empty, not YAML, not a mapping) of a folder whose cells record their settings is set aside as
    `<record>.unreadable` and None returned: it is rebuilt from them."""
    try:
        record = OmegaConf.to_container(OmegaConf.load(out_dir / RECORD))
        if not isinstance(record, dict) or "controller" not in record:
            raise ValueError("no controller recorded")
        return record
    except Exception as err:  # empty, not YAML, not a mapping: the record cannot say what the cells hold
        if any(settings is not None for settings in cells.values()):
            aside = out_dir / f"{RECORD}.unreadable"
            (out_dir / RECORD).rename(aside)
            print(
                f"warning: {out_dir / RECORD} cannot be read ({type(err).__name__}); set aside as {aside.name}",
                file=sys.stderr,
            )
            return None
        raise ConfigError(
            f"out_dir={str(out_dir)!r}: its {RECORD} cannot be read ({type(err).__name__}); restore it, or "
            "remove that folder to start it afresh"
        ) from None


def _cells_settings(out_dir: Path) -> dict[Path, dict[str, Any] | None]:
    """The settings each finished cell of the folder records (None: a cell made before cells recorded them). A cell
    that cannot be read is set aside as `<cell>.unreadable`, said so, and run again."""
    found = {}
    for path in cell_files(out_dir):
        try:
            found[path] = cell_settings(path)
        except ValueError as err:
            aside = path.with_name(f"{path.name}.unreadable")
            path.rename(aside)
            print(f"warning: {err}; set aside as {aside.name}, and run again", file=sys.stderr)
    return found


def claim_folder(
    out_dir: str | Path, settings: dict[str, Any], defaults: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Record `settings` in `out_dir`, or check them against the record there; ConfigError naming the folder and
    every setting that differs. Every finished cell is checked against the record too: one of other settings (a
    file copied in, a run that wrote into the folder before its record) is refused, naming it; one that cannot be
    read is set aside and run again. A record that was lost is rebuilt from the settings its cells record, not
    taken from this command. A setting a record lacks matches when this run has it at its value in `defaults`
    (flattened keys; `option_defaults`). A folder whose cells record nothing (made before records existed) adopts
    these settings. Returns the settings each cell this run writes records (CELL_SETTINGS)."""
    defaults, out_dir = defaults or {}, Path(out_dir)
    mine = OmegaConf.to_container(OmegaConf.create(settings))  # the types a YAML round trip gives
    cells = _cells_settings(out_dir)
    record = _read_record(out_dir, cells) if (out_dir / RECORD).exists() else None
    if record is None:
        recorded = [s for s in cells.values() if s is not None]
        record = recorded[0] if recorded else mine
        if cells and not recorded:
            print(f"note: {out_dir} has results but no {RECORD}; recording this run's settings", file=sys.stderr)
    for path, theirs in cells.items():
        differ = [] if theirs is None else setting_differences(theirs, record, defaults)
        if differ:
            raise ConfigError(
                f"out_dir={str(out_dir)!r}: cells/{path.name} holds results of other settings than "
                f"the folder's ({'; '.join(differ)}): remove that cell, or the folder to start it "
                "afresh"
            )
    if not (out_dir / RECORD).exists() and record is not mine:  # the folder's own record again, whatever comes
        write_text_atomic(out_dir / RECORD, OmegaConf.to_yaml(OmegaConf.create(record)))
        print(f"note: {out_dir} had lost its {RECORD}: rebuilt from the settings its cells record", file=sys.stderr)
    differ = setting_differences(record, mine, defaults)
    if differ:
        raise ConfigError(
            f"out_dir={str(out_dir)!r} holds results of other settings ({'; '.join(differ)}): give this run "
            f"another out_dir, or remove that folder to start it afresh"
        )
    if not (out_dir / RECORD).exists():
        write_text_atomic(out_dir / RECORD, OmegaConf.to_yaml(OmegaConf.create(record)))
    return mine
