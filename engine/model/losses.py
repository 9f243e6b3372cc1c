"""ODMO training losses; every frame-level term is masked so padded frames never count."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import Tensor

from engine.metrics.physics import HEADING_SPAN, MOVING_SPEED, PLANTED_TOL
from engine.model.config import OdmoConfig
from engine.motion.contact import HEIGHT_TOL, foot_lines, hip_pair, shoulder_pair
from engine.motion.skeleton import Skeleton

LOSS_TERMS = (
    "recon",
    "traj",
    "consistency",
    "contrastive",
    "prior",
    "raw",
    "velocity",
    "contact",
    "skate",
    "free",
    "speed",
    "spectrum",
    "free_skate",
    "foot_height",
    "heading",
    "twist",
    "coordination",
    "start",
    "stance",
    "rollout",
    "upper_speed",
    "foot_twist",
    "skim",
    "stand",
    "floor",
)
STANCE_TAU = 0.01  # metres: how much lower a foot joint must be than another to take the weight
SKIM_TAU = 0.01  # metres: how softly a foot joint passes out of the skate rule's planted band


def masked_mse(pred: Tensor, target: Tensor, mask: Tensor, axis_weights: Tensor | None = None) -> Tensor:
    """Mean squared error over real frames only.

    Parameters
    ----------
    pred, target : (B, T, ..., 3) tensors.
    mask : (B, T) bool or 0/1, True for real frames.
    axis_weights : optional (3,) weight of each of x, y, z.
    """
    err = (pred - target).square()
    if axis_weights is not None:
        err = err * axis_weights
    per_frame = err.flatten(2).mean(dim=2)
    m = mask.to(per_frame.dtype)
    return (per_frame * m).sum() / m.sum().clamp(min=1.0)


def velocity_loss(pred: Tensor, target: Tensor, mask: Tensor, fps: float) -> Tensor:
    """Mean squared error (m²/s²) of frame-to-frame joint velocities over pairs of real frames."""
    both = mask[:, 1:].bool() & mask[:, :-1].bool()
    return masked_mse(pred.diff(dim=1) * fps, target.diff(dim=1) * fps, both)


def _spans(x: Tensor, span: int) -> Tensor:
    """Per-frame values (B, T, ...) cut into runs of ``span`` frames (0: one run, the whole window) →
    (B, K, span, ...), the last run padded with zeros."""
    n = x.shape[1]
    span = n if span <= 0 else min(span, n)
    padded = torch.nn.functional.pad(x.movedim(1, -1), (0, -n % span)).movedim(-1, 1)
    return padded.unflatten(1, (-1, span))


def _span_sums(steps: Tensor, span: int) -> Tensor:
    """Sums (B, K, ...) of per-step values (B, S, ...) over runs of ``span`` steps (0: all of them; the
    last run may be shorter)."""
    return _spans(steps, span).sum(2)


def _window_span_errors(pred: Tensor, target: Tensor, mask: Tensor, span: int) -> tuple[Tensor, Tensor]:
    """Per window (B,): the squared errors of the runs' mean positions (``span_mean_mse``), each run's
    weighted by its real frames and summed, and the window's real frames."""
    real = mask.to(pred.dtype)[:, :, None, None]
    counts = _span_sums(real, span)  # (B, K, 1, 1)
    error = (_span_sums(pred * real, span) - _span_sums(target * real, span)) / counts.clamp(min=1.0)
    return (error.square().flatten(2).mean(2) * counts[:, :, 0, 0]).sum(1), counts.flatten(1).sum(1)


def span_mean_mse(pred: Tensor, target: Tensor, mask: Tensor, span: int) -> Tensor:
    """Squared error of the mean positions of ``pred`` against ``target`` (B, T, J, 3) over the real
    frames of each run of ``span`` frames, weighted by its real frames (1: ``masked_mse``): the motion
    within a run is left to phase-free terms, so an uncertain phase no longer pulls it to a still pose."""
    if span <= 1:
        return masked_mse(pred, target, mask)
    error, frames = _window_span_errors(pred, target, mask, span)
    return error.sum() / frames.sum().clamp(min=1.0)


