"""KindRun, what every kind's training shares: the size check, the split, and the provenance it records."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.model.a2m import A2mConfig
from engine.model.config import OdmoConfig
from engine.motion.motion import Motion
from engine.train.kind_run import KindRun, RunOptions
from engine.train.pairs import split_clips
from tests.engine.test_epochs import ToySteps

ACTIONS = ["walk", "wave", "jump"]


def test_a_config_of_other_sizes_is_refused_naming_both(procedural_clips: list[Motion]) -> None:
    joints = procedural_clips[0].skeleton.n_joints
    config = OdmoConfig(n_actions=4, n_joints=joints)
    with pytest.raises(
        ConfigError, match=f"config has 4 actions and {joints} joints, data has 3 and {joints}"
    ):
        KindRun.prepare(procedural_clips, ACTIONS, config, RunOptions())


def test_the_split_and_provenance_are_the_runs(tmp_path, procedural_clips: list[Motion]) -> None:
    skeleton = procedural_clips[0].skeleton
    config = A2mConfig(n_actions=3, n_joints=skeleton.n_joints, epochs=2, epoch_size=64, batch_size=16)
    data = KindRun.prepare(procedural_clips, ACTIONS, config, RunOptions(seed=3, val_fraction=0.25))
    expected = split_clips(data.prepared.actions, 0.25, 3)
    np.testing.assert_array_equal(data.train_idx, expected[0])
    np.testing.assert_array_equal(data.val_idx, expected[1])
    assert data.device.type == "cpu"
    run = data.train(ToySteps(), tmp_path, config)
    assert len(run.rows) == 2 and (tmp_path / "train_log.csv").is_file()
    made = data.provenance(run, config, steps=7)
    assert made["arch"] == "a2m" and made["steps"] == 7 and made["seed"] == 3
    assert made["windows_seen"] == 2 * 4 * 16  # epochs × steps of an epoch × batch
    assert made["n_train"] + made["n_val"] == len(procedural_clips) == made["n_clips"]
    sources = [c.meta["source"] for c in procedural_clips]
    assert made["train_sources"] == [sources[i] for i in expected[0]]
    result = data.result(tmp_path, config, run, None)
    assert (result.n_train, result.n_val, result.epochs) == (len(expected[0]), len(expected[1]), 2)
