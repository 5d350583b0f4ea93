"""The torch device a policy runs on: checked once, in one line, by every app that takes one (training's `device=`,
evaluation's `device=`, `python -m searchrl.render --device`, `python -m searchrl.bench eval|policy --device`).

A device asked for and missing is refused, never replaced by the CPU: a run or an evaluation that silently fell back
would be slower than asked, and an evaluation would record a device it did not use.
"""

from __future__ import annotations

import torch
from stable_baselines3.common.utils import get_device

from searchrl.world.config import ConfigError, need

ALLOWED = "cpu, cuda, cuda:<index>, mps or auto (cuda when torch sees one, else cpu)"


def check_device(device: str, name: str = "device") -> None:
    """ConfigError "`name`=device is not allowed: ..." unless torch can run on `device` here."""
    if device == "auto":
        return
    try:
        parsed = torch.device(device)
    except (RuntimeError, ValueError, TypeError):
        raise ConfigError(f"{name}={device!r} is not allowed: {ALLOWED}") from None
    if parsed.type == "cuda":
        count = torch.cuda.device_count()
        need(count > 0, name, device, "cpu here: torch sees no CUDA device (torch.cuda.is_available() is False)")
        need((parsed.index or 0) < count, name, device, f"a CUDA index below {count} (devices torch sees)")
    elif parsed.type == "mps":
        need(torch.backends.mps.is_available(), name, device, "cpu here: torch sees no MPS device")
    else:
        need(parsed.type == "cpu", name, device, ALLOWED)


def policy_device(device: str, has_policy: bool, name: str = "--device") -> str:
    """`device` of a command that runs either a policy's network or a heuristic (render, bench eval and policy),
    resolved as `resolve_device`; without a policy only cpu or auto, as a heuristic runs on the CPU."""
    resolved = str(resolve_device(device, name))
    if not has_policy and device not in ("cpu", "auto"):
        raise ConfigError(f"{name}={device!r} is not allowed: cpu without --checkpoint (a heuristic runs on the CPU)")
    return resolved


def resolve_device(device: str, name: str = "device") -> torch.device:
    """The torch device `device` names (`auto`: cuda when torch sees one, else cpu, as SB3 and training read it),
    after `check_device`."""
    check_device(device, name)
    return get_device(device)