def shift_tolerant_mse(pred: Tensor, target: Tensor, mask: Tensor, span: int, max_shift: int) -> Tensor:
    """``span_mean_mse`` of each window at the time shift that fits it best: ``pred`` frame t against
    ``target`` frame t + s, |s| ≤ ``max_shift``, over the frames real in both. A decode that keeps the
    motion's amplitude but not its phase is not pulled toward a still pose."""
    n_frames = pred.shape[1]
    errors, weights = [], []
    for s in range(-max_shift, max_shift + 1):
        a, b, n = max(0, -s), max(0, s), n_frames - abs(s)
        both = mask[:, a : a + n].bool() & mask[:, b : b + n].bool()
        error, frames = _window_span_errors(pred[:, a : a + n], target[:, b : b + n], both, max(span, 1))
        errors.append(torch.where(frames > 0, error / frames.clamp(min=1.0), torch.inf))
        weights.append(frames)
    stacked = torch.stack(errors, 1)
    best = stacked.argmin(1, keepdim=True)
    error = stacked.gather(1, best)[:, 0]
    frames = torch.stack(weights, 1).gather(1, best)[:, 0]
    return torch.where(frames > 0, error * frames, 0.0).sum() / frames.sum().clamp(min=1.0)


def start_mse(pred: Tensor, target: Tensor, mask: Tensor, root: int, frames: int) -> Tensor:
    """Squared error of the first ``frames`` root-relative poses of ``pred`` against ``target`` (B, T, J, 3)
    over the real ones: where in its cycle a motion starts, and which way it moves."""
    return masked_mse(
        about_root(pred[:, :frames], root), about_root(target[:, :frames], root), mask[:, :frames]
    )


def about_root(joints: Tensor, root: int) -> Tensor:
    """Joints (B, T, J, 3) relative to each frame's ``root`` joint."""
    return joints - joints[:, :, root : root + 1]


def _real_pairs(mask: Tensor) -> Tensor:
    """(B, T - 1) 1 where a frame and the next are both real, else 0."""
    return (mask[:, 1:].bool() & mask[:, :-1].bool()).float()


def mean_speeds(joints: Tensor, mask: Tensor, fps: float, root: int, span: int = 0) -> Tensor:
    """Per window, span and joint (B, K, J): mean speed (m/s) of the root-relative joints (B, T, J, 3)
    over the pairs of real frames in each run of ``span`` frame steps (0: one span, the whole window;
    a span without a real pair reads 0); independent of the motion's phase."""
    local = about_root(joints, root)
    both = _real_pairs(mask).to(joints.dtype)[:, :, None]
    speed = local.diff(dim=1).square().sum(-1).clamp(min=1e-12).sqrt() * fps
    return _span_sums(speed * both, span) / _span_sums(both, span).clamp(min=1.0)


#: Speed (m/s) added to both sides of the log-speed error, so that joints at rest weigh little.
LOG_SPEED_FLOOR = 0.05


def speed_loss(
    pred: Tensor,
    target: Tensor,
    mask: Tensor,
    fps: float,
    root: int,
    log: bool = False,
    span: int = 0,
    on: Sequence[int] | None = None,
) -> Tensor:
    """Squared error of the mean joint speeds of ``pred`` against ``target`` (B, T, J, 3) in each run of
    ``span`` frame steps (0: the whole window; spans without real frames left out): the motion an L2
    loss on positions lets shrink towards a mean pose. Spans shorter than the window keep a decode from
    meeting the window's mean speed with a burst that then stops. In m²/s², or with ``log`` of
    log(speed + LOG_SPEED_FLOOR), so that a hand waving at a third of its speed costs as much as a foot
    running at a third of its own. ``on``: the joints compared (None: all)."""
    pred_speed = mean_speeds(pred, mask, fps, root, span)
    target_speed = mean_speeds(target, mask, fps, root, span)
    if on is not None:
        pred_speed, target_speed = pred_speed[..., list(on)], target_speed[..., list(on)]
    if log:
        pred_speed = torch.log(pred_speed + LOG_SPEED_FLOOR)
        target_speed = torch.log(target_speed + LOG_SPEED_FLOOR)
    real = _span_sums(_real_pairs(mask), span) > 0  # (B, K)
    return (pred_speed - target_speed).square().mean(-1)[real].mean()


#: Amplitude (m) added to both sides of the log-spectrum error, so that bins without motion weigh little.
SPECTRUM_FLOOR = 0.002
COORDINATION_FLOOR = 1e-3  # (m²/s²)²: a still window's Gram is near zero


def amplitude_spectra(joints: Tensor, mask: Tensor, root: int) -> Tensor:
    """Per window, joint and frequency (B, J, T // 2 + 1): the amplitude (m) of the root-relative joints
    (B, T, J, 3) about their mean over the real frames, padded frames held at that mean; phase-free."""
    local = about_root(joints, root)
    m = mask.to(joints.dtype)[:, :, None, None]
    mean = (local * m).sum(1, keepdim=True) / m.sum(1, keepdim=True).clamp(min=1.0)
    spectra = torch.fft.rfft((local - mean) * m, dim=1).abs().square().sum(-1)
    return (spectra.clamp(min=1e-12).sqrt() / m.sum(1).clamp(min=1.0)).transpose(1, 2)


