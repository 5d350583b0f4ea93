"""Shipped checkpoints without what only a resumed training needs.

A `model.zip` holds, beside the weights (`policy.pth`), the optimiser's moments (twice the weights), which only a
resumed training reads, and where SB3's `save` wrote it the rollout in progress (`_last_obs`), which no load reads.
`slim_checkpoint` empties the optimiser's state (its parameter groups kept, so SB3 loads the file as it is), drops
the rollout and copies every other member byte for byte: `weights_sha256`, the digest of `policy.pth`, is unchanged.

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
        optimizer = torch.load(io.BytesIO(archive.read("policy.optimizer.pth")), map_location="cpu", weights_only=True)
    return not optimizer["state"] and all(data.get(key) is None for key in ROLLOUT_STATE)


def slim_checkpoint(path: str | Path, out: str | Path | None = None, keep_moments: bool = False) -> Path:
    """Write `path` without its rollout and (unless `keep_moments`) moments to `out` (default: in place, atomically)."""
    with zipfile.ZipFile(path) as archive:
        members = [(info, archive.read(info.filename)) for info in archive.infolist()]
    slimmed = []
    for info, content in members:
        if info.filename == "data":
            data = json.loads(content)
            content = json.dumps(data | {key: None for key in ROLLOUT_STATE if key in data}, indent=4).encode()
        elif info.filename == "policy.optimizer.pth" and not keep_moments:
            buffer = io.BytesIO()  # Adam's moments and step counts emptied; the parameter groups (rates, ids) stay
            torch.save(torch.load(io.BytesIO(content), map_location="cpu", weights_only=True) | {"state": {}}, buffer)
            content = buffer.getvalue()
        slimmed.append((info, content))

    def write(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            for info, content in slimmed:
                archive.writestr(info, content)

    return write_atomic(out or path, write)


def main(argv: list[str]) -> int:
    paths = [p for arg in map(Path, argv) for p in (sorted(arg.rglob("model.zip")) if arg.is_dir() else [arg])]
    if not paths or not all(p.is_file() for p in paths):
        bad = next((f"{str(p)!r} is not a file" for p in paths if not p.is_file()), "nothing to slim")
        print(f"slim: {bad} (expected FOLDER_OR_ZIP [...]: a model.zip or a folder holding some)", file=sys.stderr)
        return 2
    for path in paths:
        before, digest = path.stat().st_size, weights_sha256(path)
        slim_checkpoint(path)
        assert weights_sha256(path) == digest, f"{path}: the weights changed while slimming"
        print(f"{path}: {before / 1e6:.1f} MB -> {path.stat().st_size / 1e6:.1f} MB, weights {digest[:12]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
