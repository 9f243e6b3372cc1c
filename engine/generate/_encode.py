"""Encode a motion into a latent code and guess its action."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np
import torch
from scipy.special import logsumexp

from engine.errors import ConfigError
from engine.generate._decode import as_codes
from engine.modelio import LoadedModel
from engine.motion.datasets import drop_extra_joints
from engine.motion.motion import Motion
from engine.train.windows import crop_windows, prepare_clips


def conform(loaded: LoadedModel, motion: Motion) -> Motion:
    """``motion`` on the model's skeleton: extra joints (e.g. Bandai's ground-projected ``joint_Root``)
    are dropped by name when every model joint is present; ConfigError naming both joint lists otherwise."""
    ours, theirs = loaded.skeleton, motion.skeleton
    if not ours.same_topology(theirs):
        motion = drop_extra_joints(motion, ours.names)
    if not ours.same_topology(motion.skeleton):
        source = motion.meta.get("source", motion.meta.get("path", "the motion"))
        raise ConfigError(
            f"{source}: skeleton does not match the model's ({theirs.n_joints} joints "
            f"[{', '.join(theirs.names)}] vs {ours.n_joints} joints [{', '.join(ours.names)}])"
        )
    return motion


def guess_action(loaded: LoadedModel, code: np.ndarray) -> int | None:
    """The action whose mode mixture gives ``code`` (D,) the highest density; None without a bank."""
    bank = loaded.bank
    if bank is None or not bank.modes:
        return None
    x = as_codes(loaded, code)
    actions = sorted(bank.modes)
    scores = [float(logsumexp(bank.modes[a].log_responsibilities(x)[0])) for a in actions]
    return actions[int(np.argmax(scores))]


def encode_clips(loaded: LoadedModel, motions: Sequence[Motion]) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean codes (N, D) and end locations (N, 3) of ``motions``, as the training bank has them.

    Each motion is resampled to the model's fps and canonicalised like a training window (frame-0 root
    at the origin, facing +z); a clip longer than T frames is represented by its centre window, a
    shorter one is padded with its last frame and masked. Action labels are not used.
    """
    if not motions:
        raise ConfigError("no motions to encode")
    # The label only routes clips through the training preparation; it does not affect the codes.
    unlabelled = [dataclasses.replace(conform(loaded, m), action=loaded.action_names[0]) for m in motions]
    prepared = prepare_clips(unlabelled, loaded.action_names, loaded.fps, loaded.window)
    window = crop_windows(prepared, np.arange(len(motions)), None)
    model = loaded.model
    device = next(model.parameters()).device
    with torch.inference_mode():
        lmp = torch.as_tensor(window.lmp, dtype=torch.float32, device=device)
        mask = torch.as_tensor(window.mask, device=device)
        mu, _ = model.encode(lmp, mask)
    return mu.cpu().numpy().astype(np.float32), window.ends.astype(np.float32)


def encode(loaded: LoadedModel, motion: Motion) -> tuple[np.ndarray, int | None]:
    """Posterior mean code (D,) of ``motion`` (its centre window, see :func:`encode_clips`) and a guess
    of its action index (None without a latent bank)."""
    codes, _ = encode_clips(loaded, [motion])
    return codes[0], guess_action(loaded, codes[0])
