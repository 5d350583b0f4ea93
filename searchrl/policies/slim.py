"""Shipped checkpoints without what only a resumed training needs.

An SB3 `model.zip` holds, beside the policy's weights (`policy.pth`), the optimiser's moments
(`policy.optimizer.pth`, twice the weights) and the last rollout's observations (`_last_obs` in `data`, one
observation per slot: 1.3 MB for 384 slots). Initialising a run from a checkpoint (`init=`), evaluating it and
rendering it read only the weights and the settings; resuming a training reads the rest, and a training run's own
checkpoints keep it. `slim_checkpoint` writes the same zip with the optimiser's state emptied (its parameter groups
kept, so SB3 loads the file as it is) and the last observations dropped; every other member is copied byte for byte,
so `weights_sha256`, the digest of the `policy.pth` member, is the same before and after.

    python -m searchrl.policies.slim runs/reference      # every model.zip below, in place
"""

from __future__ import annotations

import hashlib
import io
import json
import sys
import zipfile
from pathlib import Path

import torch

from searchrl.atomic import write_atomic

# `data` entries of the rollout in progress when the model was saved: set again by the next `learn`.
ROLLOUT_STATE = ("_last_obs", "_last_original_obs", "_last_episode_starts")


def weights_sha256(path: str | Path) -> str:
    """sha256 of the checkpoint's `policy.pth` member: its weights, whatever else the zip holds."""
    with zipfile.ZipFile(path) as archive:
        return hashlib.sha256(archive.read("policy.pth")).hexdigest()


def is_slim(path: str | Path) -> bool:
    """True when the checkpoint holds no optimiser moments and no last rollout."""
    with zipfile.ZipFile(path) as archive:
        data = json.loads(archive.read("data"))
        optimizer = torch.load(io.BytesIO(archive.read("policy.optimizer.pth")), weights_only=True)
    return not optimizer["state"] and all(data.get(key) is None for key in ROLLOUT_STATE)


def slim_checkpoint(path: str | Path, out: str | Path | None = None) -> Path:
    """Write `path` without optimiser moments and last rollout to `out` (default: in place, atomically)."""
    path = Path(path)
    with zipfile.ZipFile(path) as archive:
        members = [(info, archive.read(info.filename)) for info in archive.infolist()]
    slimmed = []
    for info, content in members:
        if info.filename == "data":
            data = json.loads(content)
            data.update({key: None for key in ROLLOUT_STATE if key in data})
            content = json.dumps(data, indent=4).encode()
        elif info.filename == "policy.optimizer.pth":
            state = torch.load(io.BytesIO(content), weights_only=True)
            state["state"] = {}  # Adam's moments and step counts; the parameter groups (rates, ids) stay
            buffer = io.BytesIO()
            torch.save(state, buffer)
            content = buffer.getvalue()
        slimmed.append((info, content))

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for info, content in slimmed:
                archive.writestr(info, content)

    return write_atomic(out or path, write)


def main(argv: list[str]) -> int:
    if not argv:
        print("usage: python -m searchrl.policies.slim FOLDER_OR_ZIP [...]", file=sys.stderr)
        return 2
    paths = [p for arg in map(Path, argv) for p in (sorted(arg.rglob("model.zip")) if arg.is_dir() else [arg])]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        print(f"slim: {missing[0]!r} is not a file (expected a model.zip or a folder holding some)", file=sys.stderr)
        return 2
    for path in paths:
        before, digest = path.stat().st_size, weights_sha256(path)
        slim_checkpoint(path)
        assert weights_sha256(path) == digest, f"{path}: the weights changed while slimming"
        print(f"{path}: {before / 1e6:.1f} MB -> {path.stat().st_size / 1e6:.1f} MB, weights {digest[:12]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
