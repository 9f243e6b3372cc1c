"""The bundled model's card names every departure from the paper that its config makes."""

from __future__ import annotations

import re
from pathlib import Path

from bench import train_modi
from bench.model_card import card_argv, training_argv, training_command
from bench.train_default import model_switches
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


def test_a_card_made_later_from_a_trained_folder_shows_the_training_command(tmp_path: Path) -> None:
    """A --skip-train card evaluated on other options (here one thread where training took two) shows the
    command the training recorded; a folder whose training recorded none shows this run's."""
    trained = ["--data", "/home/me/bandai", "--work", str(tmp_path), "--epochs", "100", "--threads", "2"]
    expected = "python bench/train_dvgan.py --data DATA --epochs 100 --threads 2"
    assert training_command("bench/train_dvgan.py", tmp_path, trained, trained=True) == expected
    later = ["--data", "/mnt/other", "--work", str(tmp_path), "--skip-train", "--threads", "1"]
    assert training_command("bench/train_dvgan.py", tmp_path, later, trained=False) == expected
    fresh = tmp_path / "older"
    fresh.mkdir()
    assert (
        training_command("bench/x.py", fresh, later, trained=False)
        == "python bench/x.py --data DATA --threads 1"
    )


def test_a_modi_card_made_later_reads_the_training_threads_from_the_recorded_command(tmp_path: Path) -> None:
    """The MoDi card's budget names the threads the training ran on, not the re-evaluation's."""
    trained = ["--data", "/home/me/bandai", "--work", str(tmp_path), "--epochs", "160", "--threads", "2"]
    training_argv(tmp_path, trained, trained=True)
    later = ["--data", "/mnt/other", "--work", str(tmp_path), "--skip-train", "--threads", "1"]
    assert train_modi.parse_args(training_argv(tmp_path, later, trained=False)).threads == 2
    unrecorded = tmp_path / "older"
    unrecorded.mkdir()
    assert train_modi.parse_args(training_argv(unrecorded, ["--data", "D"], trained=False)).threads == 1
