"""The shared epoch loop on a toy kind with two optimisers (a GAN's shape): log, resume, cancel, identity."""

from __future__ import annotations

import csv
import dataclasses
import io
from pathlib import Path

import numpy as np
import pytest
import torch

from engine.errors import CancelledError, ModelFormatError
from engine.model.config_base import ModelConfig
from engine.train.checkpoint import checkpoint_path
from engine.train.epochs import TrainProgress, run_epochs, run_identity


@dataclasses.dataclass
class ToyConfig(ModelConfig):
    """A config for the toy kind."""

    lr: float = 0.05
    epochs: int = 4
    arch: str = "toy"
    POSITIVE = ("lr", "epochs")
    ARCH = "toy"


class ToySteps:
    """Two linear maps fitted to y = 3x by two optimisers, one per map, like a GAN's G and D."""

    terms = ("a", "b", "total")
    windows_per_step = 8

    def __init__(self, lr: float = 0.05) -> None:
        torch.manual_seed(0)
        self.modules = torch.nn.ModuleDict({"g": torch.nn.Linear(1, 1), "d": torch.nn.Linear(1, 1)})
        self.optimizers = (
            torch.optim.Adam(self.modules["g"].parameters(), lr=lr),
            torch.optim.SGD(self.modules["d"].parameters(), lr=lr, momentum=0.9),
        )
        self.steps_seen = 0

    def _losses(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        a = ((self.modules["g"](x) - 3 * x) ** 2).mean()
        b = ((self.modules["d"](x) - 3 * x) ** 2).mean()
        return {"a": a, "b": b, "total": a + b}

    def step(self, epoch: int, rng: np.random.Generator, generator: torch.Generator) -> dict[str, float]:
        x = torch.from_numpy(rng.normal(size=(8, 1)).astype(np.float32))
        x = x + 0.01 * torch.randn(x.shape, generator=generator)
        terms = self._losses(x)
        for optimizer in self.optimizers:
            optimizer.zero_grad()
        terms["total"].backward()
        for optimizer in self.optimizers:
            optimizer.step()
        self.steps_seen += 1
        return {k: float(v.detach()) for k, v in terms.items()}

    def validate(self) -> dict[str, float] | None:
        with torch.no_grad():
            return {k: float(v) for k, v in self._losses(torch.linspace(-1, 1, 5)[:, None]).items()}

    def epoch_columns(self, epoch: int) -> dict[str, float]:
        return {"epoch_squared": float(epoch * epoch)}


def _run(out: Path, steps: ToySteps, config: ToyConfig, **kw) -> object:
    identity = run_identity(config, "data", 0, 0.1)
    return run_epochs(
        steps,
        out,
        config,
        identity,
        epochs=config.epochs,
        steps_per_epoch=5,
        rng=np.random.default_rng(0),
        generator=torch.Generator().manual_seed(0),
        **kw,
    )


def _weights(steps: ToySteps) -> np.ndarray:
    return np.concatenate([p.detach().numpy().ravel() for p in steps.modules.parameters()])


def test_the_loop_logs_every_term_and_epoch_column_and_lowers_the_losses(tmp_path: Path) -> None:
    reports: list[TrainProgress] = []
    run = _run(tmp_path, ToySteps(), ToyConfig(), progress=reports.append)
    rows = list(csv.DictReader(io.StringIO((tmp_path / "train_log.csv").read_text())))
    assert [int(r["epoch"]) for r in rows] == [1, 2, 3, 4]
    assert list(rows[0])[:2] == ["epoch", "epoch_squared"]
    assert [float(r["epoch_squared"]) for r in rows] == [0, 1, 4, 9]
    for term in ("a", "b", "total"):
        assert float(rows[-1][f"train_{term}"]) < float(rows[0][f"train_{term}"])
        assert np.isfinite(float(rows[-1][f"val_{term}"]))
    assert len(reports) == 20 and reports[-1].fraction == 1.0 and reports[-1].step == 5
    assert reports[-1].windows_per_s == pytest.approx(8 * reports[-1].steps_per_s)
    assert run.train_losses["total"] == pytest.approx(float(rows[-1]["train_total"]))


def test_cancel_then_resume_gives_the_uninterrupted_weights_for_both_optimisers(tmp_path: Path) -> None:
    straight = ToySteps()
    _run(tmp_path / "straight", straight, ToyConfig())

    calls = {"n": 0}

    def cancel_in_epoch_3() -> bool:
        calls["n"] += 1
        return calls["n"] > 12  # epochs 1-2 (10 steps) and 2 steps of epoch 3

    interrupted = tmp_path / "interrupted"
    with pytest.raises(CancelledError, match="epoch 3"):
        _run(interrupted, ToySteps(), ToyConfig(), cancel=cancel_in_epoch_3, checkpoint_every=2)
    assert checkpoint_path(interrupted).is_file()
    resumed = ToySteps()
    run = _run(interrupted, resumed, ToyConfig(), resume=True)
    assert resumed.steps_seen == 10  # epochs 3 and 4 only
    np.testing.assert_array_equal(_weights(resumed), _weights(straight))
    assert [r["epoch"] for r in run.rows] == [1, 2, 3, 4]


def test_resume_refuses_a_checkpoint_of_another_config(tmp_path: Path) -> None:
    _run(tmp_path, ToySteps(), ToyConfig())
    with pytest.raises(ModelFormatError, match="different config"):
        _run(tmp_path, ToySteps(0.1), ToyConfig(lr=0.1), resume=True)
    # another epoch count is the same run, extended
    run = _run(tmp_path, ToySteps(), ToyConfig(epochs=6), resume=True)
    assert len(run.rows) == 6


def test_a_checkpoint_with_the_wrong_number_of_optimisers_is_refused(tmp_path: Path) -> None:
    _run(tmp_path, ToySteps(), ToyConfig())
    one = ToySteps()
    one.optimizers = one.optimizers[:1]
    with pytest.raises(ModelFormatError, match="2 optimiser states for 1"):
        _run(tmp_path, one, ToyConfig(epochs=5), resume=True)


def test_a_checkpoint_written_before_optimisers_were_a_list_still_resumes(tmp_path: Path) -> None:
    one = ToySteps()
    one.optimizers = one.optimizers[:1]
    _run(tmp_path, one, ToyConfig(epochs=2))
    payload = torch.load(checkpoint_path(tmp_path), weights_only=True)
    payload["optimizer"] = payload.pop("optimizers")[0]  # the layout of checkpoints until this change
    torch.save(payload, checkpoint_path(tmp_path))
    again = ToySteps()
    again.optimizers = again.optimizers[:1]
    run = _run(tmp_path, again, ToyConfig(epochs=3), resume=True)
    assert again.steps_seen == 5 and len(run.rows) == 3
    assert again.optimizers[0].state_dict()["state"][0]["step"] == 15  # Adam's count carried over


def test_select_keeps_the_best_scoring_epoch_across_a_resume(tmp_path: Path) -> None:
    """A score that peaks at epoch 3 of 6 (checked every epoch): the modules end with the weights they
    had after epoch 3 (those of a plain 3-epoch run), the log has the scores, and a run stopped after
    epoch 4 and resumed still ends on epoch 3's weights."""
    plain = ToySteps()
    _run(tmp_path / "plain", plain, ToyConfig(epochs=3))
    peak = {1: 0.1, 2: 0.5, 3: 0.9, 4: 0.2, 5: 0.3, 6: 0.8}

    def scorer(steps: ToySteps) -> object:
        return lambda: peak[steps.steps_seen // 5]

    chosen = ToySteps()
    run = _run(tmp_path / "chosen", chosen, ToyConfig(epochs=6), checkpoint_every=1, select=scorer(chosen))
    assert run.selected_epoch == 3
    np.testing.assert_array_equal(_weights(chosen), _weights(plain))
    rows = list(csv.DictReader(io.StringIO((tmp_path / "chosen" / "train_log.csv").read_text())))
    assert [float(r["select_score"]) for r in rows] == [peak[e] for e in range(1, 7)]

    first = ToySteps()
    _run(tmp_path / "split", first, ToyConfig(epochs=4), checkpoint_every=1, select=scorer(first))
    later = ToySteps()
    later.steps_seen = 20
    resumed = _run(
        tmp_path / "split", later, ToyConfig(epochs=6), checkpoint_every=1, select=scorer(later), resume=True
    )
    assert resumed.selected_epoch == 3
    np.testing.assert_array_equal(_weights(later), _weights(plain))
