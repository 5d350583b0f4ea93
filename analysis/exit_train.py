# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---
# %% [markdown]
# # The student fitted to the planner's move values (expert iteration's distillation; an experiment)
#
# Reads the shards of `analysis/exit_labels.py` (one or more rounds' folders: DAgger keeps every round's states)
# and trains the paper network, from `--init`'s weights, on the cross-entropy between its policy and
# softmax(log π_init + values / tau) at every step the planner labelled (`--no-prior`: softmax(values / tau)),
# over whole episodes (the LSTM from zeros at each episode's start, as when it acts). `tau` is in targets: the
# planner's values are expected finds, and moves that differ by much less than tau keep the init's odds (ExIt's
# and AggreVaTe's cost-sensitive targets rather than the planner's one move, around the roll-in policy as Gumbel
# MuZero's improved policy is). A tenth of the sequences is held out: its cross-entropy and the share of steps
# where the student's most likely move is the planner's best are printed each epoch. The result is a run folder:
# the init run's config.yaml beside the new model.zip, so `python -m searchrl.evaluate checkpoint=<out>/model.zip`
# takes it.
#
#     python -m analysis.exit_train --labels runs/exit/round1/labels --init runs/reference/term/b/model.zip \
#         --out runs/exit/round1/student --epochs 4 --tau 0.01

# %%
from __future__ import annotations

import argparse
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import torch

from searchrl.policies.actor import policy_copy
from searchrl.policies.checkpoint import load_checkpoint, run_config, save_model
from searchrl.policies.recurrent import process_sequence
from searchrl.threads import use_threads

KEYS = ("maps", "vector", "actions", "values", "mask")


def load_labels(folders: list[str]) -> dict[str, np.ndarray]:
    """Every shard of `folders`, padded to the longest sequence: maps (S, T, C, F, F) float16, vector, actions,
    values (S, T, A), mask (S, T) of the steps the planner labelled, and the observation parts every shard holds
    (`part_<key>`, a whole-map student's)."""
    shards = [np.load(path) for folder in folders for path in sorted(Path(folder).glob("shard_*.npz"))]
    if not shards:
        raise ValueError(f"--labels {folders} hold no shard_*.npz")
    length = max(s["mask"].shape[1] for s in shards)
    parts = set.intersection(*({key for key in s.files if key.startswith("part_")} for s in shards))
    out = {}
    for key in (*KEYS, *sorted(parts)):
        parts = []
        for s in shards:
            grow = [(0, 0), (0, length - s[key].shape[1])] + [(0, 0)] * (s[key].ndim - 2)
            parts.append(np.pad(s[key], grow, constant_values=np.nan if key == "values" else 0))
        out[key] = np.concatenate(parts)
    out["mask"] &= np.isfinite(out["values"]).all(axis=2)
    return out


def targets(values: np.ndarray, tau: float, prior: torch.Tensor | None) -> torch.Tensor:
    """softmax(prior + values / tau) over the last axis (NaN rows: masked out later): the planner's values as a
    policy improvement of `prior` (the log-probabilities of the policy the labels were collected with, or none),
    as Gumbel MuZero's and MPO's improved policies are. Where the moves' values tie the target is the prior, so
    the student keeps what it did where the planner sees no difference."""
    q = torch.from_numpy(np.nan_to_num(values, nan=0.0)) / tau
    return torch.softmax(q if prior is None else q + prior, dim=-1)


# %%
def logits(policy, data: dict[str, np.ndarray], rows: np.ndarray) -> torch.Tensor:
    """(B, T, A) the actor's logits over whole sequences `rows`, its LSTM from zeros at t = 0."""
    b, t = len(rows), data["mask"].shape[1]
    sources = {"map": "maps", "vector": "vector"} | {key.removeprefix("part_"): key for key in data if "part_" in key}
    reads = getattr(policy.pi_features_extractor, "keys", ("map", "vector"))
    obs = {
        key: torch.from_numpy(data[sources[key]][rows].reshape(b * t, *data[sources[key]].shape[2:]).astype(np.float32))
        for key in reads
    }
    features = policy.pi_features_extractor(obs)
    starts = torch.zeros(b, t)
    starts[:, 0] = 1.0
    lstm = policy.lstm_actor
    zeros = torch.zeros(lstm.num_layers, b, lstm.hidden_size)
    out, _ = process_sequence(features, (zeros, zeros), starts.flatten(), lstm)
    return policy.action_net(policy.mlp_extractor.forward_actor(out)).reshape(b, t, -1)