def leg_joints(config: OdmoConfig, parents: Sequence[int], root: int) -> set[int]:
    """The chains from the root (not included) to the config's foot joints."""
    legs = set()
    for j in config.foot_joints:
        while j != root and j >= 0:
            legs.add(j)
            j = parents[j]
    return legs


def spectrum_joints(config: OdmoConfig, parents: Sequence[int], root: int) -> list[int]:
    """Joints the spectrum term sees: all, or with ``spectrum_legs`` off all but ``leg_joints`` (a
    per-joint spectrum leaves a foot's lift out of phase with its step)."""
    every = set(range(len(parents)))
    return sorted(every if config.spectrum_legs else every - leg_joints(config, parents, root))


def upper_joints(config: OdmoConfig, parents: Sequence[int], root: int) -> list[int]:
    """Joints the upper-body speed term sees: all but the root and ``leg_joints``."""
    return sorted(set(range(len(parents))) - leg_joints(config, parents, root) - {root})


def coordination_joints(config: OdmoConfig, parents: Sequence[int], root: int) -> list[int]:
    """Joints the coordination term sees: all, or with ``coordination_on`` "legs" only ``leg_joints``."""
    if config.coordination_on == "legs":
        return sorted(leg_joints(config, parents, root))
    return list(range(len(parents)))


@dataclass(frozen=True)
class LossJoints:
    """Joints the loss terms read, found once from the skeleton: the root, the joints of the spectrum
    term, the two hips of the heading term and the two shoulders of the twist term (None: a rig without
    two legs, or two arms), the joints of the coordination term and of the upper-body speed term, and
    the (toe, ankle) pairs of the foot-twist term (the first foot joint below each ankle)."""

    root: int
    spectrum_on: tuple[int, ...]
    hips: tuple[int, int] | None
    shoulders: tuple[int, int] | None
    coordination_on: tuple[int, ...]
    upper_on: tuple[int, ...]
    feet: tuple[tuple[int, int], ...] = ()

    @classmethod
    def of(cls, config: OdmoConfig, skeleton: Skeleton) -> LossJoints:
        """The joints of ``config``'s terms on ``skeleton``."""
        spectrum_on = tuple(spectrum_joints(config, skeleton.parents, skeleton.root))
        coordination_on = tuple(coordination_joints(config, skeleton.parents, skeleton.root))
        upper_on = tuple(
            upper_joints(config, skeleton.parents, skeleton.root) if config.w_upper_speed else ()
        )
        hips, shoulders = hip_pair(skeleton), shoulder_pair(skeleton)
        feet = tuple((toe, ankle) for ankle, toe in foot_lines(skeleton))
        return cls(skeleton.root, spectrum_on, hips, shoulders, coordination_on, upper_on, feet)


def spectrum_loss(
    pred: Tensor,
    target: Tensor,
    mask: Tensor,
    root: int,
    on: Sequence[int] | None = None,
    span: int = 0,
) -> Tensor:
    """Squared error of the log amplitude spectra (``amplitude_spectra`` + SPECTRUM_FLOOR) of ``pred``
    against ``target`` (B, T, J, 3) over the joints ``on`` (None: all): how much each joint moves at each
    rhythm, whatever the phase, so that a slow raise and a quick wave of the same speed differ. With
    ``span`` > 0 the spectra are taken over each run of that many frames (runs with fewer than two real
    frames left out), so that a burst which then stops no longer matches a steady motion."""
    pick = slice(None) if on is None else list(on)
    pred, target = _spans(pred, span).flatten(0, 1), _spans(target, span).flatten(0, 1)
    mask = _spans(mask.to(pred.dtype), span).flatten(0, 1)
    pred_log = torch.log(amplitude_spectra(pred, mask, root)[:, pick] + SPECTRUM_FLOOR)
    real_log = torch.log(amplitude_spectra(target, mask, root)[:, pick] + SPECTRUM_FLOOR)
    real = mask.sum(1) >= 2
    return (pred_log - real_log).square()[real].mean()


