"""bench/train_a2m.py --select: the classifier choosing the epoch is the run's own, and the card says so."""

from __future__ import annotations

from pathlib import Path

import torch

from bench.train_a2m import SELECT_CLASSIFIER, selected_line, selection_classifier
from engine.metrics.classifier import WEIGHTS_FILE, train_classifier
from engine.motion.motion import Motion
from tests.fixtures.procedural import PROCEDURAL_ACTIONS


def test_epochs_are_chosen_by_a_classifier_trained_once_with_another_seed(
    tmp_path: Path, procedural_clips: list[Motion]
) -> None:
    evaluation = train_classifier(
        procedural_clips, PROCEDURAL_ACTIONS, tmp_path / "evaluation", epochs=20, lr_floor=1.0, seed=0
    )
    judge = selection_classifier(tmp_path, procedural_clips, PROCEDURAL_ACTIONS, evaluation, seed=0)
    weights = tmp_path / SELECT_CLASSIFIER / WEIGHTS_FILE
    saved = weights.read_bytes()
    again = selection_classifier(tmp_path, procedural_clips, PROCEDURAL_ACTIONS, evaluation, seed=0)
    assert weights.read_bytes() == saved  # read back, not trained again
    assert again.test_accuracy == judge.test_accuracy
    assert judge.test_accuracy >= 0.75  # it learnt the three procedural actions (chance: 0.33)
    assert judge.config == evaluation.config  # the evaluation classifier's settings
    ours, theirs = judge.net.state_dict(), evaluation.net.state_dict()
    assert ours.keys() == theirs.keys()
    assert any(not torch.equal(ours[k], theirs[k]) for k in ours)


def test_the_card_names_what_chose_the_epoch_and_nothing_when_none_was_chosen() -> None:
    line = selected_line(40, 2500, {"samples": 50, "classifier_accuracy": 0.9612})
    assert len(line) == 1
    assert "epoch 40 of 2500" in line[0]
    assert "50 prior samples per action" in line[0]
    assert "0.961 on its validation windows" in line[0]
    assert "Neither a held-out clip nor the evaluation's classifier chooses the epoch" in line[0]
    assert selected_line(None, 2500, {"samples": 50, "classifier_accuracy": 0.96}) == []
