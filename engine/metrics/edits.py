"""How well an edit direction edits: on decoded motions, does a style classifier see more of the target
style, and does the action classifier still see the same action (MoDi paper §4.3's measurement)?"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from engine.errors import ConfigError
from engine.generators.base import FolderGenerator
from engine.metrics.classifier import Classifier
from engine.motion.skeleton import Skeleton
from engine.train.windows import canonicalize


@dataclass(frozen=True)
class EditEffect:
    """Of ``n`` edited codes: the share whose motion the style classifier gives a higher probability of
    ``target`` than before (``raised``), the share whose predicted action is unchanged (``kept``), and
    the mean probability of the target before and after."""

    direction: str
    target: str
    amount: float
    n: int
    raised: float
    kept: float
    before: float
    after: float


def _probabilities(classifier: Classifier, joints: np.ndarray, skeleton: Skeleton) -> np.ndarray:
    """(N, classes) softmax of the classifier on the centre windows of motions (N, T, J, 3)."""
    window = classifier.config.window
    if joints.shape[1] < window:
        raise ConfigError(f"motions have {joints.shape[1]} frames, the classifier reads {window}")
    start = (joints.shape[1] - window) // 2
    x = np.stack([canonicalize(m[start : start + window], skeleton)[0] for m in joints]).astype(np.float32)
    with torch.inference_mode():
        _, logits = classifier.net(torch.from_numpy(x.reshape(len(x), window, -1)), None)
    return torch.softmax(logits, dim=1).numpy()


def edit_effect(
    generator: FolderGenerator,
    codes: np.ndarray,
    actions: list[str | None],
    direction: str,
    amount: float,
    style_classifier: Classifier,
    action_classifier: Classifier,
) -> EditEffect:
    """The effect of moving ``codes`` (N, D) ``amount`` along ``direction`` ("style=NAME")."""
    key, _, target = direction.partition("=")
    if key != "style" or target not in style_classifier.action_names:
        known = ", ".join(f"style={s}" for s in style_classifier.action_names)
        raise ConfigError(f"{direction!r}: the style classifier knows {known}")
    if len(codes) != len(actions) or len(codes) == 0:
        raise ConfigError("give one action (or None) per code, and at least one code")
    column = style_classifier.action_names.index(target)
    before, after = [], []
    for code, action in zip(codes, actions, strict=True):
        [motion] = generator.decode(np.asarray(code, np.float32)[None], action)
        before.append(motion.joints)
        after.append(generator.edit(code, action, direction, amount).motion.joints)
    skeleton = generator.skeleton
    b, a = np.stack(before), np.stack(after)
    p_before, p_after = (_probabilities(style_classifier, x, skeleton)[:, column] for x in (b, a))
    act_before, act_after = (_probabilities(action_classifier, x, skeleton).argmax(1) for x in (b, a))
    return EditEffect(
        direction, target, float(amount), len(codes), float(np.mean(p_after > p_before)),
        float(np.mean(act_before == act_after)), float(p_before.mean()), float(p_after.mean()),
    )  # fmt: skip