def velocity_gram(
    joints: Tensor, mask: Tensor, root: int, fps: float, on: Sequence[int] | None = None
) -> Tensor:
    """(B, 3J, 3J) mean outer product over the real frame steps of each window's joint velocities
    relative to the root (m²/s²), of the joints ``on`` (None: all, J of them): how every joint's movement
    goes with every other's, whatever the phase."""
    local = about_root(joints, root)
    if on is not None:
        local = local[:, :, list(on)]
    steps = _real_pairs(mask).to(joints.dtype)
    vel = (local.diff(dim=1) * fps).flatten(2) * steps.unsqueeze(-1)
    return torch.einsum("btk,btl->bkl", vel, vel) / steps.sum(1).clamp(min=1.0)[:, None, None]


def coordination_loss(
    pred: Tensor, target: Tensor, mask: Tensor, root: int, fps: float, on: Sequence[int] | None = None
) -> Tensor:
    """Squared error of ``velocity_gram`` of ``pred`` against ``target`` (B, T, J, 3) over the joints
    ``on`` (None: all), relative to both (their squared norms plus COORDINATION_FLOOR, so 0..2 per window,
    however still either is): feet that should alternate but step together differ in sign there, which
    per-joint speeds and spectra cannot see."""
    pred_g, real_g = velocity_gram(pred, mask, root, fps, on), velocity_gram(target, mask, root, fps, on)
    error = (pred_g - real_g).square().sum(dim=(1, 2))
    scale = pred_g.square().sum(dim=(1, 2)) + real_g.square().sum(dim=(1, 2)) + COORDINATION_FLOOR
    return (error / scale).mean()


def contact_loss(logits: Tensor, labels: Tensor, mask: Tensor) -> Tensor:
    """Cross-entropy of the contact logits (B, T, F) against labels (B, T, F) over real frames."""
    m = mask.to(logits.dtype).unsqueeze(-1).expand_as(logits)
    bce = torch.nn.functional.binary_cross_entropy_with_logits(logits, labels, weight=m, reduction="sum")
    return bce / m.sum().clamp(min=1.0)


def skate_loss(feet: Tensor, labels: Tensor, mask: Tensor, fps: float) -> Tensor:
    """Mean squared speed (m²/s²) of generated foot joints ``feet`` (B, T, F, 3) where the data's are
    planted (``labels`` (B, T, F)) in both frames of a real frame step."""
    m = mask.to(feet.dtype).unsqueeze(-1)
    planted = (labels[:, 1:] * labels[:, :-1] * m[:, 1:] * m[:, :-1]).detach()
    speed2 = (feet.diff(dim=1) * fps).square().sum(-1)
    return (speed2 * planted).sum() / planted.sum().clamp(min=1.0)


def own_contacts(feet: Tensor, rest_heights: Sequence[float], mask: Tensor) -> Tensor:
    """Contact labels (B, T, F) of generated foot joints ``feet`` (B, T, F, 3) by the height rule of the
    data's labels alone: within HEIGHT_TOL of the joint's resting height over the window's floor (the
    lowest any foot comes to its resting height in real frames), so a floating window still has contacts."""
    return (_above_floor(feet, rest_heights, mask) <= HEIGHT_TOL).to(feet.dtype).detach()


def _above_floor(feet: Tensor, rest_heights: Sequence[float], mask: Tensor) -> Tensor:
    """Heights (B, T, F) of foot joints over their resting heights, less the window's floor: the lowest
    any foot comes to its resting height in real frames."""
    above = feet[..., 1] - feet.new_tensor(list(rest_heights))
    return above - above.masked_fill(~mask.unsqueeze(-1), float("inf")).amin(dim=(1, 2), keepdim=True)


def stance_speeds(feet: Tensor, rest_heights: Sequence[float], mask: Tensor, fps: float) -> Tensor:
    """(B,) mean horizontal speed (m/s) of the lowest foot joint over its resting height in each window of
    ``feet`` (B, T, F, 3): each frame step weighs every joint by a softmin of its height (``STANCE_TAU``),
    so the speed is the standing foot's and moves with whichever foot the decode puts lowest."""
    above = feet[..., 1] - feet.new_tensor(list(rest_heights))
    weight = torch.softmax(-above / STANCE_TAU, dim=-1)
    weight = 0.5 * (weight[:, 1:] + weight[:, :-1])
    speed = ((feet[:, 1:, :, ::2] - feet[:, :-1, :, ::2]).square().sum(-1) + 1e-8).sqrt() * fps
    pairs = _real_pairs(mask).to(feet.dtype)
    return ((weight * speed).sum(-1) * pairs).sum(1) / pairs.sum(1).clamp(min=1.0)


