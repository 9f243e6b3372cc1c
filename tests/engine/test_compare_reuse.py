"""bench/compare.py reuses a saved evaluation only when it evaluated the same model the same way."""

from __future__ import annotations

import json
import os
from pathlib import Path
from types import SimpleNamespace

import pytest

import bench.compare
from bench.compare import _fresh_eval, engine_fingerprint

SETTINGS = {"repeats": 10, "n_per_action": 50, "seed": 0}


def _saved(tmp_path: Path, strategy: str) -> tuple[Path, Path]:
    """A model folder and an evaluation of it written after its weights, with ``strategy`` in its meta."""
    folder = tmp_path / "model"
    folder.mkdir()
    (folder / "model.safetensors").write_bytes(b"weights")
    saved = tmp_path / "eval_model_1.json"
    meta = SETTINGS | {"model": str(folder), "strategy": strategy, "classifier_test_accuracy": 0.96}
    meta["engine_fingerprint"] = engine_fingerprint()
    saved.write_text(json.dumps({"meta": meta}))
    later = (folder / "model.safetensors").stat().st_mtime + 10
    os.utime(saved, (later, later))
    return saved, folder


def test_a_kind_evaluated_with_its_own_strategy_is_reused_and_a_changed_one_is_not(tmp_path: Path) -> None:
    saved, folder = _saved(tmp_path, "prior")
    classifier = SimpleNamespace(test_accuracy=0.96)
    assert _fresh_eval(saved, folder, classifier, SETTINGS, None)  # the kind's own strategy: reused
    assert _fresh_eval(saved, folder, classifier, SETTINGS, "prior")
    assert not _fresh_eval(saved, folder, classifier, SETTINGS, "mode_preserving")
    assert not _fresh_eval(saved, folder, classifier, SETTINGS | {"seed": 1}, None)
    assert not _fresh_eval(saved, folder, SimpleNamespace(test_accuracy=0.9), SETTINGS, None)
    os.utime(folder / "model.safetensors", None)  # weights rewritten after the evaluation
    os.utime(saved, (0, 0))
    assert not _fresh_eval(saved, folder, classifier, SETTINGS, None)


def test_an_evaluation_made_by_other_engine_code_is_not_reused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "runs").mkdir()
    saved, folder = _saved(tmp_path / "runs", "prior")
    classifier = SimpleNamespace(test_accuracy=0.96)
    repo = tmp_path / "repo"
    (repo / "engine" / "motion").mkdir(parents=True)
    source = repo / "engine" / "motion" / "ik.py"
    source.write_text("RAMP = 3\n")
    monkeypatch.setattr(bench.compare, "REPO", repo)
    report = json.loads(saved.read_text())
    report["meta"]["engine_fingerprint"] = engine_fingerprint()
    saved.write_text(json.dumps(report))
    os.utime(saved, (os.stat(folder / "model.safetensors").st_mtime + 10,) * 2)
    assert _fresh_eval(saved, folder, classifier, SETTINGS, None)
    source.write_text("RAMP = 1\n")  # the clean-up changed after the evaluation
    assert not _fresh_eval(saved, folder, classifier, SETTINGS, None)
