"""Motion generator: a trajectory encoder initialises an LSTM decoder that emits every frame's pose."""

from __future__ import annotations

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn


class MotionGenerator(nn.Module):
    """Seq2seq pose decoder conditioned on a root trajectory and the action-code conditioning.

    Decoder input per frame t: [previous pose (J·3), conditioning (C·D), t/T] → FC + PReLU → 2-layer
    LSTM (initialised by the trajectory encoder's final state) → FC to the absolute xyz of all J joints.
    The previous pose of frame 0 is zero.
    """

    def __init__(self, n_joints: int, cond_dim: int, hidden: int, window: int):
        super().__init__()
        self.pose_dim = n_joints * 3
        self.window = window
        self.traj_embed = nn.Sequential(nn.Linear(3, hidden), nn.PReLU())
        self.traj_lstm = nn.LSTM(hidden, hidden, num_layers=2, batch_first=True)
        self.embed = nn.Linear(self.pose_dim + cond_dim + 1, hidden)
        self.embed_act = nn.PReLU()
        self.lstm = nn.LSTM(hidden, hidden, num_layers=2, batch_first=True)
        self.out = nn.Linear(hidden, self.pose_dim)
        steps = torch.arange(window, dtype=torch.float32) / window
        self.register_buffer("steps", steps.view(1, -1, 1), persistent=False)

    def _context(self, trajectory: Tensor, cond: Tensor) -> tuple[tuple[Tensor, Tensor], Tensor]:
        """Decoder initial state from ``trajectory`` (B, T, 3) and the pose-free input term (B, T, H)."""
        _, state = self.traj_lstm(self.traj_embed(trajectory))
        b, t = cond.shape[0], self.window
        static = torch.cat([cond.unsqueeze(1).expand(b, t, -1), self.steps.expand(b, t, 1)], dim=2)
        const = F.linear(static, self.embed.weight[:, self.pose_dim :], self.embed.bias)
        return state, const

    def _run(self, prev: Tensor, const: Tensor, state: tuple[Tensor, Tensor]) -> Tensor:
        """Poses (B, T, J·3) given every frame's previous pose ``prev`` (B, T, J·3), in one LSTM call."""
        emb = self.embed_act(const + F.linear(prev, self.embed.weight[:, : self.pose_dim]))
        out, _ = self.lstm(emb, state)
        return self.out(out)

    def forward(
        self,
        trajectory: Tensor,
        cond: Tensor,
        truth: Tensor | None = None,
        tf_rate: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> Tensor:
        """Joint positions (B, T, J, 3).

        With ``truth`` (B, T, J, 3) this is parallel scheduled sampling: a teacher-forced pass over the
        whole sequence, then (if ``tf_rate`` < 1) a second pass whose previous pose at each frame is the
        ground truth with probability ``tf_rate`` (drawn per frame and sample from ``generator``) and the
        first pass's (detached) prediction otherwise. Without ``truth`` it decodes free-running.
        """
        b = cond.shape[0]
        state, const = self._context(trajectory, cond)
        if truth is None:
            return self._free_run(const, state).view(b, self.window, -1, 3)
        gt = truth.reshape(b, self.window, self.pose_dim)
        prev = torch.cat([gt.new_zeros(b, 1, self.pose_dim), gt[:, :-1]], dim=1)
        if tf_rate >= 1.0:
            return self._run(prev, const, state).view(b, self.window, -1, 3)
        with torch.no_grad():
            first = self._run(prev, const, state)
        keep = torch.rand(b, self.window - 1, 1, generator=generator, device=gt.device) < tf_rate
        mixed = torch.where(keep, gt[:, :-1], first[:, :-1])
        prev = torch.cat([gt.new_zeros(b, 1, self.pose_dim), mixed], dim=1)
        return self._run(prev, const, state).view(b, self.window, -1, 3)

    def _free_run(self, const: Tensor, state: tuple[Tensor, Tensor]) -> Tensor:
        """Autoregressive decode, one frame at a time with LSTM cells sharing the nn.LSTM weights.

        The output layer and the next frame's pose embedding are folded into one H×H product
        (pose_t = W_out·h_t + b, so W_pose·pose_t = (W_pose·W_out)·h_t + W_pose·b); every frame's
        pose is then read out of the stacked hidden states with a single matrix product.
        """
        lstm = self.lstm
        w_pose = self.embed.weight[:, : self.pose_dim]
        fused = (w_pose @ self.out.weight).t()
        const_next = const + self.out.bias @ w_pose.t()
        slope = self.embed_act.weight
        layers = [
            (
                getattr(lstm, f"weight_ih_l{k}"),
                getattr(lstm, f"weight_hh_l{k}"),
                getattr(lstm, f"bias_ih_l{k}"),
                getattr(lstm, f"bias_hh_l{k}"),
            )
            for k in range(lstm.num_layers)
        ]
        h = list(state[0].unbind(0))
        c = list(state[1].unbind(0))
        tops = []
        x = const[:, 0]
        for t in range(self.window):
            if t > 0:
                x = torch.addmm(const_next[:, t], h[-1], fused)
            x = F.prelu(x, slope)
            for k, (w_ih, w_hh, b_ih, b_hh) in enumerate(layers):
                h[k], c[k] = torch.lstm_cell(x, (h[k], c[k]), w_ih, w_hh, b_ih, b_hh)
                x = h[k]
            tops.append(x)
        return self.out(torch.stack(tops, dim=1))