def stance_loss(
    pred: Tensor, target: Tensor, rest_heights: Sequence[float], mask: Tensor, fps: float
) -> Tensor:
    """Squared error (m²/s²) of ``stance_speeds`` of ``pred`` against ``target`` (B, T, F, 3) per window:
    the foot a decode puts lowest stands as still as the data's (real walks about 0.3 m/s by this
    measure; a run's foot moves in flight), whatever the phase, and a foot kept off the floor does not
    escape it."""
    return (
        (stance_speeds(pred, rest_heights, mask, fps) - stance_speeds(target, rest_heights, mask, fps))
        .square()
        .mean()
    )


def foot_height_loss(pred: Tensor, target: Tensor, rest_heights: Sequence[float], mask: Tensor) -> Tensor:
    """Squared error (m²) of each foot joint's sorted heights over its window's floor in ``pred`` against
    ``target`` (B, T, F, 3): how long each foot spends at each height, whatever the phase, so feet
    neither float nor skim where the data's step. Padded frames sort last in both and cost nothing."""
    pred_h, real_h = _above_floor(pred, rest_heights, mask), _above_floor(target, rest_heights, mask)
    return _sorted_error(pred_h, real_h, mask)


def _sorted_error(pred_h: Tensor, real_h: Tensor, mask: Tensor) -> Tensor:
    """Squared error of heights (B, T, …) each sorted over time, ``pred_h`` against ``real_h``: how long
    each spends at each height, whatever the phase; padded frames (``mask`` (B, T) False) sort last in both
    and cost nothing."""
    shape = (*mask.shape, *(1,) * (pred_h.dim() - 2))
    pad = ~mask.bool().view(shape)
    pred_s = pred_h.masked_fill(pad, 1e3).sort(dim=1).values
    real_s = real_h.masked_fill(pad, 1e3).sort(dim=1).values
    m = mask.to(pred_h.dtype).sort(dim=1, descending=True).values.view(shape).expand_as(pred_s)
    return ((pred_s - real_s).square() * m).sum() / m.sum().clamp(min=1.0)


def skim_speeds(feet: Tensor, mask: Tensor, fps: float) -> Tensor:
    """(B,) the skate metric's planted-foot speed made soft: per window of foot joints ``feet`` (B, T, F, 3),
    the mean over frame steps and joints of the squared horizontal speed (m²/s²), each step weighed by how
    far inside ``PLANTED_TOL`` of the window's lowest foot point both its frames lie (a sigmoid of width
    ``SKIM_TAU``), so a foot skimming the floor is slowed or lifted, whichever costs the decode less."""
    pad = ~mask.bool().unsqueeze(-1)
    floor = feet[..., 1].masked_fill(pad, float("inf")).amin(dim=(1, 2), keepdim=True).detach()
    near = torch.sigmoid((PLANTED_TOL - (feet[..., 1] - floor)) / SKIM_TAU)
    pairs = _real_pairs(mask).to(feet.dtype).unsqueeze(-1)
    weight = near[:, 1:] * near[:, :-1] * pairs
    speed2 = (feet[:, 1:, :, ::2] - feet[:, :-1, :, ::2]).square().sum(-1) * fps**2
    return (weight * speed2).sum(dim=(1, 2)) / (pairs.sum(dim=(1, 2)) * feet.shape[2]).clamp(min=1.0)


def skim_loss(pred: Tensor, target: Tensor, mask: Tensor, fps: float) -> Tensor:
    """Mean over windows of how far (m²/s²) the ``skim_speeds`` of ``pred`` exceed those of ``target``
    (B, T, F, 3): feet near the floor move no faster than the data's, and a decode gains nothing by
    keeping them higher than the data does."""
    excess = skim_speeds(pred, mask, fps) - skim_speeds(target, mask, fps).detach()
    return excess.clamp(min=0.0).mean()


def stand_heights(joints: Tensor, root: int, feet: Sequence[int], mask: Tensor) -> Tensor:
    """(B,) mean over the real frames of each window (B, T, J, 3) of the ``root`` joint's height over the
    lowest of its ``feet`` joints: how far the body stands up on its legs, wherever its floor is."""
    stand = joints[:, :, root, 1] - joints[:, :, list(feet), 1].amin(dim=-1)
    m = mask.to(joints.dtype)
    return (stand * m).sum(1) / m.sum(1).clamp(min=1.0)


