"""Motion generator: a trajectory encoder initialises an LSTM decoder that emits every frame's pose."""

from __future__ import annotations

import functools
import logging
import math
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.motion.kinematics import FkLevels, fk_levels, rotation_6d_to_matrix, walk_tree
from engine.motion.skeleton import Skeleton

logger = logging.getLogger(__name__)


def _loop_gates(weight: Tensor) -> Tensor:
    """LSTM gate rows reordered from torch's (i, f, g, o) to (i, f, o, g), the g rows doubled: one sigmoid
    over all four then gives tanh(g) = 2·σ(2g) − 1."""
    i, f, g, o = weight.chunk(4, 0)
    return torch.cat([i, f, o, 2 * g], 0)


def _free_run_loop(
    const: Tensor,
    bias_next: Tensor,
    h0: Tensor,
    c0: Tensor,
    fused: Tensor,
    slope: Tensor,
    w_ih: list[Tensor],
    w_hh: list[Tensor],
    bias: list[Tensor],
    start: Tensor,
    residual: bool,
    fused_step: Tensor,
    bias_step: Tensor,
    stepped: bool,
) -> Tensor:
    """Top-layer hidden states (B, T, H) of the free-running decoder (TorchScript-compatible).

    ``const`` (B, T, H) is the pose-free part of each frame's input projection, ``bias_next`` (H,) what
    the previous pose's output bias adds to it, ``h0`` / ``c0`` (L, B, H) the initial state, ``fused``
    (H, H) the transposed product W_pose·W_out, ``slope`` the PReLU weight; per layer ``w_ih`` (in, 4H)
    and ``w_hh`` (H, 4H) are transposed and ``bias`` (4H,) summed, laid out by ``_loop_gates``. ``start``
    (H,) is what frame 0's previous pose adds to its input; with ``residual`` each frame's output is a
    step from the previous pose, so the pose terms add up, and with ``stepped`` the next frame also reads
    that step (``fused_step`` and ``bias_step`` as ``fused`` and ``bias_next`` for the step's columns).
    """
    h = [h0[k] for k in range(len(w_ih))]
    c = [c0[k] for k in range(len(w_ih))]
    steps = (const + bias_next).transpose(0, 1).contiguous().unbind(0)
    tops: list[Tensor] = []
    pose_term = start.expand(const.shape[0], -1)
    x = const[:, 0] + pose_term
    for t in range(len(steps)):
        if t > 0 and residual:  # W_pose·(previous pose + previous output)
            pose_term = torch.addmm(pose_term + bias_next, h[-1], fused)
            x = const[:, t] + pose_term
            if stepped:
                x = x + torch.addmm(bias_step, h[-1], fused_step)
        elif t > 0:
            x = torch.addmm(steps[t], h[-1], fused)
        tops.append(_cell_stack(F.prelu(x, slope), h, c, w_ih, w_hh, bias))
    return torch.stack(tops, dim=1)


def _cell_stack(
    x: Tensor, h: list[Tensor], c: list[Tensor], w_ih: list[Tensor], w_hh: list[Tensor], bias: list[Tensor]
) -> Tensor:
    """One frame through the LSTM layers (weights as in ``_free_run_loop``): updates the states ``h`` and
    ``c`` in place and returns the top layer's output."""
    for k in range(len(w_ih)):
        i, f, o, g = torch.addmm(bias[k], x, w_ih[k]).addmm_(h[k], w_hh[k]).sigmoid().chunk(4, 1)
        cell = torch.addcmul(f * c[k] - i, i, g, value=2.0)  # f·c + i·(2g − 1) = f·c + i·tanh(gate)
        x = o * cell.tanh()
        h[k] = x
        c[k] = cell
    return x


