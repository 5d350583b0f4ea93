"""A features extractor run by ONNX Runtime: `inference=onnx`, the faster of the CPU's inference paths.

The paper network's cost is its convolutions on a 5×11×11 window (about 1.9 MFLOP of its 2.2 a sample). PyTorch
runs them at about half of the CPU's measured matrix-multiply peak; ONNX Runtime's CPU provider, given the same
graph (exported by `torch.onnx.export`, nothing folded by hand), prepacks the weights and fuses each convolution with
its ReLU, and runs them about 1.5 times as fast on an AVX2 core (`python -m searchrl.bench policy` measures every
path beside the peak). torch's `inductor` with frozen weights reaches the same speed, but only for one batch shape
(an evaluation's batch shrinks as its episodes end: seconds of compiling per shape) and only with a C++ compiler.

Not bit for bit: the fused kernels sum in another order, so features differ from torch's by about 1e-5. On 10 maps
of 80×8 no greedy action of any shipped policy differed on torch's own episodes (0 of 101,656 agent-steps), and 50
sampled episodes of term/b were the same 50 episodes. An evaluation records its path (`inference`), and a folder
refuses cells of another (searchrl/evaluate/record.py); tests/test_onnx_inference.py checks the paths agree on a
small grid.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import torch
from torch import nn


class _Positional(nn.Module):
    """The extractor with its dict input as positional tensors, in `keys` order (ONNX takes named inputs)."""

    def __init__(self, extractor: nn.Module, keys: tuple[str, ...]) -> None:
        super().__init__()
        self.extractor, self.keys = extractor, keys

    def forward(self, *tensors: torch.Tensor) -> torch.Tensor:
        return self.extractor(dict(zip(self.keys, tensors, strict=True)))


class OnnxExtractor:
    """Callable like the extractor: {key: (B, ...) float32 CPU tensor} -> (B, features) float32 CPU tensor.

    Exported once with a dynamic batch axis; the session uses torch's thread count at construction (the threads an
    evaluation asked for, `searchrl/threads.py`)."""

    def __init__(self, extractor: nn.Module, keys: tuple[str, ...], example: dict[str, torch.Tensor]) -> None:
        import onnxruntime  # imported here: only this path needs it

        self.keys = keys
        buffer = io.BytesIO()
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the exporter's notes about its TorchScript path
            torch.onnx.export(
                _Positional(extractor.eval(), keys),
                tuple(example[k].cpu() for k in keys),
                buffer,
                input_names=list(keys),
                output_names=["features"],
                dynamic_axes={name: {0: "batch"} for name in (*keys, "features")},
                dynamo=False,  # the TorchScript exporter: no onnxscript needed, one graph for any batch
            )
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = torch.get_num_threads()
        options.inter_op_num_threads = 1
        options.log_severity_level = 3  # errors only: no notes on stderr for every session
        # Its workers sleep between calls instead of spinning: each call is milliseconds of work, and spinning
        # workers took the cores from the world's and other jobs' threads (searchrl/threads.py)
        options.add_session_config_entry("session.intra_op.allow_spinning", "0")
        self._session = onnxruntime.InferenceSession(buffer.getvalue(), options, providers=["CPUExecutionProvider"])

    def __call__(self, observations: dict[str, torch.Tensor]) -> torch.Tensor:
        feeds = {k: np.ascontiguousarray(observations[k].numpy(), np.float32) for k in self.keys}
        return torch.from_numpy(self._session.run(None, feeds)[0])