def stand_loss(pred: Tensor, target: Tensor, root: int, feet: Sequence[int], mask: Tensor) -> Tensor:
    """Squared error (m²) of ``stand_heights`` of ``pred`` against ``target``, mean over windows: a decode
    that draws its legs up under a body at the data's height, which the clean-up then lowers onto the
    floor crouched, pays for it (every foot term reads heights over the window's own floor)."""
    return (stand_heights(pred, root, feet, mask) - stand_heights(target, root, feet, mask)).square().mean()


def floor_heights(feet: Tensor, rest_heights: Sequence[float]) -> Tensor:
    """(B, T) height of the lowest foot joint over its resting height in each frame of ``feet`` (B, T, F, 3),
    in the window's own frame (where the data's floor is the same for a decode and its real window)."""
    return (feet[..., 1] - feet.new_tensor(list(rest_heights))).amin(dim=-1)


def floor_loss(pred: Tensor, target: Tensor, rest_heights: Sequence[float], mask: Tensor) -> Tensor:
    """Squared error (m²) of the sorted ``floor_heights`` of ``pred`` against ``target`` (B, T, F, 3): how
    long the lowest foot spends at each height over the data's floor, whatever the phase; a decode whose
    feet leave the floor together, or stand on a floor of their own, pays for it (every other foot term
    reads heights over the window's own lowest point). Padded frames sort last in both and cost nothing."""
    return _sorted_error(floor_heights(pred, rest_heights), floor_heights(target, rest_heights), mask)


