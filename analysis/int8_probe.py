# ---
# jupyter:
#   jupytext:
#     formats: py:percent
# ---

# %% [markdown]
# # int8 inference: past the fp32 peak on a CPU without bf16 (a probe)
#
# The fp32 paths of the actor run at about half (eager) to three quarters (ONNX Runtime) of the cores' measured
# matrix-product peak (`python -m searchrl.bench policy`), so no fp32 path reaches 3 times eager. On an AVX2 core
# without AVX512-BF16 or AMX the one format with more arithmetic per instruction is int8 (u8 × s8 multiply-adds).
# This probe quantizes the actor's extractor with ONNX Runtime's own static quantization (per-channel weights,
# activations calibrated on the batch, nothing folded by hand) and times the whole actor (extractor, LSTM step,
# heads) on each path on 4,096 observations of 80 × 32 worlds, beside how many greedy actions int8 changes.
#
#     python -m analysis.int8_probe --checkpoint runs/reference/term/b/model.zip --threads 1

# %%
from __future__ import annotations

import argparse
import io
import tempfile
import warnings
from pathlib import Path

import numpy as np
import torch

from searchrl.bench.policy import _rate
from searchrl.threads import use_threads


# %%
def quantized_extractor(extractor, keys: tuple[str, ...], obs: dict[str, torch.Tensor], threads: int):
    """The extractor as an int8 ONNX Runtime session (QOperator, u8 activations, s8 per-channel weights with
    reduce_range for AVX2's u8 × s8 pairs), calibrated on `obs`: a callable like the extractor."""
    import onnxruntime as ort
    from onnxruntime.quantization import (
        CalibrationDataReader,
        QuantFormat,
        QuantType,
        quant_pre_process,
        quantize_static,
    )

    from searchrl.policies.onnx_extractor import _Positional

    folder = Path(tempfile.mkdtemp())
    buffer = io.BytesIO()
    with torch.no_grad(), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(
            _Positional(extractor, keys),
            tuple(obs[k] for k in keys),
            buffer,
            input_names=list(keys),
            output_names=["features"],
            dynamic_axes={n: {0: "batch"} for n in (*keys, "features")},
            dynamo=False,
        )
    (folder / "fp32.onnx").write_bytes(buffer.getvalue())
    quant_pre_process(str(folder / "fp32.onnx"), str(folder / "pre.onnx"))
    batches = [{k: obs[k][i : i + 256].numpy() for k in keys} for i in range(0, len(obs[keys[0]]), 256)]

    class Reader(CalibrationDataReader):
        def __init__(self) -> None:
            self.batches = iter(batches)

        def get_next(self):
            return next(self.batches, None)

    quantize_static(
        str(folder / "pre.onnx"),
        str(folder / "int8.onnx"),
        Reader(),
        quant_format=QuantFormat.QOperator,
        activation_type=QuantType.QUInt8,
        weight_type=QuantType.QInt8,
        per_channel=True,
        reduce_range=True,
    )
    options = ort.SessionOptions()
    options.intra_op_num_threads, options.inter_op_num_threads, options.log_severity_level = threads, 1, 3
    session = ort.InferenceSession(str(folder / "int8.onnx"), options, providers=["CPUExecutionProvider"])
    return lambda o: torch.from_numpy(session.run(None, {k: o[k].numpy() for k in keys})[0])


# %%
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--checkpoint", default="runs/reference/term/b/model.zip")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--seconds", type=float, default=4.0)
    parser.add_argument("--out", default="analysis/out/int8_probe")
    args = parser.parse_args()
    use_threads(args.threads, network_on_cpu=True)  # before torch's first parallel work (searchrl/threads.py)
    from searchrl.evaluate.grid import Cell
    from searchrl.evaluate.runner import cell_config
    from searchrl.policies.actor import Actor, policy_copy
    from searchrl.policies.checkpoint import checkpoint_config, load_checkpoint
    from searchrl.world.config import WorldConfig
    from searchrl.world.observe import observe
    from searchrl.world.reset import reset_world
    from searchrl.world.state import allocate

    # The batch `bench policy` times: every slot of 128 worlds of 80 x 32
    config = cell_config(WorldConfig.from_dict(checkpoint_config(args.checkpoint)[0]), Cell(80, 32, 16, 32))
    state = allocate(config, 128)
    for w in range(128):
        reset_world(config, state, w, np.random.default_rng(w))
    maps, vector = observe(config, state)
    batch = 128 * config.n_agents
    maps, vector = maps.reshape(batch, *maps.shape[2:]).astype(np.float32), vector.reshape(batch, -1).astype(np.float32)
    model = load_checkpoint(args.checkpoint)
    actors = {
        name: Actor(
            policy_copy(model), optimize=name in ("torch", "onnx"), inference="onnx" if name == "onnx" else "torch"
        )
        for name in ("eager", "torch", "onnx", "int8")
    }
    obs = {"map": torch.from_numpy(maps), "vector": torch.from_numpy(vector)}
    int8 = actors["int8"]
    int8._extract = quantized_extractor(int8._extract, int8.keys, obs, args.threads)
    zero = actors["eager"].initial_state(batch)
    logits = {name: a.logits(maps, vector, zero)[0] for name, a in actors.items()}
    rates = {name: _rate(lambda a=a: a.logits(maps, vector, zero), batch, args.seconds) for name, a in actors.items()}
    greedy = logits["eager"].argmax(1)
    lines = [
        f"# int8 inference probe: {args.checkpoint}, {batch} observations of 80 x 32 worlds, {args.threads} thread(s)",
        "",
        "| path | agent-steps/s | x eager | greedy actions changed | max logit error |",
        "|---|---|---|---|---|",
    ]
    for name in actors:
        changed = float((logits[name].argmax(1) != greedy).mean())
        error = float(np.abs(logits[name] - logits["eager"]).max())
        lines.append(
            f"| {name} | {rates[name]:,.0f} | {rates[name] / rates['eager']:.2f} | {changed:.2%} | {error:.2g} |"
        )
    text = "\n".join(lines) + "\n"
    print(text)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "int8_probe.md").write_text(text)


# %%
if __name__ == "__main__":
    main()