def cross_entropy(policy, data, rows: np.ndarray, tau: float, prior_policy=None) -> tuple[torch.Tensor, float]:
    """(mean cross-entropy to the targets over the labelled steps, share where argmax π = argmax values)."""
    log_p = torch.log_softmax(logits(policy, data, rows), dim=-1)
    mask = torch.from_numpy(data["mask"][rows])
    prior = None
    if prior_policy is not None:
        with torch.no_grad():
            prior = torch.log_softmax(logits(prior_policy, data, rows), dim=-1)
    goal = targets(data["values"][rows], tau, prior)
    loss = -(goal * log_p).sum(-1)[mask].mean()
    best = np.nan_to_num(data["values"][rows], nan=0.0).argmax(-1)
    agree = (log_p.argmax(-1).numpy() == best)[data["mask"][rows]].mean()
    return loss, float(agree)


# %%
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m analysis.exit_train", description=__doc__)
    parser.add_argument("--labels", required=True, help="label folders, comma-separated")
    parser.add_argument("--init", required=True, help="the model.zip the student starts from")
    parser.add_argument("--out", required=True, help="the student's run folder")
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--tau", type=float, default=0.01, help="softmax temperature, in targets")
    parser.add_argument("--lr", type=float, default=1e-4)
    parser.add_argument("--branch-lr", type=float, help="learning rate of a whole-map branch and its gate (--lr)")
    parser.add_argument("--batch", type=int, default=16, help="sequences per minibatch")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-prior", action="store_true", help="softmax(values / tau) alone, not around --init")
    args = parser.parse_args(argv)
    if args.tau <= 0 or args.epochs < 0 or args.lr <= 0 or args.batch < 1:
        parser.error(f"--tau={args.tau}, --epochs={args.epochs}, --lr={args.lr}, --batch={args.batch}: all > 0")
    use_threads(1)
    torch.manual_seed(args.seed)
    data = load_labels(args.labels.split(","))
    model = load_checkpoint(args.init, device="cpu")
    policy = model.policy
    prior = None if args.no_prior else policy_copy(model)  # the roll-in policy: --init, as the labels were collected
    policy.set_training_mode(True)
    rng = np.random.default_rng(args.seed)
    order = rng.permutation(len(data["mask"]))
    held, train = order[: max(1, len(order) // 10)], order[max(1, len(order) // 10) :]
    # A whole-map branch (own_map_cnn's grid encoder and gate) starts closed: its own rate lets it open in few steps.
    extractor = policy.pi_features_extractor
    branch = [*extractor.grid.parameters(), extractor.gate] if getattr(extractor, "gate", None) is not None else []
    rest = [p for p in policy.parameters() if all(p is not q for q in branch)]
    groups = [{"params": rest}] + ([{"params": branch, "lr": args.branch_lr or args.lr}] if branch else [])
    optimizer = torch.optim.Adam(groups, lr=args.lr)
    print(
        f"{len(train)} sequences to train on, {len(held)} held out; {int(data['mask'].sum())} labelled steps",
        file=sys.stderr,
    )
    for epoch in range(args.epochs + 1):
        if epoch:  # epoch 0 only measures the initial student
            start = time.perf_counter()
            for i in range(0, len(train), args.batch):
                loss, _ = cross_entropy(policy, data, train[i : i + args.batch], args.tau, prior)
                optimizer.zero_grad()
                loss.backward()
                torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
                optimizer.step()
            rng.shuffle(train)
        with torch.no_grad():
            ce, agree = cross_entropy(policy, data, held, args.tau, prior)
        print(
            f"epoch {epoch}: held-out cross-entropy {ce.item():.4f}, agrees with the planner's best on {agree:.3f}"
            + (f" ({time.perf_counter() - start:.0f} s)" if epoch else ""),
            file=sys.stderr,
        )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(Path(args.init).parent / "config.yaml", out / "config.yaml")
    run_config(args.init)  # the init's run config exists and reads
    save_model(model, out / "model.zip", {"exit": {"init": str(args.init), "labels": args.labels, "tau": args.tau}})
    print(f"{out / 'model.zip'}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
