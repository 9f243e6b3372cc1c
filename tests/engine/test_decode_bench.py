"""The decode benchmark's references: the paper's modules built plainly compute the project's decode, and
the int8 variants are quantized copies that leave the float32 model alone."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from bench.decode import int8_dynamic, plain_decode, rounded_weights
from engine.model.config import PAPER, OdmoConfig
from engine.model.odmo import OdmoModel


def _model_and_codes(paper: bool = False) -> tuple[OdmoModel, torch.Tensor, torch.Tensor, torch.Tensor]:
    """A small random-weights model (the paper's switches or the project's) and five codes, actions, ends."""
    sizes = {"traj_hidden": 32, "motion_hidden": 32, "enc_hidden": 16, "enc_fc": 32}
    config = OdmoConfig(n_actions=4, n_joints=7, **sizes, **(PAPER if paper else {}))
    model = OdmoModel(config, seed=3).eval()
    generator = torch.Generator().manual_seed(0)
    z = torch.randn(5, config.latent_dim, generator=generator)
    action = torch.randint(0, config.n_actions, (5,), generator=generator)
    end = torch.randn(5, 3, generator=generator)
    return model, z, action, end


@pytest.mark.parametrize("paper", [False, True], ids=["project", "paper"])
def test_plain_decode_matches_the_fused_decoder(paper: bool) -> None:
    """plain_decode (one nn.LSTM call per frame) gives OdmoModel's raw joints on the same weights, both
    with the paper's absolute poses and with root-relative ones."""
    model, z, action, end = _model_and_codes(paper)
    config = model.config
    with torch.inference_mode():
        raw = model.decode_full(z, action, end).raw
        plain = plain_decode(model, z, action, end)
    assert plain.shape == raw.shape == (5, config.window, config.n_joints, 3)
    assert raw.abs().max() > 0.1  # a motion, not zeros
    torch.testing.assert_close(plain, raw, atol=1e-5, rtol=1e-4)


@torch.no_grad()
def test_int8_rounded_weights_lie_on_an_int8_grid_per_row() -> None:
    """Every nn.LSTM / nn.Linear weight row of the copy is k·scale with integer |k| <= 127 and scale its
    largest magnitude / 127, within half a step of the original; biases and the original stay as they were."""
    model, *_ = _model_and_codes()
    before = {name: p.clone() for name, p in model.named_parameters()}
    rounded = dict(rounded_weights(model, "int8").named_parameters())
    weights = {n for n, m in model.named_modules() if isinstance(m, nn.LSTM | nn.Linear)}
    checked = 0
    for name, original in model.named_parameters():
        torch.testing.assert_close(original, before[name], rtol=0, atol=0)
        module, _, leaf = name.rpartition(".")
        if module in weights and leaf.startswith("weight"):
            scale = original.abs().amax(1, keepdim=True) / 127
            steps = rounded[name] / scale
            torch.testing.assert_close(steps, steps.round(), rtol=0, atol=1e-3)
            assert float(steps.abs().max()) <= 127 + 1e-3
            assert bool(((rounded[name] - original).abs() <= scale / 2 + 1e-7).all())
            assert not torch.equal(rounded[name], original)
            checked += 1
        else:
            torch.testing.assert_close(rounded[name], original, rtol=0, atol=0)
    assert checked >= 10  # the LSTMs' input and hidden weights and the Linear layers


@pytest.mark.parametrize("fmt", ["bfloat16", "float16"])
@torch.no_grad()
def test_float_rounded_weights_are_the_formats_nearest_values(fmt: str) -> None:
    """Each nn.LSTM / nn.Linear weight of the copy is representable in ``fmt`` and within half a unit in
    the last place of the original (bfloat16: 2**-8 relative, float16: 2**-11); the rest is untouched."""
    model, *_ = _model_and_codes()
    rounded = dict(rounded_weights(model, fmt).named_parameters())
    weights = {n for n, m in model.named_modules() if isinstance(m, nn.LSTM | nn.Linear)}
    half_ulp = {"bfloat16": 2.0**-8, "float16": 2.0**-11}[fmt]
    checked = 0
    for name, original in model.named_parameters():
        module, _, leaf = name.rpartition(".")
        if module in weights and leaf.startswith("weight"):
            dtype = getattr(torch, fmt)
            torch.testing.assert_close(rounded[name].to(dtype).float(), rounded[name], rtol=0, atol=0)
            assert bool(((rounded[name] - original).abs() <= half_ulp * original.abs() + 1e-7).all())
            assert not torch.equal(rounded[name], original)
            checked += 1
        else:
            torch.testing.assert_close(rounded[name], original, rtol=0, atol=0)
    assert checked >= 10


def test_int8_dynamic_quantizes_a_copy_that_plain_decode_runs() -> None:
    """The copy's decoder runs int8 modules through plain_decode, near but not equal to float32; the
    original keeps its float modules and its own decode."""
    model, z, action, end = _model_and_codes()
    quantized = int8_dynamic(model)
    assert isinstance(model.motion_gen.lstm, nn.LSTM)
    assert "quantized" in type(quantized.motion_gen.lstm).__module__
    assert "quantized" in type(quantized.motion_gen.out).__module__
    with torch.inference_mode():
        exact = plain_decode(model, z, action, end)
        int8 = plain_decode(quantized, z, action, end)
        torch.testing.assert_close(model.decode_full(z, action, end).raw, exact, atol=1e-5, rtol=1e-4)
    error = torch.linalg.vector_norm(int8 - exact, dim=-1).max()
    assert 0 < error < 0.05  # metres: the same motion, a few centimetres off at most (1.2 cm here)
