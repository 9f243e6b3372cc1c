"""The evaluation classifier: a GRU over canonical pose windows (Action2Motion / ODMO), training, files.

Two GRU layers (128 hidden) read the flattened joint positions of a window; a 30-d tanh feature layer
feeds the output layer. The features are what FID, diversity and multimodality are computed on. Unlike
the reference, the initial hidden state is zero, so the same input always gives the same output.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import safetensors.torch
import torch
from torch import nn

from engine.errors import CancelledError, ConfigError, DataError, ModelFormatError
from engine.fileio import atomic_write_bytes, atomic_write_text
from engine.metrics.accuracy import recognition_accuracy
from engine.motion.motion import Motion
from engine.train.epochs import cosine_lr
from engine.train.pairs import split_clips
from engine.train.windows import PreparedClips, every_window, prepare_clips, windows_at

log = logging.getLogger(__name__)

FORMAT = "odmo-classifier"
FORMAT_VERSION = 1
WEIGHTS_FILE = "classifier.safetensors"
META_FILE = "classifier.json"

Progress = Callable[[str, float], None]


@dataclass
class ClassifierConfig:
    """Sizes and training schedule of the evaluation classifier (saved in classifier.json)."""

    n_actions: int
    n_joints: int
    window: int = 60
    fps: float = 20.0
    hidden: int = 128
    layers: int = 2
    feature_dim: int = 30
    lr: float = 1e-3
    batch_size: int = 64
    epochs: int = 60
    stride: int = 10
    lr_floor: float = 0.05  # the learning rate falls along a cosine to lr · lr_floor (1: constant)

    def __post_init__(self) -> None:
        self.fps = float(self.fps)
        for name in ("n_actions", "n_joints", "window", "fps", "hidden", "layers", "feature_dim", "lr"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"classifier {name} must be positive, got {getattr(self, name)!r}")
        if self.stride < 1:
            raise ConfigError(f"classifier stride must be at least 1, got {self.stride}")
        if self.batch_size < 1 or self.epochs < 0:
            raise ConfigError(f"need batch_size >= 1 and epochs >= 0, got {self.batch_size}, {self.epochs}")

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ClassifierConfig:
        """Config from a dict; ModelFormatError on unknown or missing keys."""
        d = {"lr_floor": 1.0} | d  # classifiers saved before the schedule existed trained at a constant rate
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ModelFormatError(f"unknown classifier config keys: {', '.join(unknown)}")
        try:
            return cls(**d)
        except TypeError as exc:
            raise ModelFormatError(f"bad classifier config: {exc}") from None


class MotionClassifier(nn.Module):
    """GRU action classifier; input (B, T, J·3) canonical joint positions in metres."""

    def __init__(self, config: ClassifierConfig):
        super().__init__()
        self.gru = nn.GRU(config.n_joints * 3, config.hidden, config.layers, batch_first=True)
        self.feature = nn.Linear(config.hidden, config.feature_dim)
        self.out = nn.Linear(config.feature_dim, config.n_actions)

    def forward(
        self, x: torch.Tensor, lengths: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Features (B, F) and logits (B, C) read at each window's last valid frame (``lengths`` (B,))."""
        hidden, _ = self.gru(x)  # zero initial state
        if lengths is None:
            last = hidden[:, -1]
        else:
            last = hidden[torch.arange(len(x), device=x.device), lengths.to(x.device) - 1]
        features = torch.tanh(self.feature(last))
        return features, self.out(features)


def build_net(config: ClassifierConfig, generator: torch.Generator | None = None) -> MotionClassifier:
    """A classifier network; weights drawn like torch's defaults from ``generator`` (else left empty)."""
    with torch.device("meta"):  # construction never draws from torch's global RNG
        net = MotionClassifier(config)
    net.to_empty(device="cpu")
    if generator is not None:
        _init_weights(net, generator)
    return net


def _init_weights(net: nn.Module, generator: torch.Generator) -> None:
    """PyTorch's default uniform(±1/√fan_in) initialisation, drawn from ``generator``."""
    with torch.no_grad():
        for module in net.modules():
            if isinstance(module, nn.GRU):
                bound = 1.0 / math.sqrt(module.hidden_size)
                for p in module.parameters():
                    p.uniform_(-bound, bound, generator=generator)
            elif isinstance(module, nn.Linear):
                bound = 1.0 / math.sqrt(module.in_features)
                for p in module.parameters():
                    p.uniform_(-bound, bound, generator=generator)