def _free_run_fk_loop(
    const: Tensor,
    h0: Tensor,
    c0: Tensor,
    w_pose: Tensor,
    w_out: Tensor,
    b_out: Tensor,
    slope: Tensor,
    w_ih: list[Tensor],
    w_hh: list[Tensor],
    bias: list[Tensor],
    offsets: Tensor,
    joints: list[Tensor],
    slots: list[Tensor],
    back: Tensor,
) -> tuple[Tensor, Tensor]:
    """Poses (B, T, J·3) and top-layer hidden states (B, T, H) of a free-running rotation decoder
    (TorchScript-compatible): each frame's 6D rotations ``top·w_out + b_out`` placed by ``walk_tree`` on
    ``offsets`` and the levels ``joints`` / ``slots`` / ``back``, root at the origin, and read back through
    the transposed ``w_pose``; the rest as in ``_free_run_loop``."""
    h = [h0[k] for k in range(len(w_ih))]
    c = [c0[k] for k in range(len(w_ih))]
    steps = const.transpose(0, 1).contiguous().unbind(0)
    origin = const.new_zeros(const.shape[0], 3)
    tops: list[Tensor] = []
    poses: list[Tensor] = []
    x = steps[0]
    for t in range(len(steps)):
        if t > 0:
            x = torch.addmm(steps[t], poses[-1], w_pose)
        top = _cell_stack(F.prelu(x, slope), h, c, w_ih, w_hh, bias)
        local = rotation_6d_to_matrix(torch.addmm(b_out, top, w_out).view(const.shape[0], -1, 6))
        poses.append(walk_tree(local, offsets, origin, joints, slots, back).flatten(1))
        tops.append(top)
    return torch.stack(poses, dim=1), torch.stack(tops, dim=1)


def _identity(tensors: list[Tensor]) -> list[tuple[Tensor, int]] | None:
    """Each tensor with its version counter (None for inference tensors, which have none)."""
    try:
        return [(t, t._version) for t in tensors]
    except RuntimeError:
        return None


def _same(old: list[tuple[Tensor, int]], new: list[tuple[Tensor, int]]) -> bool:
    """Whether ``new`` names the very same tensors as ``old``, none modified in place since."""
    return len(old) == len(new) and all(a is b and u == v for (a, u), (b, v) in zip(old, new, strict=True))


