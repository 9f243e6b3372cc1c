"""``pose_output = "rotations"``: ODMO's pose decoder emits local rotations and forward kinematics places
the joints, so every decode has the skeleton's bone lengths and rigid girdles whatever the weights."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import torch
from scipy.spatial.transform import Rotation

from engine.errors import ConfigError
from engine.generate import decode, sample
from engine.model import generator as generator_module
from engine.model.config import OdmoConfig
from engine.model.odmo import OdmoModel
from engine.modelio import load_model, save_model
from engine.train.loop import train
from tests.fixtures.procedural import PROCEDURAL_ACTIONS, procedural_skeleton
from tests.fixtures.tiny_model import TINY_PROJECTIONS, single_thread, tiny_config

pytestmark = pytest.mark.usefixtures("torch_single_thread")

T = 16


def _model(seed: int = 2) -> OdmoModel:
    skeleton = procedural_skeleton()
    config = OdmoConfig(
        n_actions=3, n_joints=skeleton.n_joints, window=T, enc_fc=32, traj_hidden=16, motion_hidden=16
    )
    model = OdmoModel(OdmoConfig(**(config.to_dict() | {"pose_output": "rotations"})), seed=seed)
    model.attach_skeleton(skeleton)
    return model


def _inputs(n: int = 4) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(7)
    return torch.randn(n, 20, generator=g), torch.arange(n) % 3, torch.randn(n, 3, generator=g)


def _bone_lengths(joints: np.ndarray, parents: np.ndarray) -> np.ndarray:
    """(..., J − 1) lengths of every non-root bone."""
    return np.linalg.norm(joints[..., 1:, :] - joints[..., parents[1:], :], axis=-1)


def _numpy_fk(d6: np.ndarray, skeleton) -> np.ndarray:
    """Joints (..., J, 3) of 6D local rotations (..., J, 6), root at the origin, written independently:
    scipy-checked rotation matrices from Gram–Schmidt, the tree walked joint by joint."""
    a, b = d6[..., :3], d6[..., 3:]
    e1 = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b - np.sum(b * e1, axis=-1, keepdims=True) * e1
    e2 = b / np.linalg.norm(b, axis=-1, keepdims=True)
    local = np.stack([e1, e2, np.cross(e1, e2)], axis=-1)
    world = np.zeros_like(local)
    pos = np.zeros((*d6.shape[:-1], 3))
    for j, p in enumerate(skeleton.parents):
        if p < 0:
            world[..., j, :, :] = local[..., j, :, :]
            continue
        world[..., j, :, :] = world[..., p, :, :] @ local[..., j, :, :]
        pos[..., j, :] = pos[..., p, :] + world[..., p, :, :] @ skeleton.offsets[j]
    flat = local.reshape(-1, 3, 3)
    np.testing.assert_allclose(Rotation.from_matrix(flat).as_matrix(), flat, atol=1e-5)  # proper rotations
    return pos


def test_every_decode_has_the_skeletons_bone_lengths_whatever_the_weights() -> None:
    model, skeleton = _model(), procedural_skeleton()
    z, action, end = _inputs()
    with torch.no_grad():
        free = model.decode_full(z, action, end)
        forced = model.decode_full(z, action, end, prev_truth=torch.randn(4, T, 11, 3), tf_rate=0.5)
    rest = np.linalg.norm(skeleton.offsets[1:], axis=1)
    for out in (free, forced):
        joints = out.joints.numpy()
        np.testing.assert_allclose(
            _bone_lengths(joints, skeleton.parents), np.broadcast_to(rest, (4, T, 10)), atol=2e-6
        )
        torch.testing.assert_close(out.joints[:, :, 0], out.trajectory)  # the root is the trajectory
        assert out.raw is out.joints  # nothing to project
    assert model.projection is None


def test_joints_are_the_forward_kinematics_of_the_emitted_rotations() -> None:
    model, skeleton = _model(), procedural_skeleton()
    z, action, end = _inputs()
    gen = model.motion_gen
    with torch.no_grad():
        cond = model.condition(z, action)
        traj = model.traj_gen(cond, end)
        joints, hidden = gen(traj, cond)
        d6 = gen.out(hidden).unflatten(-1, (11, 6)).double().numpy()
    expected = _numpy_fk(d6, skeleton) + traj.double().numpy()[:, :, None]
    np.testing.assert_allclose(joints.numpy(), expected, atol=1e-5)


def test_the_free_decode_reads_back_its_own_joints() -> None:
    """Teacher-forced on its own free-running output, the decoder reproduces it frame for frame."""
    model = _model().eval()
    z, action, end = _inputs()
    with torch.no_grad():
        free = model.decode_full(z, action, end).joints
        forced = model.decode_full(z, action, end, prev_truth=free, tf_rate=1.0).joints
    torch.testing.assert_close(forced, free, atol=1e-5, rtol=1e-5)


def test_the_free_decode_trains_every_decoder_weight() -> None:
    model = _model().train()
    z, action, end = _inputs(3)
    joints, _ = model.decode(z, action, end)
    (joints - torch.randn_like(joints)).square().mean().backward()
    gen = model.motion_gen
    for name in ("out.weight", "embed.weight", "lstm.weight_hh_l0", "lstm.weight_ih_l1"):
        grad = gen.get_parameter(name).grad
        assert grad is not None and grad.abs().sum() > 0, name


def test_a_rotation_decoder_needs_root_relative_poses_and_a_skeleton() -> None:
    with pytest.raises(ConfigError, match="root_relative_poses"):
        OdmoConfig(n_actions=3, n_joints=11, pose_output="rotations", root_relative_poses=False)
    with pytest.raises(ConfigError, match="pose_output"):
        OdmoConfig(n_actions=3, n_joints=11, pose_output="quaternions")
    unattached = OdmoModel(OdmoConfig(n_actions=3, n_joints=11, window=T, pose_output="rotations"))
    with pytest.raises(RuntimeError, match="attach_skeleton"):
        unattached.decode(*_inputs())


def test_save_load_decode_is_bit_identical(tmp_path: Path) -> None:
    model = _model().eval()
    save_model(tmp_path, model, model.config, procedural_skeleton(), PROCEDURAL_ACTIONS, {"seed": 2}, 0.95)
    loaded = load_model(tmp_path)
    assert loaded.config.pose_output == "rotations"
    shown = decode(loaded, np.zeros(20, np.float32), 2, end=[0.5, 0.0, 1.0]).joints
    with torch.inference_mode():
        z, action, end = _inputs()
        a, _ = model.decode(z, action, end)
        b, _ = loaded.model.decode(z, action, end)
    assert torch.equal(a, b)
    rest = np.linalg.norm(procedural_skeleton().offsets[1:], axis=1)
    lengths = _bone_lengths(shown, procedural_skeleton().parents)
    assert np.abs(lengths - rest).max() < 1e-5  # sampled through the app's path, foot clean-up included


def test_training_a_rotation_decoder_lowers_its_reconstruction_loss(tmp_path: Path, procedural_clips) -> None:
    config = tiny_config(pose_output="rotations", epochs=6)  # from torch's initialisation: far to go
    with single_thread():
        train(
            procedural_clips,
            PROCEDURAL_ACTIONS,
            tmp_path,
            config,
            seed=0,
            device="cpu",
            bank_projections=TINY_PROJECTIONS,
            bank_k_range=(3, 4),
        )
    with open(tmp_path / "train_log.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    recon = [float(row["train_recon"]) for row in rows]
    assert recon[-1] < 0.75 * recon[0]  # measured 0.287 → 0.190
    loaded = load_model(tmp_path)
    rest = np.linalg.norm(procedural_skeleton().offsets[1:], axis=1)
    for drawn in sample(loaded, 0, 4, 1):
        lengths = _bone_lengths(drawn.motion.joints, procedural_skeleton().parents)
        assert np.abs(lengths - rest).max() < 1e-5


def test_compiled_and_eager_rotation_loops_agree() -> None:
    model = _model().eval()
    gen = model.motion_gen
    z, action, end = _inputs(3)
    with torch.no_grad():
        cond = model.condition(z, action)
        state, const = gen._context(model.traj_gen(cond, end), cond)
        args = (const, state[0], state[1], *gen._step_weights(), gen.fk_offsets, *gen._fk_levels())
        eager = generator_module._free_run_fk_loop(*args)
        compiled = generator_module._compiled(generator_module._free_run_fk_loop)(*args)
    assert isinstance(
        generator_module._compiled(generator_module._free_run_fk_loop), torch.jit.ScriptFunction
    )
    for a, b in zip(compiled, eager, strict=True):
        torch.testing.assert_close(a, b, atol=1e-6, rtol=1e-6)
