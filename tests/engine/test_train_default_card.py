"""The bundled model's card names every departure from the paper that its config makes."""

from __future__ import annotations

import re
from pathlib import Path

from bench.train_default import card_argv, model_switches
from engine.model.config import PAPER, OdmoConfig


def test_the_card_names_a_heavier_root_height_only_when_the_config_has_one() -> None:
    plain = model_switches(OdmoConfig(n_actions=3, n_joints=5))
    heavier = model_switches(OdmoConfig(n_actions=3, n_joints=5, traj_y_weight=5.0))
    assert "traj_y_weight" not in plain
    assert "`traj_y_weight = 5`" in heavier
    assert re.findall(r"`(\w+)", plain) == [n for n in re.findall(r"`(\w+)", heavier) if n != "traj_y_weight"]


def test_the_card_names_every_project_loss_weight_the_config_turns_on() -> None:
    added = [name for name in PAPER if name.startswith("w_")]
    assert "w_stance" in added
    for name in added:
        on = OdmoConfig(n_actions=3, n_joints=5, foot_joints=(3, 4), foot_heights=(0.0, 0.0), **{name: 2.5})
        assert f"`{name} = 2.5`" in model_switches(on), name


def test_the_card_command_leaves_out_where_files_go_and_the_data_path() -> None:
    argv = ["--data", "/home/me/bandai", "--work", "runs/w", "--out=resources/x", "--skip-train"]
    argv += ["--reuse-eval", "--no-results", "--epochs", "100", "--threads", "2"]
    assert card_argv(argv) == ["--data", "DATA", "--epochs", "100", "--threads", "2"]


def test_the_card_command_names_a_warm_start_by_its_place_in_the_repository() -> None:
    inside = str(Path(__file__).resolve().parents[2] / "resources" / "models" / "bandai2-odmo")
    argv = ["--data", "/home/me/bandai", "--warm-start", inside, "--weight", "w_skim=1"]
    assert card_argv(argv) == [
        "--data",
        "DATA",
        "--warm-start",
        "resources/models/bandai2-odmo",
        "--weight",
        "w_skim=1",
    ]
    assert card_argv(["--warm-start", "/elsewhere/runs/stage1"]) == ["--warm-start", "stage1"]