def _heading_cosines(joints: Tensor, hips: tuple[int, int], span: int) -> tuple[Tensor, Tensor]:
    """Cosines (B, S) between the hips' axis at each span's middle and the horizontal travel of the
    hips' midpoint over ``span`` frames, and that travel (m)."""
    pelvis = 0.5 * (joints[:, :, hips[0], ::2] + joints[:, :, hips[1], ::2])
    travel = pelvis[:, span:] - pelvis[:, :-span]
    middle = joints[:, span // 2 : span // 2 + travel.shape[1]]
    axis = middle[:, :, hips[0], ::2] - middle[:, :, hips[1], ::2]
    dist = travel.norm(dim=-1)
    return (travel * axis).sum(-1) / (dist * axis.norm(dim=-1)).clamp(min=1e-6), dist


def heading_loss(pred: Tensor, target: Tensor, mask: Tensor, hips: tuple[int, int], fps: float) -> Tensor:
    """Squared error of the cosine between the body's hip axis and its direction of travel over
    HEADING_SPAN (see ``engine.metrics.physics``) in ``pred`` against ``target`` (B, T, J, 3), over the
    spans where the target moves at MOVING_SPEED or more: 0 when the body faces its path as the data's."""
    span = max(1, round(HEADING_SPAN * fps))
    if pred.shape[1] <= span:
        return pred.new_zeros(())
    pred_cos, _ = _heading_cosines(pred, hips, span)
    real_cos, dist = _heading_cosines(target, hips, span)
    valid = (mask[:, span:] & mask[:, :-span] & (dist >= MOVING_SPEED * span / fps)).to(pred.dtype)
    return ((pred_cos - real_cos.detach()).square() * valid).sum() / valid.sum().clamp(min=1.0)


def _twists(joints: Tensor, hips: tuple[int, int], shoulders: tuple[int, int]) -> Tensor:
    """(B, T, 2) unit (cos, sin) of the angle about +y from the hips' axis to the shoulders' axis."""
    h = joints[:, :, hips[0], ::2] - joints[:, :, hips[1], ::2]
    s = joints[:, :, shoulders[0], ::2] - joints[:, :, shoulders[1], ::2]
    turn = torch.stack([(h * s).sum(-1), h[..., 1] * s[..., 0] - h[..., 0] * s[..., 1]], dim=-1)
    return turn / turn.norm(dim=-1, keepdim=True).clamp(min=1e-6)


def twist_loss(
    pred: Tensor, target: Tensor, mask: Tensor, hips: tuple[int, int], shoulders: tuple[int, int]
) -> Tensor:
    """Squared distance between the unit (cos, sin) of the torso twist (``engine.metrics.physics``) of
    ``pred`` and of ``target`` (B, T, J, 3) per real frame: 0 for the data's twist, 2 − 2 cos Δ for a
    twist Δ off it. Any joint pair in place of the shoulders gives its turn against the hips (a foot's:
    (toe, ankle))."""
    err = (_twists(pred, hips, shoulders) - _twists(target, hips, shoulders).detach()).square().sum(-1)
    m = mask.to(err.dtype)
    return (err * m).sum() / m.sum().clamp(min=1.0)


def contrastive_loss(
    mu_a: Tensor, mu_b: Tensor, same: Tensor, alpha: float, pull_weight: float = 1.0
) -> Tensor:
    """Pairwise loss on code means (B, D): same action pull_weight·0.5·relu(d² − 0.25), different
    0.5·relu(α − d)²."""
    d2 = (mu_a - mu_b).square().sum(dim=1)
    pull = pull_weight * 0.5 * torch.relu(d2 - 0.25)
    push = 0.5 * torch.relu(alpha - torch.sqrt(d2 + 1e-12)).square()
    return torch.where(same, pull, push).mean()


def prior_loss(logvar: Tensor, sigma2: float) -> Tensor:
    """Posterior prior −log det Σ + tr Σ / σ² (diagonal Σ), shifted to 0 at Σ = σ²I, per dimension."""
    ratio = logvar.exp() / sigma2
    return (ratio - logvar + torch.log(torch.as_tensor(sigma2)) - 1.0).mean()


def odmo_losses(
    config: OdmoConfig,
    *,
    joints: Tensor,
    trajectory: Tensor,
    mask: Tensor,
    pred_joints: Tensor,
    pred_trajectory: Tensor,
    mu: Tensor,
    logvar: Tensor,
    same: Tensor,
    root: int,
    raw_joints: Tensor | None = None,
    contact_logits: Tensor | None = None,
    contacts: Tensor | None = None,
    free_joints: Tensor | None = None,
    spectrum_on: Sequence[int] | None = None,
    hips: tuple[int, int] | None = None,
    shoulders: tuple[int, int] | None = None,
    coordination_on: Sequence[int] | None = None,
    rollout: tuple[int, Tensor] | None = None,
    upper_on: Sequence[int] | None = None,
    feet: Sequence[tuple[int, int]] = (),
) -> dict[str, Tensor]:
    """Every loss term and the weighted ``total``.

    Parameters
    ----------
    joints, pred_joints : (2B, T, J, 3) real and generated joints of B anchors followed by their B partners.
    trajectory, pred_trajectory : (2B, T, 3) real and generated root paths.
    mask : (2B, T) real frames.
    mu, logvar : (2B, D) code posteriors.
    same : (B,) True where anchor i and partner i share an action.
    root : index of the root joint.
    raw_joints : (2B, T, J, 3) the decoder's joints before the bone projection (None: no projection).
    contact_logits, contacts : (2B, T, F) predicted contact logits and the data's labels of the config's
        foot joints (None: no contact head).
    free_joints : (2B, T, J, 3) a free-running decode of the same codes (None: no free-running terms).
    spectrum_on : the joints the spectrum term compares (``spectrum_joints``; None: all).
    hips : the two hips of the heading and twist terms (``hip_pair``; None: neither term).
    shoulders : the two shoulders of the twist term (``shoulder_pair``; None: no twist term).
    coordination_on : the joints the coordination term compares (``coordination_joints``; None: all).
    rollout : the first frame and the joints (2B, K, J, 3) of a rollout (``OdmoModel.rollout``; None: no
        rollout term).
    upper_on : the joints the upper-body speed term compares (``upper_joints``; None: all).
    feet : the (toe, ankle) pairs of the foot-twist term (``LossJoints.feet``; empty: no such term).
    """
    axis = torch.tensor([1.0, config.traj_y_weight, 1.0], device=joints.device)
    zero = joints.new_zeros(())
    b = same.shape[0]
    terms = {
        "recon": masked_mse(pred_joints, joints, mask),
        "traj": masked_mse(pred_trajectory, trajectory, mask, axis),
        "consistency": masked_mse(pred_joints[:, :, root], pred_trajectory, mask),
        "contrastive": contrastive_loss(mu[:b], mu[b:], same, config.alpha, config.contrastive_pull),
        "prior": prior_loss(logvar, config.prior_sigma2),
        "raw": zero if raw_joints is None else masked_mse(raw_joints, joints, mask),
        "velocity": velocity_loss(pred_joints, joints, mask, config.fps),
        "contact": zero,
        "skate": zero,
        "free": zero,
        "speed": zero,
        "spectrum": zero,
        "free_skate": zero,
        "foot_height": zero,
        "heading": zero,
        "twist": zero,
        "coordination": zero,
        "start": zero,
        "stance": zero,
        "rollout": zero,
        "upper_speed": zero,
        "foot_twist": zero,
        "skim": zero,
        "stand": zero,
        "floor": zero,
    }
    twist_on = free_joints is not None and hips is not None and shoulders is not None
    foot_twist_on = free_joints is not None and hips is not None and len(feet) > 0
    if free_joints is not None:
        if config.free_shift > 0:  # root-relative: the shifted target's root is the trajectory loss's
            local, truth = about_root(free_joints, root), about_root(joints, root)
            terms["free"] = shift_tolerant_mse(local, truth, mask, config.free_span, config.free_shift)
        else:
            terms["free"] = span_mean_mse(free_joints, joints, mask, config.free_span)
        terms["start"] = start_mse(free_joints, joints, mask, root, config.start_frames)
        log = config.speed_error == "log"
        terms["speed"] = speed_loss(free_joints, joints, mask, config.fps, root, log, config.speed_span)
        if config.w_upper_speed > 0:  # LossJoints leaves upper_on empty while the term is off
            terms["upper_speed"] = speed_loss(
                free_joints, joints, mask, config.fps, root, log, config.upper_speed_span, upper_on
            )
        terms["spectrum"] = spectrum_loss(free_joints, joints, mask, root, spectrum_on, config.spectrum_span)
        if hips is not None:
            terms["heading"] = heading_loss(free_joints, joints, mask, hips, config.fps)
        if twist_on:
            terms["twist"] = twist_loss(free_joints, joints, mask, hips, shoulders)
        if foot_twist_on and config.w_foot_twist > 0:
            twists = [twist_loss(free_joints, joints, mask, hips, pair) for pair in feet]
            terms["foot_twist"] = torch.stack(twists).mean()
        terms["coordination"] = coordination_loss(
            free_joints, joints, mask, root, config.fps, coordination_on
        )
    if contact_logits is not None and contacts is not None:
        feet = list(config.foot_joints)
        terms["contact"] = contact_loss(contact_logits, contacts, mask)
        terms["skate"] = skate_loss(pred_joints[:, :, feet], contacts, mask, config.fps)
        if free_joints is not None:
            free_feet, rest = free_joints[:, :, feet], config.foot_heights or (0.0,) * len(feet)
            terms["foot_height"] = foot_height_loss(free_feet, joints[:, :, feet], rest, mask)
            terms["stance"] = stance_loss(free_feet, joints[:, :, feet], rest, mask, config.fps)
            if config.free_skate_contacts == "own":
                contacts = own_contacts(free_feet, rest, mask)
            terms["free_skate"] = skate_loss(free_feet, contacts, mask, config.fps)
            terms["skim"] = skim_loss(free_feet, joints[:, :, feet], mask, config.fps)
            terms["stand"] = stand_loss(free_joints, joints, root, feet, mask)
            terms["floor"] = floor_loss(free_feet, joints[:, :, feet], rest, mask)
    if rollout is not None:
        start, rolled = rollout
        span = slice(start, start + rolled.shape[1])
        truth = about_root(joints[:, span], root)
        terms["rollout"] = masked_mse(about_root(rolled, root), truth, mask[:, span])
    free_feet_on = free_joints is not None and contact_logits is not None
    weights = {
        "recon": config.w_recon,
        "traj": config.w_traj,
        "consistency": config.w_consistency,
        "contrastive": config.w_contrastive,
        "prior": config.w_prior,
        "raw": config.w_raw if raw_joints is not None else 0.0,
        "velocity": config.w_velocity,
        "contact": config.w_contact if contact_logits is not None else 0.0,
        "skate": config.w_skate if contact_logits is not None else 0.0,
        "free": config.w_free if free_joints is not None else 0.0,
        "speed": config.w_speed if free_joints is not None else 0.0,
        "spectrum": config.w_spectrum if free_joints is not None else 0.0,
        "free_skate": config.w_free_skate if free_feet_on else 0.0,
        "foot_height": config.w_foot_height if free_feet_on else 0.0,
        "heading": config.w_heading if free_joints is not None and hips is not None else 0.0,
        "twist": config.w_twist if twist_on else 0.0,
        "coordination": config.w_coordination if free_joints is not None else 0.0,
        "start": config.w_start if free_joints is not None else 0.0,
        "stance": config.w_stance if free_feet_on else 0.0,
        "rollout": config.w_rollout if rollout is not None else 0.0,
        "upper_speed": config.w_upper_speed if free_joints is not None else 0.0,
        "foot_twist": config.w_foot_twist if foot_twist_on else 0.0,
        "skim": config.w_skim if free_feet_on else 0.0,
        "stand": config.w_stand if free_feet_on else 0.0,
        "floor": config.w_floor if free_feet_on else 0.0,
    }
    terms["total"] = sum(weights[k] * terms[k] for k in LOSS_TERMS if weights[k] > 0)
    return terms
