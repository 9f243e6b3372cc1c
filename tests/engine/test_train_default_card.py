"""The bundled model's card names every departure from the paper that its config makes."""

from __future__ import annotations

import re

from bench.train_default import model_switches
from engine.model.config import OdmoConfig


def test_the_card_names_a_heavier_root_height_only_when_the_config_has_one() -> None:
    plain = model_switches(OdmoConfig(n_actions=3, n_joints=5))
    heavier = model_switches(OdmoConfig(n_actions=3, n_joints=5, traj_y_weight=5.0))
    assert "traj_y_weight" not in plain
    assert "`traj_y_weight = 5`" in heavier
    assert re.findall(r"`(\w+)", plain) == [n for n in re.findall(r"`(\w+)", heavier) if n != "traj_y_weight"]
