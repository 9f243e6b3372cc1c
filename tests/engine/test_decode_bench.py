"""The decode benchmark's reference: the paper's modules built plainly compute the project's decode."""

from __future__ import annotations

import pytest
import torch

from bench.decode import plain_decode
from engine.model.config import PAPER, OdmoConfig
from engine.model.odmo import OdmoModel


@pytest.mark.parametrize("paper", [False, True], ids=["project", "paper"])
def test_plain_decode_matches_the_fused_decoder(paper: bool) -> None:
    """plain_decode (one nn.LSTM call per frame) gives OdmoModel's raw joints on the same weights, both
    with the paper's absolute poses and with root-relative ones."""
    sizes = {"traj_hidden": 32, "motion_hidden": 32, "enc_hidden": 16, "enc_fc": 32}
    config = OdmoConfig(n_actions=4, n_joints=7, **sizes, **(PAPER if paper else {}))
    model = OdmoModel(config, seed=3).eval()
    generator = torch.Generator().manual_seed(0)
    z = torch.randn(5, config.latent_dim, generator=generator)
    action = torch.randint(0, config.n_actions, (5,), generator=generator)
    end = torch.randn(5, 3, generator=generator)
    with torch.inference_mode():
        raw = model.decode_full(z, action, end).raw
        plain = plain_decode(model, z, action, end)
    assert plain.shape == raw.shape == (5, config.window, config.n_joints, 3)
    assert raw.abs().max() > 0.1  # a motion, not zeros
    torch.testing.assert_close(plain, raw, atol=1e-5, rtol=1e-4)
