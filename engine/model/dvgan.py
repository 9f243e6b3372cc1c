"""DVGAN (Lin & Amer 2018): text-conditioned motion GANs with a densely validating critic.

Motions are DVGAN features (``engine.model.dvgan_features``), normalised per feature. The action is a
phrase ("walk turn left") read word by word by a 2-layer LSTM language model, so a phrase never trained
on, made of known words, can be asked for.

- RNN generator (paper eq. 4): an initial frame from the plot of z_0, then per frame t a plot of z_t and
  the phrase, and a 2-layer LSTM that adds a difference to the previous frame. Seed frames (a prefix)
  replace the initial frame and warm the LSTM up: completion and continuation.
- CNN generator (eq. 5): from one frame, each level doubles the frame rate (residual upsampling) and adds
  the plot of its own noise z_i (2^i frames).
- Final cut: both generate 2N frames and a uniformly placed N-frame cut is the output.
- Critic (eq. 6): residual downsampling to one frame; a validation module (two size-1 convolutions
  matching the representation with the phrase) scores every frame of every level; the final score is a
  learned convex combination of the levels' mean scores. Inputs are shifted by up to ±N/2 frames and
  zero-padded (the paper's data augmentation). Trained as WGAN-GP.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import ClassVar

import torch
import torch.nn.functional as F  # noqa: N812
from torch import Tensor, nn

from engine.errors import ConfigError
from engine.model.config_base import ModelConfig

GENERATORS = ("rnn", "cnn")
#: How far past the training frames' range (a share of it) a generated feature may go.
RANGE_MARGIN = 0.1
DVGAN_TERMS = ("critic", "wasserstein", "gp", "generator", "total")


def phrase_words(phrase: str) -> list[str]:
    """The lower-case words of an action phrase ("walk-turn-left" → walk, turn, left)."""
    return [w for w in re.split(r"[\s_\-]+", phrase.lower()) if w]


@dataclass
class DvganConfig(ModelConfig):
    """Sizes, schedule and switches of one DVGAN model.

    The paper uses k = 256 everywhere, Adam 1e-4 and 10 critic updates per generator update for 20,000
    iterations; the defaults are sized for two CPU cores (k = 128, 5 critic updates). ``n_features``
    and ``words`` (the language model's vocabulary) come from the data when training starts (0 and
    empty until then); ``prefix_rate`` of the generator batches start from a real prefix of
    1..``max_prefix`` frames (the completion the RNN is trained for);
    ``foot_heights`` are the training data's resting foot heights (the decode-time foot clean-up).
    An epoch is ``epoch_size`` generated windows (``epoch_size / batch_size`` generator updates). With
    ``final_cut`` a generated window is cut from a tape of ``tape_windows`` windows (the paper's 2N):
    a longer tape makes the RNN keep a motion going past its first frames.
    """

    n_actions: int
    n_joints: int
    n_features: int = 0
    words: tuple[str, ...] = ()
    window: int = 32
    fps: float = 20.0
    generator: str = "rnn"
    hidden: int = 128
    noise_dim: int = 32
    final_cut: bool = True
    tape_windows: int = 2
    shift: bool = True
    critic_steps: int = 5
    gp_weight: float = 10.0
    lr: float = 1e-4
    batch_size: int = 64
    epoch_size: int = 3200
    epochs: int = 20
    prefix_rate: float = 0.5
    max_prefix: int = 24
    foot_heights: tuple[float, ...] = ()
    arch: str = "dvgan"

    POSITIVE = ("n_actions", "n_joints", "window", "fps", "hidden", "noise_dim")
    POSITIVE += ("critic_steps", "lr", "batch_size", "epoch_size", "max_prefix", "tape_windows")
    NON_NEGATIVE = ("n_features", "gp_weight", "epochs")
    RATES = ("prefix_rate",)
    CHOICES: ClassVar[dict[str, tuple[str, ...]]] = {"generator": GENERATORS}
    ARCH = "dvgan"

    def check(self) -> None:
        """A prefix shorter than the window; CNN windows a power of two."""
        if self.max_prefix >= self.window:
            raise ConfigError(f"max_prefix {self.max_prefix} must be shorter than the window {self.window}")
        if self.generator == "cnn" and self.tape & (self.tape - 1):
            raise ConfigError(
                f"the CNN generator needs a power-of-two tape, got {self.window} × {self.tape_windows} frames"
            )

    @property
    def tape(self) -> int:
        """Frames generated before the final cut."""
        return self.tape_windows * self.window if self.final_cut else self.window


class LanguageModel(nn.Module):
    """Word embeddings read by a 2-layer LSTM; a phrase's representation is its last hidden state."""

    def __init__(self, words: tuple[str, ...], hidden: int):
        super().__init__()
        self.words = list(words)
        self.embed = nn.Embedding(len(words) + 1, hidden, padding_idx=len(words))
        self.lstm = nn.LSTM(hidden, hidden, 2, batch_first=True)

    def tokens(self, phrases: list[str]) -> tuple[Tensor, Tensor]:
        """Word indices (P, L), padded, and lengths (P,) of phrases; ConfigError for an unknown word."""
        rows = []
        for phrase in phrases:
            words = phrase_words(phrase)
            unknown = [w for w in words if w not in self.words]
            if unknown or not words:
                raise ConfigError(
                    f"action {phrase!r}: {'unknown words ' + ', '.join(unknown) if unknown else 'no words'};"
                    f" the model knows {', '.join(self.words)}"
                )
            rows.append([self.words.index(w) for w in words])
        longest = max(len(r) for r in rows)
        device = self.embed.weight.device
        padded = torch.tensor([r + [len(self.words)] * (longest - len(r)) for r in rows], device=device)
        return padded, torch.tensor([len(r) for r in rows], device=device)

    def forward(self, phrases: list[str]) -> Tensor:
        """(P, hidden) representations of ``phrases``."""
        tokens, lengths = self.tokens(phrases)
        out, _ = self.lstm(self.embed(tokens))
        return out[torch.arange(len(phrases), device=out.device), lengths - 1]


class _Plot(nn.Module):
    """Linear{ReLU[Linear(z) + h_txt]}: what new motion the noise ``z`` brings, given the phrase."""

    def __init__(self, noise: int, hidden: int):
        super().__init__()
        self.inner = nn.Linear(noise, hidden)
        self.outer = nn.Linear(hidden, hidden)

    def forward(self, z: Tensor, text: Tensor) -> Tensor:
        """Plots (..., hidden) of noise (..., noise) and phrase representations broadcast to it."""
        return self.outer(F.relu(self.inner(z) + text))


class RnnGenerator(nn.Module):
    """Eq. 4: a_0 = Decode(InitialPlot(z_0)); a_t = a_{t-1} + Linear(LSTM_diff([Linear(a_{t-1}), p_t]))."""

    def __init__(self, config: DvganConfig):
        super().__init__()
        k, n = config.hidden, config.n_features
        self.config = config
        self.initial_plot = _Plot(config.noise_dim, k)
        self.first = nn.Linear(k, n)
        self.plot = _Plot(config.noise_dim, k)
        self.previous = nn.Linear(n, k)
        self.lstm = nn.LSTM(2 * k, k, 2, batch_first=True)
        self.diff = nn.Linear(k, n)

    def forward(
        self,
        text: Tensor,
        z0: Tensor,
        z: Tensor,
        bounds: tuple[Tensor, Tensor, Tensor],
        prefix: Tensor | None = None,
        state: tuple[Tensor, Tensor] | None = None,
    ) -> tuple[Tensor, tuple[Tensor, Tensor]]:
        """Frames (B, P + S, F): the ``prefix`` (B, P, F; or the initial frame of ``z0`` (B, noise)) and
        one generated frame per step of ``z`` (B, S, noise); and the LSTM state after them.

        ``bounds`` are (keep, low, high) (F,): generated frames are multiplied by ``keep``, which holds
        features constant in the data at zero, and clamped to [low, high], the training frames' range,
        so that no feature can drift away over thousands of frames.

        ``state`` continues an earlier call whose last frame is ``prefix``'s last (then only that
        frame is given)."""
        keep, low, high = bounds
        if prefix is None:
            prefix = torch.clamp(self.first(self.initial_plot(z0, text))[:, None] * keep, low, high)
        frames = [prefix]
        if prefix.shape[1] > 1:  # warm the LSTM up on the seed frames
            seed_plots = self.plot(z.new_zeros(len(z), prefix.shape[1] - 1, z.shape[2]), text[:, None])
            _, state = self.lstm(torch.cat([self.previous(prefix[:, :-1]), seed_plots], 2), state)
        plots = self.plot(z, text[:, None])
        last = prefix[:, -1:]
        for t in range(z.shape[1]):
            out, state = self.lstm(torch.cat([self.previous(last), plots[:, t : t + 1]], 2), state)
            last = torch.clamp(last + self.diff(out) * keep, low, high)
            frames.append(last)
        return torch.cat(frames, 1), state


class CnnGenerator(nn.Module):
    """Eq. 5: h_0 = Plot_0(z_0); h_i = Up(h_{i-1}) + Conv(ReLU{Up[Conv(h_{i-1})] + Plot_i(z_i)});
    A = Conv(h_L), L = log2 of the tape length."""

    def __init__(self, config: DvganConfig):
        super().__init__()
        k = config.hidden
        self.levels = int(math.log2(config.tape))
        self.plots = nn.ModuleList(_Plot(config.noise_dim, k) for _ in range(self.levels + 1))
        self.inner = nn.ModuleList(nn.Conv1d(k, k, 3, padding=1) for _ in range(self.levels))
        self.outer = nn.ModuleList(nn.Conv1d(k, k, 3, padding=1) for _ in range(self.levels))
        self.decode = nn.Conv1d(k, config.n_features, 1)

    def forward(self, text: Tensor, z0: Tensor, noise: list[Tensor]) -> Tensor:
        """Frames (B, 2^L, F) of the top code ``z0`` (B, noise) and finer ``noise`` [(B, 2^i, noise)]."""
        h = self.plots[0](z0, text)[:, :, None]  # (B, k, 1)
        for i in range(self.levels):
            up = F.interpolate(h, scale_factor=2.0, mode="nearest")
            inner = F.interpolate(self.inner[i](h), scale_factor=2.0, mode="nearest")
            plot = self.plots[i + 1](noise[i], text[:, None]).transpose(1, 2)
            h = up + self.outer[i](F.relu(inner + plot))
        return self.decode(h).transpose(1, 2)


class DvganNetwork(nn.Module):
    """The shipped network: language model, RNN or CNN generator, and the feature normalisation."""

    def __init__(self, config: DvganConfig, seed: int = 0):
        super().__init__()
        self.config = config
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.language = LanguageModel(config.words, config.hidden)
            self.net = RnnGenerator(config) if config.generator == "rnn" else CnnGenerator(config)
        self.register_buffer("mean", torch.zeros(config.n_features))
        self.register_buffer("std", torch.ones(config.n_features))
        self.register_buffer("keep", torch.ones(config.n_features))
        self.register_buffer("low", torch.full((config.n_features,), -10.0))
        self.register_buffer("high", torch.full((config.n_features,), 10.0))

    @torch.no_grad()
    def set_statistics(self, frames: Tensor) -> None:
        """Take the normalisation of unnormalised training frames (N, F); features constant in them (the
        rotations of joints without children) are held at their value (``keep`` 0: a critic would tell
        any generated wobble of them from the data at once); generated frames stay within the range of
        the normalised training frames, widened by ``RANGE_MARGIN`` of it on either side."""
        std = frames.std(0)
        varies = std > 1e-4
        self.mean.copy_(frames.mean(0))
        self.std.copy_(torch.where(varies, std, torch.ones_like(std)))
        self.keep.copy_(varies.float())
        x = self.normalise(frames)
        low, high = x.min(0).values, x.max(0).values
        margin = RANGE_MARGIN * (high - low)
        self.low.copy_(low - margin)
        self.high.copy_(high + margin)

    @property
    def bounds(self) -> tuple[Tensor, Tensor, Tensor]:
        """(keep, low, high): what generated frames are held to (``set_statistics``)."""
        return self.keep, self.low, self.high

    def normalise(self, raw: Tensor) -> Tensor:
        """Network features of unnormalised ones (..., F)."""
        return (raw - self.mean) / self.std

    def denormalise(self, x: Tensor) -> Tensor:
        """Unnormalised features of network ones (..., F)."""
        return x * self.std + self.mean

    def noise(self, n: int, frames: int, generator: torch.Generator | None) -> list[Tensor]:
        """The finer noise of ``n`` motions of ``frames`` generated frames: per frame (RNN, one tensor
        (n, frames, noise)) or per level (CNN)."""
        device = self.mean.device
        dim = self.config.noise_dim
        if self.config.generator == "rnn":
            return [torch.randn(n, frames, dim, generator=generator, device=device)]
        return [
            torch.randn(n, 2**i, dim, generator=generator, device=device)
            for i in range(1, self.net.levels + 1)
        ]

    def tape(self, text: Tensor, z0: Tensor, noise: list[Tensor]) -> Tensor:
        """Network frames (B, tape, F) of phrase representations (B, hidden), top codes and finer noise."""
        if self.config.generator == "rnn":
            frames, _ = self.net(text, z0, noise[0][:, : self.config.tape - 1], self.bounds)
            return frames
        return torch.clamp(self.net(text, z0, noise) * self.keep, self.low, self.high)

    def rnn(
        self,
        text: Tensor,
        z0: Tensor,
        z: Tensor,
        prefix: Tensor | None = None,
        state: tuple[Tensor, Tensor] | None = None,
    ) -> tuple[Tensor, tuple[Tensor, Tensor]]:
        """The RNN generator's frames and state (``RnnGenerator.forward``) with the constant features held."""
        return self.net(text, z0, z, self.bounds, prefix=prefix, state=state)


class DenseCritic(nn.Module):
    """Eq. 6 with the data augmentation: the critic of (B, N, F) network frames under phrase texts."""

    def __init__(self, config: DvganConfig, seed: int = 1):
        super().__init__()
        k, n = config.hidden, config.n_features
        self.config = config
        self.levels = max(1, math.ceil(math.log2(config.window)))
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.language = LanguageModel(config.words, k)
            self.encode = nn.Conv1d(n, k, 1)
            self.inner = nn.ModuleList(nn.Conv1d(k, k, 3, padding=1) for _ in range(self.levels))
            self.outer = nn.ModuleList(nn.Conv1d(k, k, 3, padding=1) for _ in range(self.levels))
            self.valid_in = nn.ModuleList(nn.Conv1d(k, k, 1) for _ in range(self.levels + 1))
            self.valid_text = nn.ModuleList(nn.Linear(k, k) for _ in range(self.levels + 1))
            self.valid_out = nn.ModuleList(nn.Conv1d(k, 1, 1) for _ in range(self.levels + 1))
            self.level_weights = nn.Parameter(torch.zeros(self.levels + 1))

    def _validate(self, i: int, h: Tensor, text: Tensor) -> Tensor:
        """Mean over frames of level ``i``'s validation scores (B,)."""
        inner = self.valid_in[i](h) + self.valid_text[i](text)[:, :, None]
        return self.valid_out[i](F.relu(inner)).mean(dim=(1, 2))

    def forward(self, frames: Tensor, text: Tensor) -> Tensor:
        """Scores (B,) of frames (B, N, F) under phrase representations (B, hidden)."""
        h = self.encode(frames.transpose(1, 2))
        scores = [self._validate(0, h, text)]
        for i in range(self.levels):
            h = _halve(h) + self.outer[i](F.relu(_halve(self.inner[i](h))))
            scores.append(self._validate(i + 1, h, text))
        return (torch.stack(scores, 1) * torch.softmax(self.level_weights, 0)).sum(1)


def _halve(h: Tensor) -> Tensor:
    """(B, C, ⌈L/2⌉): the means of frame pairs of (B, C, L), an odd last frame paired with itself."""
    if h.shape[-1] % 2:
        h = torch.cat([h, h[..., -1:]], -1)
    return h.unflatten(-1, (h.shape[-1] // 2, 2)).mean(-1)


def shifted(frames: Tensor, generator: torch.Generator | None) -> Tensor:
    """Each window (B, N, F) shifted by a uniform whole number of frames in [−N/2, N/2], the frames
    shifted in from outside zero (the paper's translation-invariance augmentation)."""
    b, n, _ = frames.shape
    shift = torch.randint(-(n // 2), n // 2 + 1, (b, 1), generator=generator, device=frames.device)
    source = torch.arange(n, device=frames.device)[None] - shift
    inside = (source >= 0) & (source < n)
    gathered = torch.gather(frames, 1, source.clamp(0, n - 1)[:, :, None].expand(-1, -1, frames.shape[2]))
    return gathered * inside[:, :, None]


def final_cut(tape: Tensor, window: int, generator: torch.Generator | None) -> Tensor:
    """A uniformly placed ``window``-frame cut (B, window, F) of each tape (B, L, F)."""
    b, length, f = tape.shape
    start = torch.randint(0, length - window + 1, (b, 1), generator=generator, device=tape.device)
    index = start + torch.arange(window, device=tape.device)[None]
    return torch.gather(tape, 1, index[:, :, None].expand(-1, -1, f))


def gradient_penalty(
    critic: DenseCritic, real: Tensor, fake: Tensor, text: Tensor, generator: torch.Generator | None
) -> Tensor:
    """WGAN-GP's (‖∇ D(x̂)‖₂ − 1)² at random points x̂ between real and generated windows."""
    alpha = torch.rand(len(real), 1, 1, generator=generator, device=real.device)
    mixed = (alpha * real + (1 - alpha) * fake).requires_grad_(True)
    (grad,) = torch.autograd.grad(critic(mixed, text).sum(), mixed, create_graph=True)
    return ((grad.flatten(1).norm(dim=1) - 1.0) ** 2).mean()