@functools.cache
def _compiled(loop: Callable[..., Any]) -> Callable[..., Any]:
    """A decoder loop compiled with TorchScript (no per-op Python overhead), or the plain one."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # torch.jit.script is deprecated but still the lightest option
            return torch.jit.script(loop)
    except Exception as error:  # no TorchScript here, or no source to compile: the same loop, eager
        logger.info("TorchScript unavailable (%s); the free-running decoder runs eagerly", error)
        return loop


class MotionGenerator(nn.Module):
    """Seq2seq pose decoder conditioned on a root trajectory and the action-code conditioning.

    Decoder input per frame t: [previous pose (J·3), conditioning (C·D), t/T] → FC + PReLU → 2-layer
    LSTM (initialised by the trajectory encoder's final state) → FC to the xyz of all J joints. The
    previous pose of frame 0 is zero. With ``relative`` the decoder's pose is read as the local movement
    profile (every joint minus the root, joint 0): that is what it reads back, and the trajectory is
    the root, so the generated root follows the trajectory exactly. With ``velocity_input`` each frame's
    input also holds the trajectory's step into that frame (m/s at ``fps``; zero at frame 0), so the
    decoder sees how far the root moves while it places the feet, not only the trajectory's summary in
    its initial state. With ``rotations`` the output layer emits each joint's local rotation (6D; the
    root's is its global one) and the pose is the skeleton's forward kinematics from a root at the
    origin (``attach_skeleton`` first; it needs ``relative``): bone lengths hold by construction. The
    decoder still reads back joint positions. With ``residual`` (joints only) each frame's output is a
    step added to the previous pose, and frame 0's previous pose is a learned start pose: a joint the
    decoder does not move stays where it was instead of falling back to a pose of its own. With
    ``clock_hz`` each frame's input also holds sin and cos of 2π·f·t at each frequency f (Hz, t in seconds
    from the window's first frame): rhythms that do not die out however long the decoder runs. With
    ``code_rhythms`` M > 0 (with ``clock_hz``) it also reads M rhythms whose phase and size the code sets:
    each a sum of those sines and cosines weighted by a linear function of the conditioning (an additive
    clock is the same for every code, so a wave's phase, which differs from window to window, cannot come
    from it). With ``step_input`` (``residual`` only) each frame's input also holds the previous frame's
    step (its pose minus the one before; zero at frame 0), so the decoder reads how each joint moves, not
    only where it is: a swing it is shown it can continue.
    """

    def __init__(
        self,
        n_joints: int,
        cond_dim: int,
        hidden: int,
        window: int,
        relative: bool = False,
        free_running_samples: bool = False,
        velocity_input: bool = False,
        fps: float = 20.0,
        rotations: bool = False,
        residual: bool = False,
        clock_hz: tuple[float, ...] = (),
        step_input: bool = False,
        code_rhythms: int = 0,
    ):
        super().__init__()
        if code_rhythms and not clock_hz:
            raise ValueError("rhythms the code sets are sums of the clock's sines: they need clock_hz")
        if step_input and not residual:
            raise ValueError("a decoder reads its previous step only when it steps (residual)")
        if rotations and not relative:
            raise ValueError("a rotation decoder places joints about the root: it needs relative poses")
        if rotations and residual:
            raise ValueError("a residual decoder steps joint positions: it cannot emit rotations")
        self.residual = residual
        self.step_input = step_input
        self.rotations = rotations
        self.n_joints = n_joints
        self.free_running_samples = free_running_samples
        self.pose_dim = n_joints * 3
        self.cond_dim = cond_dim
        self.window = window
        self.relative = relative
        self.velocity_input = velocity_input
        self.fps = fps
        self.traj_embed = nn.Sequential(nn.Linear(3, hidden), nn.PReLU())
        self.traj_lstm = nn.LSTM(hidden, hidden, num_layers=2, batch_first=True)
        extra = 1 + (3 if velocity_input else 0) + 2 * len(clock_hz) + code_rhythms
        extra += self.pose_dim if step_input else 0
        self.embed = nn.Linear(self.pose_dim + cond_dim + extra, hidden)
        self.embed_act = nn.PReLU()
        self.lstm = nn.LSTM(hidden, hidden, num_layers=2, batch_first=True)
        self.out = nn.Linear(hidden, n_joints * 6 if rotations else self.pose_dim)
        self.start = nn.Parameter(torch.zeros(self.pose_dim)) if residual else None
        self.code_rhythms = code_rhythms
        self.rhythm = nn.Linear(cond_dim, 2 * len(clock_hz) * code_rhythms) if code_rhythms else None
        self.register_buffer("fk_offsets", torch.zeros(n_joints, 3), persistent=False)
        self.fk_parents: tuple[int, ...] | None = None
        steps = torch.arange(window, dtype=torch.float32) / window
        self.register_buffer("steps", steps.view(1, -1, 1), persistent=False)
        angles = (
            2 * math.pi * torch.arange(window, dtype=torch.float32)[:, None] / fps * torch.tensor(clock_hz)
        )
        clock = torch.cat([angles.sin(), angles.cos()], dim=1)
        self.register_buffer("clock", clock.view(1, window, -1), persistent=False)
        self._step_cache: tuple[list[tuple[Tensor, int]], tuple[Tensor | list[Tensor], ...]] | None = None

    @torch.no_grad()
    def attach_skeleton(self, skeleton: Skeleton) -> None:
        """Take the skeleton whose forward kinematics places a rotation decoder's joints."""
        offsets = torch.tensor(np.array(skeleton.offsets), dtype=torch.float32)
        offsets[skeleton.root] = 0.0
        self.fk_offsets.copy_(offsets)
        self.fk_parents = tuple(int(p) for p in skeleton.parents)

    def _pose(self, out: Tensor) -> Tensor:
        """Poses (..., J·3) of the output layer's values (..., out): the joints themselves, or with
        ``rotations`` the forward kinematics of their 6D local rotations, root at the origin."""
        if not self.rotations:
            return out
        levels = self._fk_levels()
        local = rotation_6d_to_matrix(out.unflatten(-1, (self.n_joints, 6)))
        origin = out.new_zeros(*out.shape[:-1], 3)
        return walk_tree(local, self.fk_offsets.to(local), origin, *levels).flatten(-2)

    def _context(self, trajectory: Tensor, cond: Tensor) -> tuple[tuple[Tensor, Tensor], Tensor]:
        """Decoder initial state from ``trajectory`` (B, T, 3) and the pose-free input term (B, T, H).

        W·[pose, cond, t/T, v, clock, r] + b = W_pose·pose + (W_cond·cond + b) + w_t·t/T + W_v·v + W_c·clock
        + W_r·r: the code term is computed once per sequence, the time and clock terms broadcast over it, the
        root velocity term (with ``velocity_input``) added per frame, and the code's rhythms r (with
        ``code_rhythms``) are the clock times the code's weights for it, A(cond) (2F, M).
        """
        _, state = self.traj_lstm(self.traj_embed(trajectory))
        weight = self.embed.weight
        at_time = self.pose_dim + self.cond_dim
        per_code = F.linear(cond, weight[:, self.pose_dim : at_time], self.embed.bias)
        const = per_code.unsqueeze(1) + self.steps * weight[:, at_time]
        at_clock = at_time + 1
        if self.velocity_input:
            steps = trajectory.diff(dim=1, prepend=trajectory[:, :1]) * self.fps
            const = const + F.linear(steps, weight[:, at_clock : at_clock + 3])
            at_clock += 3
        at_rhythm = at_clock + self.clock.shape[-1]
        if self.clock.shape[-1]:
            const = const + F.linear(self.clock, weight[:, at_clock:at_rhythm])
        if self.rhythm is not None:
            amplitudes = self.rhythm(cond).unflatten(1, (self.clock.shape[-1], self.code_rhythms))
            rhythms = torch.einsum("tf,bfm->btm", self.clock[0].to(amplitudes), amplitudes)
            const = const + F.linear(rhythms, weight[:, at_rhythm : at_rhythm + self.code_rhythms])
        return state, const

    def _inputs(self, prev: Tensor, const: Tensor) -> Tensor:
        """Each frame's embedded input (B, T', H) given its previous pose ``prev`` (B, T', J·3) and its
        pose-free term ``const``; with ``step_input`` the step between consecutive previous poses too."""
        x = const + F.linear(prev, self.embed.weight[:, : self.pose_dim])
        if self.step_input:
            steps = torch.cat([torch.zeros_like(prev[:, :1]), prev.diff(dim=1)], dim=1)
            x = x + F.linear(steps, self.embed.weight[:, -self.pose_dim :])
        return self.embed_act(x)

    def _run(self, prev: Tensor, const: Tensor, state: tuple[Tensor, Tensor]) -> tuple[Tensor, Tensor]:
        """Poses (B, T, J·3) and top-layer hidden states (B, T, H) given every frame's previous pose
        ``prev`` (B, T, J·3), in one LSTM call."""
        out, _ = self.lstm(self._inputs(prev, const), state)
        poses = self._pose(self.out(out).float())  # float32 under autocast too
        return (prev + poses if self.residual else poses), out

    def _first_previous(self, n: int) -> Tensor:
        """Frame 0's previous pose (n, J·3): zero, or with ``residual`` the learned start pose."""
        if self.start is None:
            return self.embed.weight.new_zeros(n, self.pose_dim)
        return self._readback(self.start).expand(n, -1)

    def forward(
        self,
        trajectory: Tensor,
        cond: Tensor,
        truth: Tensor | None = None,
        tf_rate: float = 0.0,
        generator: torch.Generator | None = None,
        tf_noise: Tensor | None = None,
    ) -> tuple[Tensor, Tensor]:
        """Joint positions (B, T, J, 3) and the decoder's top-layer hidden states (B, T, H).

        With ``truth`` (B, T, J, 3) this is parallel scheduled sampling: a teacher-forced pass over the
        whole sequence, then (if ``tf_rate`` < 1) a second pass whose previous pose at each frame is the
        ground truth with probability ``tf_rate`` (per frame and sample: where ``tf_noise`` (B, T − 1, 1),
        uniform draws, is below it, drawn from ``generator`` when not given) and the
        first pass's (detached) prediction otherwise. The first pass is teacher-forced (one-step
        predictions) or, with ``free_running_samples``, a free-running decode, so that the decoder learns
        to continue from its own drifted poses as it must when it runs free. Without ``truth`` it decodes
        free-running.
        """
        b = cond.shape[0]
        state, const = self._context(trajectory, cond)
        if truth is None:
            poses, hidden = self._free_run(const, state)
            return self._absolute(poses, trajectory), hidden
        gt = self._readback(truth.reshape(b, self.window, self.pose_dim))
        start = self._first_previous(b).to(gt.dtype).unsqueeze(1)
        prev = torch.cat([start, gt[:, :-1]], dim=1)
        if tf_rate < 1.0:
            with torch.no_grad():
                guess = (
                    self._free_run(const, state)
                    if self.free_running_samples
                    else self._run(prev, const, state)
                )
                first = self._readback(guess[0])
            if tf_noise is None:
                tf_noise = torch.rand(b, self.window - 1, 1, generator=generator, device=gt.device)
            keep = tf_noise < tf_rate
            mixed = torch.where(keep, gt[:, :-1], first[:, :-1])
            prev = torch.cat([start, mixed], dim=1)
        poses, hidden = self._run(prev, const, state)
        return self._absolute(poses, trajectory), hidden

    def rollout(self, trajectory: Tensor, cond: Tensor, truth: Tensor, start: int, frames: int) -> Tensor:
        """Poses (B, frames, J·3) of frames ``start`` … ``start + frames − 1`` decoded free-running after
        teacher-forced frames before ``start`` (previous poses the real ``truth`` (B, T, J, 3)'s): how the
        decoder continues a motion whose phase it has been shown."""
        if not 1 <= start <= self.window - frames:
            raise ValueError(f"a {frames}-frame rollout cannot start at frame {start} of {self.window}")
        b = cond.shape[0]
        state, const = self._context(trajectory, cond)
        gt = self._readback(truth.reshape(b, self.window, self.pose_dim))
        prev = torch.cat([self._first_previous(b).to(gt.dtype).unsqueeze(1), gt[:, : start - 1]], dim=1)
        _, state = self.lstm(self._inputs(prev, const[:, :start]), state)
        before, last, poses = prev[:, -1], gt[:, start - 1], []
        for t in range(start, start + frames):
            pair = torch.stack([before, last], dim=1)  # the input of frame t reads both (its step)
            out, state = self.lstm(self._inputs(pair, const[:, t - 1 : t + 1])[:, 1:], state)
            pose = self._pose(self.out(out[:, 0]).float())
            poses.append(last + pose if self.residual else pose)
            before, last = last, self._readback(poses[-1])
        return torch.stack(poses, dim=1)

    def _readback(self, poses: Tensor) -> Tensor:
        """Poses (..., J·3) as the decoder reads them back: root-centred if relative (a linear map)."""
        if not self.relative:
            return poses
        joints = poses.unflatten(-1, (-1, 3))
        return (joints - joints[..., :1, :]).flatten(-2)

    def _absolute(self, poses: Tensor, trajectory: Tensor) -> Tensor:
        """Joints (B, T, J, 3) from the decoder's output (B, T, J·3): root-centred on the trajectory if
        relative."""
        joints = self._readback(poses).view(poses.shape[0], self.window, -1, 3)
        return joints + trajectory.unsqueeze(2) if self.relative else joints

    def _step_weights(self) -> tuple[Tensor | list[Tensor], ...]:
        """Decoder weights laid out for the compiled loop; cached while no parameter changes.

        ``_free_run_loop`` (joints) gets the output layer, the read-back map R (identity, or
        root-centring if relative) and the next frame's pose embedding folded into one H×H product
        (pose_t = R·(W_out·h_t + b), so W_pose·pose_t = (W_pose·R·W_out)·h_t + W_pose·R·b) and that bias,
        then the same for the step's columns (empty without ``step_input``); ``_free_run_fk_loop``
        (rotations) the transposed pose embedding, output weights and output bias. Then the PReLU slope
        and the LSTM layers.
        """
        lstm = self.lstm
        sources = [self.embed.weight, self.out.weight, self.out.bias, self.embed_act.weight]
        sources += [getattr(lstm, name) for name in lstm._flat_weights_names]
        tracked = torch.is_grad_enabled() and any(p.requires_grad for p in sources)
        key = _identity(sources)
        cache = self._step_cache
        if not tracked and key is not None and cache is not None and _same(cache[0], key):
            return cache[1]
        with torch.set_grad_enabled(tracked):
            w_pose = self.embed.weight[:, : self.pose_dim]
            if self.rotations:
                head = (w_pose.t().contiguous(), self.out.weight.t().contiguous(), self.out.bias)
            else:
                w_out = self._readback(self.out.weight.t()).t()
                bias = self._readback(self.out.bias)
                w_step = self.embed.weight[:, -self.pose_dim :] if self.step_input else w_pose[:0]
                head = ((w_pose @ w_out).t().contiguous(), bias @ w_pose.t())
                head += ((w_step @ w_out).t().contiguous(), bias @ w_step.t())
            layers = range(lstm.num_layers)
            param = functools.partial(getattr, lstm)
            prepared = (
                *head,
                self.embed_act.weight,
                [_loop_gates(param(f"weight_ih_l{k}")).t().contiguous() for k in layers],
                [_loop_gates(param(f"weight_hh_l{k}")).t().contiguous() for k in layers],
                [_loop_gates(param(f"bias_ih_l{k}") + param(f"bias_hh_l{k}")) for k in layers],
            )
        if not tracked and key is not None:
            self._step_cache = (key, prepared)
        return prepared

    def _free_run(self, const: Tensor, state: tuple[Tensor, Tensor]) -> tuple[Tensor, Tensor]:
        """Autoregressive decode, one frame at a time with LSTM cells sharing the nn.LSTM weights.

        The per-frame loop runs in TorchScript where available; a joint decoder's poses are read out of the
        stacked top-layer hidden states with a single matrix product after it, a rotation decoder's are
        placed by forward kinematics inside it (they are read back). It always runs in float32, also
        under autocast (whose lower precision would compound over the frames). Returns the poses and the
        top-layer hidden states.
        """
        with torch.autocast(const.device.type, enabled=False):
            h0, c0 = state[0].float(), state[1].float()
            if self.rotations:
                w_pose, w_out, b_out, slope, w_ih, w_hh, bias = self._step_weights()
                levels = self._fk_levels()
                args = (w_pose, w_out, b_out, slope, w_ih, w_hh, bias, self.fk_offsets, *levels)
                return _compiled(_free_run_fk_loop)(const.float(), h0, c0, *args)
            fused, bias_next, fused_step, bias_step, slope, w_ih, w_hh, bias = self._step_weights()
            first = self._first_previous(1)
            start = F.linear(first, self.embed.weight[:, : self.pose_dim])[0]
            args = (
                fused,
                slope,
                w_ih,
                w_hh,
                bias,
                start,
                self.residual,
                fused_step,
                bias_step,
                self.step_input,
            )
            tops = _compiled(_free_run_loop)(const.float(), bias_next, h0, c0, *args)
            if not self.residual:
                return self.out(tops), tops
            return first.unsqueeze(1) + self._readback(self.out(tops)).cumsum(dim=1), tops

    def _fk_levels(self) -> FkLevels:
        """The attached skeleton's depth levels, on the decoder's device."""
        if self.fk_parents is None:
            raise RuntimeError("a rotation decoder needs attach_skeleton before it decodes")
        return fk_levels(self.fk_parents).to(self.fk_offsets.device)
