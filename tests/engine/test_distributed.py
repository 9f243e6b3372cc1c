"""``odmo train`` under torchrun: two CPU processes with gloo train what one process trains on the same
global batch."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.distributed as dist
from safetensors.numpy import load_file

from engine.errors import ConfigError
from engine.model.config import OdmoConfig
from engine.model.encoder import SampleSafeBatchNorm1d
from engine.modelio import WEIGHTS_FILE, load_model
from engine.train.distributed import Ranks
from engine.train.loop import train

PATTERN = r"^(?P<action>[a-z]+)_(?P<style>[a-z-]+)_\d+"
SIZES = ("enc_hidden=8", "enc_fc=16", "traj_hidden=8", "motion_hidden=8", "batch_size=16", "epoch_size=64")
# Windows no longer than the shortest clip (42 frames) and no contact terms: no loss is a ratio of
# per-rank counts (padded frames, planted feet), so the ranks' mean gradient is the global batch's exactly.
EXACT = ("window=40", "w_skate=0", "w_contact=0")  # the contact head then takes no part in the loss
# Two processes add their gradients in another order than one does; over 8 Adam steps the float32
# rounding moves decoded joints by about 0.03 mm. Training one rank's half batch alone moves them ~90 mm.
JOINT_ATOL_M = 5e-4


def _train(
    data: Path, out: Path, *launcher: str, extra: tuple[str, ...] = (), epochs: int = 2
) -> subprocess.CompletedProcess:
    settings = [x for s in (*SIZES, *EXACT) for x in ("--set", s)]
    argv = [*launcher, "-m", "engine", "train", "--data", str(data), "--pattern", PATTERN, "--out", str(out)]
    argv += ["--epochs", str(epochs), "--device", "cpu", "--projections", "pca", *settings, *extra]
    env = os.environ | {"OMP_NUM_THREADS": "1", "ODMO_CACHE_DIR": str(out.parent / "cache")}
    return subprocess.run(argv, capture_output=True, text=True, timeout=300, env=env)


def _torchrun(n: int) -> tuple[str, ...]:
    return (sys.executable, "-m", "torch.distributed.run", "--standalone", f"--nproc_per_node={n}")


@pytest.fixture(scope="module")
def runs(procedural_npz_dir, tmp_path_factory) -> dict[str, Path]:
    """The same training in one process, in two torchrun processes, and in two for its first epoch then
    one (resumed); and one process on half the batch."""
    root = tmp_path_factory.mktemp("ddp_runs")
    made = {
        "single": _train(procedural_npz_dir, root / "single", sys.executable),
        "double": _train(procedural_npz_dir, root / "double", *_torchrun(2)),
        "half": _train(procedural_npz_dir, root / "half", sys.executable, extra=("--set", "batch_size=8")),
        "resumed": _train(procedural_npz_dir, root / "resumed", *_torchrun(2), epochs=1),
    }
    made["resumed"] = _train(procedural_npz_dir, root / "resumed", sys.executable, extra=("--resume",))
    for done in made.values():
        assert done.returncode == 0, done.stderr[-3000:]
    return {name: root / name for name in made}


def _decoded(folder: Path, codes_of: Path) -> np.ndarray:
    """Joints the model in ``folder`` decodes from the latent bank codes of the model in ``codes_of``."""
    bank = load_model(codes_of).bank
    model = load_model(folder).model
    with torch.inference_mode():
        args = (torch.from_numpy(a) for a in (bank.codes, bank.actions, bank.ends))
        return model.decode(*args)[0].numpy()


def _worst(a: Path, b: Path) -> float:
    """Largest joint difference (m) between what the two models decode from the same codes."""
    return float(np.abs(_decoded(a, a) - _decoded(b, a)).max())


def test_two_processes_train_the_single_process_model(runs):
    assert (
        load_file(str(runs["single"] / WEIGHTS_FILE)).keys()
        == load_file(str(runs["double"] / WEIGHTS_FILE)).keys()
    )
    assert _worst(runs["single"], runs["double"]) <= JOINT_ATOL_M
    assert _worst(runs["single"], runs["half"]) > 20 * JOINT_ATOL_M  # one rank's share alone is another run


def test_a_two_process_checkpoint_resumes_in_one_process(runs):
    assert _worst(runs["single"], runs["resumed"]) <= JOINT_ATOL_M


def test_the_log_holds_the_global_batch_losses(runs):
    def totals(folder: Path) -> np.ndarray:
        with open(folder / "train_log.csv", newline="") as f:
            return np.array([float(row["train_total"]) for row in csv.DictReader(f)])

    one, two = totals(runs["single"]), totals(runs["double"])
    assert len(one) == len(two) == 2
    np.testing.assert_allclose(two, one, rtol=1e-4)


def test_rank_zero_alone_writes_the_folder(runs):
    made = sorted(p.name for p in runs["double"].iterdir())
    assert made == sorted(p.name for p in runs["single"].iterdir())
    assert '"processes": 2' in (runs["double"] / "model.json").read_text()


def test_a_batch_that_does_not_split_evenly_is_refused(procedural_clips, tmp_path):
    assert Ranks(1, 2).share(8).tolist() == [4, 5, 6, 7]
    with pytest.raises(ConfigError, match="does not split evenly over 3"):
        Ranks(0, 3).share(8)
    names = sorted({c.action for c in procedural_clips})
    config = OdmoConfig(n_actions=len(names), n_joints=procedural_clips[0].skeleton.n_joints, batch_size=12)
    with pytest.raises(
        ConfigError, match=r"batch_size 12 does not split .* over 4 processes; use a multiple of 8"
    ):
        train(procedural_clips, names, tmp_path / "m", config, device="cpu", ranks=Ranks(0, 4))


def _batch_norm_rank(rank: int, store: str, out: str) -> None:
    """One of two gloo processes: normalise its half of a fixed batch and backpropagate a fixed loss."""
    dist.init_process_group("gloo", init_method=f"file://{store}", rank=rank, world_size=2)
    x, weights, norm = _batch_norm_case()
    half = x[4 * rank : 4 * rank + 4].clone().requires_grad_(True)
    y = norm(half)
    (y * weights[4 * rank : 4 * rank + 4]).sum().backward()
    grads = torch.cat([norm.weight.grad, norm.bias.grad])
    dist.all_reduce(grads)  # what DistributedDataParallel sums before it averages
    torch.save({"y": y.detach(), "x_grad": half.grad, "grads": grads, "mean": norm.running_mean,
                "var": norm.running_var}, f"{out}/{rank}.pt")  # fmt: skip
    dist.destroy_process_group()


def _batch_norm_case() -> tuple[torch.Tensor, torch.Tensor, SampleSafeBatchNorm1d]:
    generator = torch.Generator().manual_seed(0)
    x = torch.randn(8, 5, generator=generator) * 3 + 1
    weights = torch.randn(8, 5, generator=generator)
    norm = SampleSafeBatchNorm1d(5)
    with torch.no_grad():
        norm.weight.copy_(torch.rand(5, generator=generator) + 0.5)
        norm.bias.copy_(torch.randn(5, generator=generator))
    return x, weights, norm


def test_the_encoder_batch_norm_uses_every_processs_batch(tmp_path):
    torch.multiprocessing.spawn(_batch_norm_rank, args=(str(tmp_path / "store"), str(tmp_path)), nprocs=2)
    x, weights, norm = _batch_norm_case()
    x.requires_grad_(True)
    whole = torch.nn.BatchNorm1d(5)
    whole.load_state_dict(norm.state_dict())
    y = whole(x)
    (y * weights).sum().backward()
    ranks = [torch.load(tmp_path / f"{r}.pt") for r in range(2)]
    np.testing.assert_allclose(torch.cat([r["x_grad"] for r in ranks]), x.grad, atol=1e-5)
    np.testing.assert_allclose(ranks[0]["grads"], torch.cat([whole.weight.grad, whole.bias.grad]), atol=1e-5)
    np.testing.assert_allclose(torch.cat([r["y"] for r in ranks]), y.detach(), atol=1e-5)
    for r in ranks:
        np.testing.assert_allclose(r["mean"], whole.running_mean, atol=1e-6)
        np.testing.assert_allclose(r["var"], whole.running_var, atol=1e-6)
    np.testing.assert_allclose(torch.cat([r["y"] for r in ranks]), whole(x).detach(), atol=1e-5)


def test_a_kind_that_trains_in_one_process_says_so(procedural_npz_dir, tmp_path):
    done = _train(procedural_npz_dir, tmp_path / "a2m", *_torchrun(2), extra=("--arch", "a2m"))
    assert done.returncode != 0
    message = "odmo train: error: --arch a2m trains in one process; torchrun trains --arch odmo only"
    # each rank says it once; the two ranks' lines can interleave on a shared stderr
    assert done.stderr.count(message) == 2
    assert done.stderr.count("odmo train: error:") == 2
    assert "engine/" not in done.stderr  # no traceback of ours (torchrun reports its children's exit codes)