@dataclass(eq=False)
class Classifier:
    """A trained evaluation classifier (CPU, eval mode) with what it was trained on."""

    net: MotionClassifier
    config: ClassifierConfig
    action_names: list[str]
    skeleton_names: tuple[str, ...]
    test_accuracy: float
    n_test: int
    path: Path | None = None
    test_accuracy_per_action: dict[str, float] = dataclasses.field(default_factory=dict)
    n_test_windows: int = 0

    def classify(
        self, windows: np.ndarray, mask: np.ndarray | None = None, batch: int = 512
    ) -> tuple[np.ndarray, np.ndarray]:
        """Features (N, F) float64 and predicted actions (N,) of windows (N, T, J, 3), mask (N, T)."""
        windows = np.asarray(windows, dtype=np.float32)
        if windows.ndim != 4 or windows.shape[2:] != (self.config.n_joints, 3):
            raise ConfigError(f"windows must be (N, T, {self.config.n_joints}, 3), got {windows.shape}")
        lengths = None if mask is None else np.maximum(np.asarray(mask, bool).sum(axis=1), 1)
        feats, preds = [], []
        with torch.inference_mode():
            for start in range(0, len(windows), batch):
                x = torch.from_numpy(
                    windows[start : start + batch].reshape(-1, windows.shape[1], self.n_inputs)
                )
                n = None if lengths is None else torch.from_numpy(lengths[start : start + batch])
                f, logits = self.net(x, n)
                feats.append(f.numpy().astype(np.float64))
                preds.append(logits.argmax(dim=1).numpy())
        if not feats:
            return np.zeros((0, self.config.feature_dim)), np.zeros(0, dtype=np.int64)
        return np.concatenate(feats), np.concatenate(preds)

    @property
    def n_inputs(self) -> int:
        """Values per frame, J·3."""
        return self.config.n_joints * 3


def held_out_accuracy(
    clf: Classifier, prepared: PreparedClips, indices: np.ndarray
) -> tuple[float, dict[str, float], int]:
    """Accuracy over every window (the classifier's stride) of clips ``indices``, per action, and the
    number of windows (nan and {} when there are none)."""
    rows = every_window(prepared, indices, clf.config.stride)
    if len(rows) == 0:
        return float("nan"), {}, 0
    batch = windows_at(prepared, rows[:, 0], rows[:, 1])
    _, pred = clf.classify(batch.joints, batch.mask)
    labels = np.asarray(batch.actions)
    per_action = {
        prepared.action_names[int(a)]: recognition_accuracy(pred[labels == a], labels[labels == a])
        for a in np.unique(labels)
    }
    return recognition_accuracy(pred, labels), per_action, len(rows)


