"""Trajectory generator: conditioning (+ end location) → T root positions."""

from __future__ import annotations

import torch
from torch import Tensor, nn


class TrajectoryGenerator(nn.Module):
    """Embedding (2 FC + PReLU) → 2-layer LSTM over T−1 steps → 3 FC + PReLU → FC 3 displacements."""

    def __init__(self, cond_dim: int, hidden: int, window: int, use_end_location: bool):
        super().__init__()
        self.use_end_location = use_end_location
        self.window = window
        in_dim = cond_dim + (3 if use_end_location else 0)
        self.embed = nn.Sequential(
            nn.Linear(in_dim, hidden), nn.PReLU(), nn.Linear(hidden, hidden), nn.PReLU()
        )
        self.lstm = nn.LSTM(hidden + 1, hidden, num_layers=2, batch_first=True)
        self.head = nn.Sequential(
            nn.Linear(hidden, hidden),
            nn.PReLU(),
            nn.Linear(hidden, hidden),
            nn.PReLU(),
            nn.Linear(hidden, hidden),
            nn.PReLU(),
            nn.Linear(hidden, 3),
        )
        steps = torch.arange(1, window, dtype=torch.float32) / window
        self.register_buffer("steps", steps.view(1, -1, 1), persistent=False)

    def forward(self, cond: Tensor, end: Tensor | None = None) -> Tensor:
        """Root positions (B, T, 3) starting at the origin, from ``cond`` (B, C·D) and ``end`` (B, 3)."""
        if self.use_end_location:
            if end is None:
                raise ValueError("this model was trained with end locations; pass end (B, 3)")
            cond = torch.cat([cond, end], dim=1)
        emb = self.embed(cond)
        b, n = emb.shape[0], self.window - 1
        seq = torch.cat([emb.unsqueeze(1).expand(b, n, -1), self.steps.expand(b, n, 1)], dim=2)
        out, _ = self.lstm(seq)
        steps = self.head(out)
        return torch.cat([steps.new_zeros(b, 1, 3), steps.cumsum(dim=1)], dim=1)
