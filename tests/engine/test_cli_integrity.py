"""Process-level integrity: killed writers leave nothing behind, two writers never silently overwrite,
and every command answers bad input with one line naming the file."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from engine.cli import main
from engine.fileio import atomic_write_text, folder_lock
from engine.modelio import BANK_FILE, META_FILE
from engine.motion.formats import write_motion
from engine.motion.npz import read_npz
from tests.fixtures.tamper import record_bank_checksum, rewrite_npz


@pytest.fixture(scope="module")
def procedural_dir(tmp_path_factory: pytest.TempPathFactory, procedural_clips: list) -> Path:
    """A folder of procedural clips as NPZ files named ``<action>_<n>.npz``."""
    folder = tmp_path_factory.mktemp("procedural")
    for i, clip in enumerate(procedural_clips[::6]):
        write_motion(clip, folder / f"{clip.action}_{i:03d}.npz")
    return folder


_HOLD_TEMP = textwrap.dedent(
    """
    import sys, time
    from engine.fileio import atomic_write
    with atomic_write(sys.argv[1], "wb") as handle:
        handle.write(b"x" * 2_000_000)
        handle.flush()
        print("writing", flush=True)
        time.sleep(120)
    """
)


def _start_writer(target: Path) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", _HOLD_TEMP, str(target)], stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout is not None and proc.stdout.readline().strip() == "writing"
    return proc


def _kill(proc: subprocess.Popen) -> None:
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert proc.stdout is not None
    proc.stdout.close()


def _temporaries(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_a_killed_writers_temporary_is_removed_by_the_next_write(tmp_path: Path) -> None:
    folder = tmp_path / "checkpoints"
    folder.mkdir()
    _kill(_start_writer(folder / "last.pt"))
    (stale,) = _temporaries(folder)
    assert stale.name.startswith(".last.pt.") and stale.stat().st_size == 2_000_000
    assert not (folder / "last.pt").exists(), "a killed writer never leaves a torn target"
    atomic_write_text(folder / "log.csv", "epoch\n")
    assert _temporaries(folder) == []
    assert (folder / "log.csv").read_text() == "epoch\n"


def test_a_live_writers_temporary_is_left_alone(tmp_path: Path) -> None:
    proc = _start_writer(tmp_path / "big.bvh")
    try:
        atomic_write_text(tmp_path / "other.txt", "x")
        assert len(_temporaries(tmp_path)) == 1, "another process's write in progress must survive"
    finally:
        _kill(proc)


def _odmo(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "engine", *args], capture_output=True, text=True, timeout=300, env=env
    )


def _odmo_here(capsys: pytest.CaptureFixture, *args: str) -> subprocess.CompletedProcess:
    """``odmo ARGS`` run in this process (quicker than a subprocess where the process does not matter)."""
    code = main(list(args))
    return subprocess.CompletedProcess(args, code, *capsys.readouterr())


def _one_line_error(run: subprocess.CompletedProcess, *needles: str) -> None:
    assert run.returncode == 1, (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr, run.stderr
    lines = [line for line in run.stderr.splitlines() if "error:" in line]
    assert len(lines) == 1, run.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_a_second_writer_into_a_locked_output_folder_fails_clearly(
    tiny_model_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "samples"
    with folder_lock(out, "writing motions"):
        run = _odmo(
            "sample", "--model", str(tiny_model_dir), "--action", "walk", "--n", "3", "--out", str(out)
        )
    _one_line_error(run, str(out), "another odmo process (pid")
    assert [p.name for p in out.iterdir()] == [".odmo-lock"], "nothing written by the refused writer"
    run = _odmo_here(
        capsys, "sample", "--model", str(tiny_model_dir), "--action", "walk", "--n", "3", "--out", str(out)
    )
    assert run.returncode == 0, run.stderr
    assert sorted(p.name for p in out.glob("*.npz")) == ["walk_000.npz", "walk_001.npz", "walk_002.npz"]


def test_two_trainings_into_one_model_folder(tmp_path: Path, procedural_dir: Path) -> None:
    model = tmp_path / "model"
    with folder_lock(model, "training a model"):
        run = _odmo(
            "train", "--data", str(procedural_dir), "--pattern", r"^(?P<action>[a-z]+)_", "--out", str(model)
        )
    _one_line_error(run, str(model), "is training a model there")
    assert not (model / META_FILE).exists()


def test_train_refuses_an_existing_file_as_output_before_training(tmp_path: Path) -> None:
    target = tmp_path / "model.json"
    target.write_text("{}")
    assert main(["train", "--data", str(tmp_path), "--out", str(target)]) == 1
    assert target.read_text() == "{}"


@pytest.mark.parametrize(
    ("key", "value", "needle", "process"),
    [
        ("modes/0/weights", np.nan, "mixture weights", True),
        ("modes/0/covariances", -1.0, "positive definite", False),
        ("modes/0/means", 1e30, "means must be finite", False),
    ],
)
def test_sample_names_the_bank_of_a_bad_model_folder(
    tiny_model_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    key: str,
    value: float,
    needle: str,
    process: bool,
) -> None:
    folder = Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))
    rewrite_npz(folder / BANK_FILE, lambda arrays: arrays.update({key: np.full_like(arrays[key], value)}))
    record_bank_checksum(folder)
    args = ("sample", "--model", str(folder), "--action", "walk", "--out", str(tmp_path / "x.npz"))
    if process:
        run = _odmo(*args)
    else:
        code = main(list(args))
        run = subprocess.CompletedProcess(args, code, *capsys.readouterr())
    _one_line_error(run, str(folder / BANK_FILE), needle)
    assert not (tmp_path / "x.npz").exists()


def test_flipped_weights_stop_sampling(
    tiny_model_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    folder = Path(shutil.copytree(tiny_model_dir, tmp_path / "model"))
    weights = folder / "model.safetensors"
    data = bytearray(weights.read_bytes())
    data[-64:] = bytes(b ^ 0x01 for b in data[-64:])
    weights.write_bytes(bytes(data))
    run = _odmo_here(
        capsys, "sample", "--model", str(folder), "--action", "walk", "--out", str(tmp_path / "x.npz")
    )
    _one_line_error(run, "model.safetensors", "checksum")


def test_small_bad_inputs_get_one_line(
    tiny_model_dir: Path, tmp_path: Path, procedural_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    sample = ("sample", "--model", str(tiny_model_dir), "--action", "walk", "--out", str(tmp_path / "x.npz"))
    _one_line_error(_odmo_here(capsys, *sample, "--end", "nan", "0"), "--end must be two finite numbers")
    junk = tmp_path / "junk.csv"
    junk.write_bytes(bytes(range(256)) * 8)
    _one_line_error(_odmo_here(capsys, "info", str(procedural_dir), "--labels", str(junk)), str(junk))
    huge = tmp_path / "huge.npy"
    np.save(huge, np.full((10, 24, 3), 1e16, dtype=np.float32))
    run = _odmo("convert", str(huge), str(tmp_path / "out.bvh"))
    _one_line_error(run, "huge.npy", "not motion in metres")
    assert not (tmp_path / "out.bvh").exists()
    _one_line_error(_odmo_here(capsys, *sample, "--n", "0"), "--n must be a whole number")


def test_info_labels_a_folder_by_pattern(procedural_dir: Path, capsys: pytest.CaptureFixture) -> None:
    run = _odmo_here(capsys, "info", str(procedural_dir), "--pattern", r"^(?P<action>[a-z]+)_")
    assert run.returncode == 0, run.stderr
    assert "generic layout" in run.stdout and "walk" in run.stdout


def test_two_concurrent_samplers_into_one_folder_never_mix(tiny_model_dir: Path, tmp_path: Path) -> None:
    """Started together: one writes all its files, the other fails at once and writes none."""
    out = tmp_path / "samples"
    procs = [
        subprocess.Popen(
            [sys.executable, "-m", "engine", "sample", "--model", str(tiny_model_dir), "--action", "walk",
             "--n", "20", "--seed", str(seed), "--out", str(out)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        for seed in (1, 2)
    ]  # fmt: skip
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    for p in procs:
        p.stderr.close()
    codes = sorted(code for code, _ in results)
    assert codes == [0, 1], results
    loser = next(err for code, err in results if code == 1)
    assert "another odmo process (pid" in loser and "Traceback" not in loser
    winner_seed = 1 + [code for code, _ in results].index(0)
    files = sorted(out.glob("*.npz"))
    assert len(files) == 20
    assert {read_npz(f).meta["seed"] for f in files} == {winner_seed}