def train_classifier(
    clips: Sequence[Motion],
    action_names: list[str],
    out_dir: str | Path,
    *,
    window: int = 60,
    fps: float = 20.0,
    epochs: int = 60,
    batch_size: int = 64,
    stride: int = 10,
    lr_floor: float = 0.05,
    seed: int = 0,
    val_fraction: float = 0.2,
    progress: Progress | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Classifier:
    """Train the classifier on every window (starts ``stride`` frames apart) of the training clips, each
    epoch in a new order, the learning rate falling along a cosine to ``lr_floor`` (5 %) of it; measure it
    on every window of the held-out clips; save it to ``out_dir``."""
    if not clips:
        raise DataError("no clips to train the classifier on")
    if not 0.0 <= val_fraction < 1.0:
        raise ConfigError(f"val_fraction must be in [0, 1), got {val_fraction}")
    skeleton = clips[0].skeleton
    config = ClassifierConfig(
        len(action_names),
        skeleton.n_joints,
        window=window,
        fps=fps,
        batch_size=batch_size,
        epochs=epochs,
        stride=stride,
        lr_floor=lr_floor,
    )
    prepared = prepare_clips(clips, action_names, fps, window)
    train_idx, held_idx = split_clips(prepared.actions, val_fraction, seed)
    rows = every_window(prepared, train_idx, stride)
    rng = np.random.default_rng(seed)
    net = build_net(config, torch.Generator().manual_seed(seed))
    clf = Classifier(net, config, list(action_names), tuple(skeleton.names), float("nan"), len(held_idx))
    optimiser = torch.optim.Adam(net.parameters(), lr=config.lr)
    for epoch in range(epochs):
        for group in optimiser.param_groups:
            group["lr"] = cosine_lr(config.lr, epoch, epochs, config.lr_floor)
        net.train()
        order = rows[rng.permutation(len(rows))]
        total = 0.0
        for start in range(0, len(order), config.batch_size):
            if cancel is not None and cancel():
                raise CancelledError("classifier training cancelled")
            part = order[start : start + config.batch_size]
            batch = windows_at(prepared, part[:, 0], part[:, 1])
            x = torch.from_numpy(np.asarray(batch.joints, np.float32).reshape(len(part), window, -1))
            lengths = torch.from_numpy(np.maximum(np.asarray(batch.mask, bool).sum(axis=1), 1))
            _, logits = net(x, lengths)
            loss = nn.functional.cross_entropy(
                logits, torch.as_tensor(np.asarray(batch.actions), dtype=torch.long)
            )
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            total += loss.item() * len(part)
        net.eval()
        log.info("classifier epoch %d/%d: loss %.4f", epoch + 1, epochs, total / max(len(order), 1))
        if progress is not None:
            progress("training classifier", (epoch + 1) / max(epochs, 1))
    net.eval()
    clf.test_accuracy, clf.test_accuracy_per_action, clf.n_test_windows = held_out_accuracy(
        clf, prepared, held_idx
    )
    log.info(
        "classifier held-out accuracy %.4f on %d windows of %d clips",
        clf.test_accuracy,
        clf.n_test_windows,
        len(held_idx),
    )
    save_classifier(clf, out_dir)
    return clf


def save_classifier(clf: Classifier, out_dir: str | Path) -> None:
    """Write classifier.safetensors and classifier.json into ``out_dir`` (each atomically)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    tensors = {k: v.detach().cpu().contiguous() for k, v in clf.net.state_dict().items()}
    atomic_write_bytes(out / WEIGHTS_FILE, safetensors.torch.save(tensors))
    meta = {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "config": dataclasses.asdict(clf.config),
        "action_names": clf.action_names,
        "skeleton_names": list(clf.skeleton_names),
        "test_accuracy": None if math.isnan(clf.test_accuracy) else clf.test_accuracy,
        "n_test_clips": clf.n_test,
        "n_test_windows": clf.n_test_windows,
        "test_accuracy_per_action": clf.test_accuracy_per_action,
    }
    atomic_write_text(out / META_FILE, json.dumps(meta, indent=2) + "\n")
    clf.path = out


def load_classifier(clf_dir: str | Path) -> Classifier:
    """Read a classifier folder strictly; ModelFormatError on missing, corrupt, mismatched or newer files."""
    folder = Path(clf_dir)
    meta_path, weights_path = folder / META_FILE, folder / WEIGHTS_FILE
    for path in (meta_path, weights_path):
        if not path.is_file():
            raise ModelFormatError(f"{path}: missing (not a classifier folder?)")
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ModelFormatError(f"{meta_path}: not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise ModelFormatError(f"{meta_path}: not an {FORMAT} file")
    version = meta.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ModelFormatError(f"{meta_path}: format version {version!r} is newer than {FORMAT_VERSION}")
    try:
        config = ClassifierConfig.from_dict(meta["config"])
        actions = [str(a) for a in meta["action_names"]]
        skeleton = tuple(str(n) for n in meta["skeleton_names"])
        accuracy = meta["test_accuracy"]
        n_test = int(meta["n_test_clips"])
        n_windows = int(meta.get("n_test_windows", 0))
        per_action = {str(k): float(v) for k, v in dict(meta.get("test_accuracy_per_action", {})).items()}
    except (KeyError, TypeError, ValueError, ConfigError) as exc:
        raise ModelFormatError(f"{meta_path}: bad classifier description ({exc})") from None
    if len(actions) != config.n_actions or len(skeleton) != config.n_joints:
        raise ModelFormatError(f"{meta_path}: action or joint names disagree with the config")
    try:
        state = safetensors.torch.load_file(str(weights_path))
    except Exception as exc:  # safetensors raises its own error types for corrupt files
        raise ModelFormatError(f"{weights_path}: unreadable weights ({exc})") from None
    net = build_net(config)
    expected = net.state_dict()
    if set(state) != set(expected) or any(state[k].shape != expected[k].shape for k in expected):
        raise ModelFormatError(f"{weights_path}: weights do not match the classifier config")
    net.load_state_dict(state)
    net.eval()
    test_accuracy = float("nan") if accuracy is None else float(accuracy)
    return Classifier(net, config, actions, skeleton, test_accuracy, n_test, folder, per_action, n_windows)
