"""Trajectory generator: conditioning (+ end location) → T root positions."""

from __future__ import annotations

import torch
from torch import Tensor, nn


class TrajectoryGenerator(nn.Module):
    """Embedding (2 FC + PReLU) → 2-layer LSTM over T−1 steps → 3 FC + PReLU → FC 3 displacements."""

    def __init__(self, cond_dim: int, hidden: int, window: int, use_end_location: bool, exact_end: bool):
        super().__init__()
        self.use_end_location = use_end_location
        self.exact_end = exact_end and use_end_location
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
        shear = torch.arange(window, dtype=torch.float32) / (window - 1)
        self.register_buffer("shear", shear.view(1, -1, 1), persistent=False)

    def forward(self, cond: Tensor, end: Tensor | None = None) -> Tensor:
        """Root positions (B, T, 3) starting at the origin, from ``cond`` (B, C·D) and ``end`` (B, 3).

        With ``exact_end`` the path is sheared linearly in time (frame t moves by t/(T−1) of the miss) so
        that its last frame is ``end``.
        """
        if self.use_end_location:
            if end is None:
                raise ValueError("this model was trained with end locations; pass end (B, 3)")
            path = self._path(torch.cat([cond, end], dim=1))
            if self.exact_end:
                path = path + (end - path[:, -1]).unsqueeze(1) * self.shear
            return path
        return self._path(cond)

    def _path(self, cond: Tensor) -> Tensor:
        """The generator's own root path (B, T, 3) from its input (B, in_dim)."""
        emb = self.embed(cond)
        b, n = emb.shape[0], self.window - 1
        seq = torch.cat([emb.unsqueeze(1).expand(b, n, -1), self.steps.expand(b, n, 1)], dim=2)
        out, _ = self.lstm(seq)
        steps = self.head(out).float()  # summed below: float32 under autocast too
        return torch.cat([steps.new_zeros(b, 1, 3), steps.cumsum(dim=1)], dim=1)
