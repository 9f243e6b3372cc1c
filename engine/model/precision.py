"""Reduced-precision training passes that run on any CPU."""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator

import torch


def native_bfloat16(device_type: str) -> bool:
    """Whether ``device_type`` computes bfloat16 in hardware (CUDA, or a CPU whose oneDNN has bfloat16:
    AVX-512 BF16 or AMX)."""
    if device_type == "cuda":
        return True
    return device_type == "cpu" and bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


@contextlib.contextmanager
def bfloat16_autocast(device_type: str, enabled: bool = True) -> Iterator[None]:
    """bfloat16 autocast for a forward pass; on a CPU without bfloat16 instructions oneDNN has no bfloat16
    LSTM, so there the LSTMs run through torch's own kernels (in float32) instead of failing."""
    with contextlib.ExitStack() as stack:
        stack.enter_context(warnings.catch_warnings())
        # torch's flags() warns about Intel GPUs on every CPU build when it sets oneDNN's state.
        warnings.filterwarnings("ignore", message="TF32 acceleration on top of oneDNN")
        stack.enter_context(torch.autocast(device_type, torch.bfloat16, enabled=enabled))
        if enabled and device_type == "cpu" and not native_bfloat16("cpu"):
            stack.enter_context(torch.backends.mkldnn.flags(enabled=False))
        yield
