"""evaluate() on the tiny model and the `odmo train-classifier` / `odmo eval` commands."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import engine.cli
from engine.errors import ConfigError
from engine.generators.a2m import load_a2m
from engine.metrics.a2m_eval import evaluate_a2m
from engine.metrics.classifier import Classifier, train_classifier
from engine.metrics.evaluate import evaluate, evaluate_sets, reconstruction_metrics, report
from engine.modelio import load_model
from engine.motion.datasets import load_folder
from engine.motion.formats import write_motion
from engine.motion.motion import Motion
from engine.train.windows import crop_windows, prepare_clips
from tests.fixtures.procedural import PROCEDURAL_ACTIONS

REAL_KEYS = {
    "accuracy",
    "fid",
    "kid",
    "precision",
    "recall",
    "action_kl",
    "diversity",
    "multimodality",
    "apd",
    "n_apd",
}
MODEL_KEYS = {
    "mode_homogeneity",
    "style_nmi",
    "style_ari",
    "reconstruction_error_m",
    "reconstruction_accuracy",
}
CONTROL_KEYS = {"end_error_m", "end_error_pct", "control_accuracy"}
CONTROL_KEYS |= {"end_error_out_m", "end_error_out_pct", "control_accuracy_out"}
PHYSICS_KEYS = {"bone_length_cv", "foot_skate_m_s", "floor_penetration", "floor_depth_m", "float_share"}
PHYSICS_KEYS |= {"hand_speed_m_s", "hand_amplitude_m", "foot_speed_m_s", "foot_amplitude_m", "jerk_m_s3"}
PHYSICS_KEYS |= {
    "late_hand_speed_m_s",
    "joint_range_excess",
    "foot_pop_m_s",
    "pelvis_height_m",
    "hand_rhythm_hz",
}
# heading_error_deg and torso_twist_deg need two leg chains (hip, knee, foot), which the procedural
# stick figure lacks


@pytest.fixture(scope="module")
def classifier(tmp_path_factory: pytest.TempPathFactory, procedural_clips: list[Motion]) -> Classifier:
    """A briefly trained classifier (its quality does not matter here)."""
    out = tmp_path_factory.mktemp("eval_classifier")
    return train_classifier(procedural_clips, PROCEDURAL_ACTIONS, out, epochs=2, batch_size=16, seed=0)


def test_evaluate_returns_every_metric_finite(
    tiny_model_dir: Path, procedural_clips: list[Motion], classifier: Classifier
) -> None:
    loaded = load_model(tiny_model_dir)
    result = evaluate(loaded, procedural_clips, classifier, repeats=2, n_per_action=10, seed=3)
    assert set(result["real"]) == REAL_KEYS | PHYSICS_KEYS
    assert set(result["generated"]) == REAL_KEYS | MODEL_KEYS | CONTROL_KEYS | PHYSICS_KEYS
    # the procedural clips have rigid bones; walks and waves keep their feet on the floor (squats sink)
    assert result["real"]["bone_length_cv"]["mean"] < 1e-4
    assert set(result["per_action"]) == set(PROCEDURAL_ACTIONS)
    for action in ("walk", "wave"):
        assert result["per_action"][action]["real"]["floor_penetration"]["mean"] == 0.0
        assert result["per_action"][action]["real"]["float_share"]["mean"] == 0.0
    assert result["per_action"]["jump"]["real"]["floor_penetration"]["mean"] > 0.0
    wave = result["per_action"]["wave"]["real"]
    assert (
        wave["hand_speed_m_s"]["mean"] > result["per_action"]["jump"]["real"]["foot_speed_m_s"]["mean"] / 10
    )
    for column in ("real", "generated"):
        for name, cell in result[column].items():
            assert math.isfinite(cell["mean"]) and math.isfinite(cell["ci95"]) and cell["ci95"] >= 0, name
    gen = result["generated"]
    assert 0.0 <= gen["accuracy"]["mean"] <= 1.0 and 0.0 <= result["real"]["accuracy"]["mean"] <= 1.0
    assert gen["end_error_m"]["mean"] > 0 and gen["reconstruction_error_m"]["mean"] > 0
    assert result["meta"]["repeats"] == 2 and result["meta"]["actions"] == PROCEDURAL_ACTIONS
    # the same number of motions per action: the set's accuracy is the mean of the per-action ones
    for side in ("real", "generated"):
        by_action = [result["per_action"][a][side]["accuracy"]["mean"] for a in PROCEDURAL_ACTIONS]
        assert result[side]["accuracy"]["mean"] == pytest.approx(np.mean(by_action))
    # reconstruction runs on the tiny model's validation clips only (its bank marks the training ones)
    assert result["meta"]["reconstruction_held_out"]
    assert 0 < result["meta"]["n_reconstruction_clips"] < len(procedural_clips)
    again = evaluate(loaded, procedural_clips, classifier, repeats=2, n_per_action=10, seed=3)
    assert again["generated"] == result["generated"] and again["real"] == result["real"]
    # two real sets drawn from the same clips: n-APD near 1, FID far below generated-vs-real
    assert result["real"]["n_apd"]["mean"] == pytest.approx(1.0, abs=0.2)
    assert result["real"]["fid"]["mean"] < result["generated"]["fid"]["mean"]


def test_evaluate_sets_shares_the_real_row_and_runs_extra_last(
    tiny_model_dir: Path, procedural_clips: list[Motion]
) -> None:
    loaded = load_model(tiny_model_dir)
    names = list(loaded.action_names)
    prepared = prepare_clips(procedural_clips, names, loaded.fps, loaded.window)
    calls: list[str] = []

    def generate(actions: np.ndarray, n: int, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
        calls.append("generate")
        idx = np.concatenate([np.flatnonzero(prepared.actions == a)[:n] for a in actions])
        batch = crop_windows(prepared, idx, rng)
        return np.asarray(batch.joints, np.float32), np.asarray(batch.actions), batch.origin[:, 1]

    def extra(rng: np.random.Generator) -> dict[str, float]:
        calls.append("extra")
        return {"draw": float(rng.random())}

    real, gen = evaluate_sets(
        prepared, None, generate, names=names, repeats=2, n_per_action=6, seed=5, extra=extra
    )
    assert calls == ["generate", "extra"] * 2
    # the generated windows here are real windows: their physical metrics equal a real set's
    assert all(row["bone_length_cv"] < 1e-3 for row in gen)
    assert len(real) == len(gen) == 2 and all("draw" in row and "apd" in row for row in gen)
    again, _ = evaluate_sets(prepared, None, generate, names=names, repeats=2, n_per_action=6, seed=5)
    assert again == real  # the real row does not depend on what is generated or added
    odmo = evaluate(loaded, procedural_clips, None, repeats=2, n_per_action=6, seed=5)
    assert odmo["real"] == report(real, gen)["real"]
    assert "bone_length_cv" in odmo["real"] and "foot_skate_m_s" in odmo["generated"]
    per_action = odmo["per_action"]
    assert set(per_action) == set(names)
    assert all("hand_speed_m_s" in per_action[a]["real"] for a in names)


def test_reconstruction_metrics_of_a_perfect_reconstruction(
    procedural_clips: list[Motion], classifier: Classifier
) -> None:
    names = list(PROCEDURAL_ACTIONS)
    prepared = prepare_clips(procedural_clips, names, 20.0, 40)
    batch = crop_windows(prepared, np.arange(len(procedural_clips)), np.random.default_rng(0))
    joints = np.asarray(batch.joints, np.float32)
    skel = prepared.skeleton
    out = reconstruction_metrics(joints, batch, classifier, names, skel)
    pred = classifier.classify(joints, batch.mask)[1]
    truth = [classifier.action_names.index(names[a]) for a in batch.actions]
    assert out["reconstruction_error_m"] == 0.0
    assert out["reconstruction_accuracy"] == pytest.approx(np.mean(pred == np.array(truth)))
    shifted = reconstruction_metrics(joints + np.float32([0.0, 0.0, 0.03]), batch, None, names, skel)
    assert shifted == {"reconstruction_error_m": pytest.approx(0.03)}
    # turned about the vertical, each reconstruction is read in its own frame, as samples are: labelled
    # with the classifier's own reading, it is read right whichever way it faces
    as_read = replace(batch, actions=np.array([names.index(classifier.action_names[p]) for p in pred]))
    turned = Rotation.from_euler("y", 180, degrees=True).apply(joints.reshape(-1, 3)).reshape(joints.shape)
    again = reconstruction_metrics(turned.astype(np.float32), as_read, classifier, names, skel)
    assert again["reconstruction_accuracy"] == 1.0
    assert again["reconstruction_error_m"] > 0.05


def test_mismatched_actions_or_skeleton_fail(tiny_model_dir: Path, procedural_clips: list[Motion]) -> None:
    loaded = load_model(tiny_model_dir)
    clip = procedural_clips[0]
    stranger = Motion(clip.joints, clip.fps, clip.skeleton, action="cartwheel", meta={"source": "x.npz"})
    with pytest.raises(ConfigError, match="cartwheel"):
        evaluate(loaded, [*procedural_clips, stranger], None, repeats=1)
    keep = list(range(clip.n_joints - 1))
    small = Motion(clip.joints[:, keep], clip.fps, clip.skeleton.subset(keep), action=clip.action)
    with pytest.raises(ConfigError, match="skeleton"):
        evaluate(loaded, [small], None, repeats=1)


def _write_folder(clips: list[Motion], folder: Path) -> Path:
    folder.mkdir()
    rows = ["file,action,style"]
    for i, clip in enumerate(clips):
        name = f"clip_{i:03d}.npz"
        write_motion(clip, folder / name)
        rows.append(f"{name},{clip.action},{clip.meta['style']}")
    (folder / "labels.csv").write_text("\n".join(rows) + "\n")
    return folder


def test_cli_train_classifier_and_eval(
    tiny_model_dir: Path,
    procedural_clips: list[Motion],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    data = _write_folder(procedural_clips, tmp_path / "real")
    clf = tmp_path / "clf"
    code = engine.cli.main(
        [
            "train-classifier",
            "--data",
            str(data),
            "--labels",
            "labels.csv",
            "--out",
            str(clf),
            "--epochs",
            "1",
        ]
    )
    assert code == 0 and (clf / "classifier.json").is_file() and (clf / "classifier.safetensors").is_file()
    assert "held-out accuracy" in capsys.readouterr().out
    out = tmp_path / "eval.json"
    argv = ["eval", "--model", str(tiny_model_dir), "--real", str(data), "--labels", "labels.csv"]
    argv += ["--classifier", str(clf), "--repeats", "2", "--n-per-action", "10", "--json", str(out)]
    assert engine.cli.main(argv) == 0
    table = capsys.readouterr().out
    assert "fid" in table and "style_nmi" in table
    result = json.loads(out.read_text())
    assert set(result) == {"real", "generated", "per_action", "meta"}
    assert "hand speed" in table and "walk" in table
    assert set(result["generated"]["accuracy"]) == {"mean", "ci95"}
    assert result["generated"].keys() >= REAL_KEYS | MODEL_KEYS | CONTROL_KEYS


def test_cli_eval_takes_any_kind(
    tiny_a2m_dir: Path, tiny_model_dir: Path, procedural_clips, tmp_path: Path, capsys
) -> None:
    data = _write_folder(procedural_clips, tmp_path / "real")
    out = tmp_path / "eval.json"
    argv = ["eval", "--model", str(tiny_a2m_dir), "--real", str(data), "--labels", "labels.csv"]
    argv += ["--repeats", "2", "--n-per-action", "5", "--json", str(out)]
    assert engine.cli.main(argv) == 0
    clips = load_folder(data, labels="labels.csv").clips
    expected = evaluate_a2m(load_a2m(tiny_a2m_dir), clips, None, repeats=2, n_per_action=5, seed=0)
    written = json.loads(out.read_text())
    for row in ("real", "generated"):
        for metric, value in expected[row].items():
            if np.isfinite(value["mean"]):
                assert written[row][metric]["mean"] == pytest.approx(value["mean"], rel=1e-5), metric
    capsys.readouterr()
    assert written["meta"]["strategy"] == "prior"
    assert engine.cli.main([*argv, "--strategy", "conventional"]) == 0  # ODMO's sampling of A2M's codes
    from_modes = json.loads(out.read_text())
    assert from_modes["meta"]["strategy"] == "conventional" and from_modes["real"] == written["real"]
    assert from_modes["generated"]["apd"] != written["generated"]["apd"]
    assert engine.cli.main([*argv, "--truncation", "0.5"]) == 0
    truncated = json.loads(out.read_text())
    assert truncated["meta"]["truncation"] == 0.5 and truncated["real"] == written["real"]
    assert truncated["generated"]["apd"] != written["generated"]["apd"]
    odmo = [a if a != str(tiny_a2m_dir) else str(tiny_model_dir) for a in argv]
    for bad, why in (
        (["--truncation", "0.5"], "cannot evaluate at truncation 0.5"),
        (["--truncation", "3"], "[0, 2]"),
    ):
        assert engine.cli.main([*(odmo if why.startswith("cannot") else argv), *bad]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and why in err


def test_cli_eval_of_an_unconditional_model(tiny_modi_dir: Path, procedural_clips, tmp_path: Path) -> None:
    data = _write_folder(procedural_clips[::3], tmp_path / "real")
    clf = tmp_path / "clf"
    train_classifier(procedural_clips, PROCEDURAL_ACTIONS, clf, epochs=2, batch_size=16, seed=0, window=12)
    out = tmp_path / "eval.json"
    argv = ["eval", "--model", str(tiny_modi_dir), "--real", str(data), "--labels", "labels.csv"]
    argv += ["--classifier", str(clf), "--repeats", "2", "--n-per-action", "6", "--json", str(out)]
    assert engine.cli.main(argv) == 0
    result = json.loads(out.read_text())
    generated = result["generated"]
    assert generated.keys() >= {"fid", "kid", "precision", "recall", "action_kl", "inversion_error_m"}
    assert generated.keys() >= PHYSICS_KEYS
    assert "accuracy" not in generated and "accuracy" in result["real"]  # its labels are predictions
    assert result["meta"]["window"] == 12  # the motions' centre 12 of 16 frames, as the classifier reads
    assert 0.0 <= generated["precision"]["mean"] <= 1.0 and generated["action_kl"]["mean"] >= 0.0
    shares = [row["generated"]["predicted_share"]["mean"] for row in result["per_action"].values()]
    assert sum(shares) == pytest.approx(1.0, abs=1e-6)
    assert engine.cli.main([*argv, "--strategy", "conventional"]) == 1


def test_cli_errors_are_one_line(
    tiny_model_dir: Path,
    procedural_clips: list[Motion],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    keep = list(range(procedural_clips[0].n_joints - 1))
    smaller = [
        Motion(c.joints[:, keep], c.fps, c.skeleton.subset(keep), action=c.action, meta=c.meta)
        for c in procedural_clips[:6]
    ]
    data = _write_folder(smaller, tmp_path / "other")
    base = ["eval", "--model", str(tiny_model_dir), "--real", str(data), "--labels", "labels.csv"]
    for argv in (
        base,
        [*base, "--classifier", str(tmp_path / "none")],
        ["eval", "--model", str(data), "--real", str(data)],
    ):
        assert engine.cli.main(argv) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("odmo eval: error:") and "\n" not in err
