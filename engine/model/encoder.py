"""LMP encoder: local movement profile (joints minus root) → code mean and log-variance."""

from __future__ import annotations

import warnings

import torch
import torch.distributed as dist
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn
from torch.distributed.nn.functional import all_reduce


class SampleSafeBatchNorm1d(nn.BatchNorm1d):
    """BatchNorm1d that uses its running statistics for a batch of one (plain BatchNorm raises) and, when
    training across processes, the statistics of every process's batch together."""

    def forward(self, x: Tensor) -> Tensor:
        """Normalise ``x`` (B, F)."""
        if self.training and dist.is_available() and dist.is_initialized() and dist.get_world_size() > 1:
            return self._over_processes(x)
        if self.training and x.shape[0] == 1:
            return F.batch_norm(
                x, self.running_mean, self.running_var, self.weight, self.bias, False, 0.0, self.eps
            )
        return super().forward(x)

    def _over_processes(self, x: Tensor) -> Tensor:
        """Batch norm over the union of the processes' batches (torch's SyncBatchNorm is GPU-only); the
        sums go through torch.distributed's differentiable all-reduce."""
        xf, f = x.float(), x.shape[1]
        count = xf.new_full((1,), float(x.shape[0]))
        with warnings.catch_warnings():  # torch 2.13 marks it deprecated; it is the differentiable one
            warnings.simplefilter("ignore", FutureWarning)
            sums = all_reduce(torch.cat([xf.sum(0), xf.square().sum(0), count]))
        n = sums[-1]
        mean = sums[:f] / n
        var = (sums[f : 2 * f] / n - mean.square()).clamp(min=0.0)
        with torch.no_grad():
            self.num_batches_tracked.add_(1)
            weight = self.momentum if self.momentum is not None else 1.0 / float(self.num_batches_tracked)
            self.running_mean.lerp_(mean, weight)
            self.running_var.lerp_(var * n / (n - 1).clamp(min=1.0), weight)
        return ((xf - mean) * torch.rsqrt(var + self.eps) * self.weight + self.bias).to(x.dtype)


class LmpEncoder(nn.Module):
    """LSTM over the local movement profile, then FC+BN+PReLU twice, then FC to 2·D.

    With ``reverse`` the LSTM reads each clip from its last real frame back to its first, so its final
    state sits where the decoder begins (a forward LSTM's sits at the clip's end and forgets its start).
    """

    def __init__(self, n_features: int, hidden: int, fc: int, latent_dim: int, reverse: bool = False):
        super().__init__()
        self.reverse = reverse
        self.lstm = nn.LSTM(n_features, hidden, batch_first=True)
        self.head = nn.Sequential(
            nn.Linear(hidden, fc),
            SampleSafeBatchNorm1d(fc),
            nn.PReLU(),
            nn.Linear(fc, fc),
            SampleSafeBatchNorm1d(fc),
            nn.PReLU(),
            nn.Linear(fc, 2 * latent_dim),
        )
        self.latent_dim = latent_dim

    def forward(self, lmp: Tensor, mask: Tensor | None = None) -> tuple[Tensor, Tensor]:
        """Mean and log-variance (B, D) of the code of ``lmp`` (B, T, F); ``mask`` (B, T) marks real frames.

        The LSTM is causal, so reading its output at each clip's last real frame ignores padded frames.
        """
        if self.reverse:
            lmp = reverse_real_frames(lmp, mask)
        out, _ = self.lstm(lmp)
        if mask is None:
            last = out[:, -1]
        else:
            idx = (mask.sum(dim=1).long() - 1).clamp(min=0)
            last = out[torch.arange(out.shape[0], device=out.device), idx]
        mu, logvar = self.head(last).float().split(self.latent_dim, dim=1)  # float32 under autocast too
        return mu, logvar


def reverse_real_frames(x: Tensor, mask: Tensor | None) -> Tensor:
    """``x`` (B, T, F) with each row's real frames (``mask`` (B, T), real frames first; None: all) in
    reverse order and its padded frames left after them."""
    frames = torch.arange(x.shape[1], device=x.device).expand(x.shape[0], -1)
    n = frames.new_full((x.shape[0], 1), x.shape[1]) if mask is None else mask.sum(dim=1, keepdim=True).long()
    order = torch.where(frames < n, n - 1 - frames, frames)
    return x.gather(1, order.unsqueeze(-1).expand_as(x))
