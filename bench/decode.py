"""Decode latency and throughput on CPU (T = 60, 21 joints, 10 actions, default sizes, random weights).

Run: ``python bench/decode.py [--threads 2] [--repeats 50]`` (every row at 1 thread and at --threads).
The skeleton is the bundled model's (Bandai-Namco, 21 joints) so that the bone projection (the FK of
bone directions the decoder runs) and the foot clean-up are timed on real topology; they have their
own rows, with the torch FK of local rotations (what a rotation-output decoder would run) beside them.
Reference rows: the paper's modules built plainly (``plain_decode``: the reference code's structure, one
nn.LSTM call per frame in a Python loop) on the same random weights, timed beside OdmoModel.decode in the
same run, with the speed ratio and the largest difference of their joints. Aim: < 6 ms, >= 5,000/s.
The reduced-precision rows decode the bundled model's bank codes against float32 in the same run (speed
ratio, largest joint difference): OdmoModel.decode under bfloat16 and float16 autocast; int8 dynamic
quantization (quantize_dynamic of every nn.LSTM and nn.Linear) of the paper's modules, against them in
float32, since the fused decoder loop reads float weights that quantize_dynamic cannot reach; and weights
rounded to int8, bfloat16 or float16 in float32 arithmetic, the accuracy each format allows at best.
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
import statistics
import sys
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import nn

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record
from engine.generate import decode, decode_array
from engine.model.config import OdmoConfig
from engine.model.odmo import OdmoModel
from engine.model.precision import bfloat16_autocast, native_bfloat16
from engine.modelio import LoadedModel, load_model
from engine.motion.contact import foot_joints
from engine.motion.ik import plant_feet
from engine.motion.kinematics import BoneProjection, forward_kinematics, rotation_6d_to_matrix
from engine.motion.skeleton import Skeleton

N_ACTIONS, N_JOINTS = 10, 21
BUNDLED = Path(__file__).resolve().parents[1] / "resources" / "models" / "bandai2-odmo" / "model.json"


def bundled_skeleton() -> Skeleton:
    """The bundled model's skeleton (names, parents, offsets from its model.json)."""
    import json

    meta = json.loads(BUNDLED.read_text(encoding="utf-8"))["skeleton"]
    return Skeleton(tuple(meta["names"]), np.array(meta["parents"]), np.array(meta["offsets"]))


def _timed(fn: Callable[[], object], repeats: int) -> float:
    """Median seconds of ``fn`` over ``repeats`` calls, after warm-up calls (TorchScript specialises the
    decoder loop during its first calls)."""
    for _ in range(max(2, repeats // 10)):
        fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _loaded(model: OdmoModel, config: OdmoConfig, skeleton: Skeleton) -> LoadedModel:
    """A LoadedModel around random weights (no bank: end locations are given)."""
    return LoadedModel(
        model=model,
        config=config,
        skeleton=skeleton,
        action_names=[f"a{i}" for i in range(N_ACTIONS)],
        fps=config.fps,
        window=config.window,
        root_height=0.9,
        provenance={},
        bank=None,
        path=Path("random-weights"),
    )


def _stages(model: OdmoModel, rng: np.random.Generator, config: OdmoConfig) -> list[dict[str, object]]:
    """Time the three decode stages (trajectory LSTM, trajectory encoder, free-running pose decoder)."""
    rows = []
    gen = model.motion_gen
    for batch in (1, 1024):
        z = torch.as_tensor(rng.standard_normal((batch, config.latent_dim)), dtype=torch.float32)
        a = torch.as_tensor(rng.integers(0, N_ACTIONS, batch))
        e = torch.as_tensor(rng.standard_normal((batch, 3)), dtype=torch.float32)
        with torch.inference_mode():
            cond = model.condition(z, a)
            traj = model.traj_gen(cond, e)
            state, const = gen._context(traj, cond)
            repeats = 20 if batch == 1 else 3
            stages = {
                "trajectory generator": lambda cond=cond, e=e: model.traj_gen(cond, e),
                "trajectory encoder + static input": lambda traj=traj, cond=cond: gen._context(traj, cond),
                "free-running pose decoder": lambda const=const, state=state: gen._free_run(const, state),
            }
            for name, fn in stages.items():
                seconds = _timed(fn, repeats)
                rows.append({"what": f"stage: {name}", "batch": batch, "ms": round(seconds * 1e3, 2)})
    return rows


def _decodes(loaded: LoadedModel, rng: np.random.Generator, repeats: int) -> list[dict[str, object]]:
    """Time one decode through the API (bone projection and foot clean-up included), then
    OdmoModel.decode (projection included, no clean-up) at batch 1, 2, 64 and 1024, and decode_array
    (everything the app and the exports get) at batch 1024."""
    config, model = loaded.config, loaded.model
    model.attach_skeleton(loaded.skeleton)
    code, end = rng.standard_normal(config.latent_dim), np.array([0.5, 0.0, 1.0])
    one = _timed(lambda: decode(loaded, code, 3, end), repeats)
    rows: list[dict[str, object]] = [
        {
            "what": "engine.generate.decode, one motion (API, Motion built)",
            "batch": 1,
            "ms": round(one * 1e3, 2),
            "motions/s": round(1 / one),
        }
    ]
    rows += _model_decodes(model, "OdmoModel.decode (inference_mode)", (1, 2, 64, 1024), rng, repeats)
    codes = rng.standard_normal((1024, config.latent_dim)).astype(np.float32)
    actions, ends = rng.integers(0, N_ACTIONS, 1024), rng.standard_normal((1024, 3)).astype(np.float32)
    seconds = _timed(lambda: decode_array(loaded, codes, actions, ends), 3)
    rows.append(
        {
            "what": "engine.generate.decode_array (projection + foot clean-up)",
            "batch": 1024,
            "ms": round(seconds * 1e3, 2),
            "motions/s": round(1024 / seconds),
        }
    )
    return rows


def plain_decode(model: OdmoModel, z: torch.Tensor, action: torch.Tensor, end: torch.Tensor) -> torch.Tensor:
    """The paper's decode built plainly, as the public reference code runs it, on ``model``'s weights:
    the pose decoder's input [previous pose, conditioning, t/T] rebuilt every frame and one ``nn.LSTM``
    call (a sequence of one) per frame in a Python loop. Joints (B, T, J, 3) before the bone
    projection, which the reference code does not have."""
    gen = model.motion_gen
    cond = model.condition(z, action)
    trajectory = model.traj_gen(cond, end)
    _, state = gen.traj_lstm(gen.traj_embed(trajectory))
    b = z.shape[0]
    prev = z.new_zeros(b, gen.pose_dim)
    poses = []
    for t in range(gen.window):
        step = torch.full((b, 1), t / gen.window, dtype=z.dtype)
        x = gen.embed_act(gen.embed(torch.cat([prev, cond, step], dim=1)))
        out, state = gen.lstm(x.unsqueeze(1), state)
        pose = gen.out(out[:, 0])
        poses.append(pose)
        prev = gen._readback(pose)
    return gen._absolute(torch.stack(poses, dim=1), trajectory)


def _plain_modules(loaded: LoadedModel, rng: np.random.Generator, repeats: int) -> list[dict[str, object]]:
    """The plainly built modules against OdmoModel.decode in the same run, at batch 1, 2, 64 and 1024:
    the speed ratio, and the largest difference of their joints from the project's (before projection)
    to show that they compute the same motion."""
    config, model = loaded.config, loaded.model
    rows: list[dict[str, object]] = []
    for batch in (1, 2, 64, 1024):
        z = torch.as_tensor(rng.standard_normal((batch, config.latent_dim)), dtype=torch.float32)
        a = torch.as_tensor(rng.integers(0, N_ACTIONS, batch))
        e = torch.as_tensor(rng.standard_normal((batch, 3)), dtype=torch.float32)
        n = max(3, repeats // max(1, batch // 16))
        with torch.inference_mode():
            raw = model.decode_full(z, a, e).raw
            error = _largest_mm(plain_decode(model, z, a, e) - raw, 4)
            plain = _timed(lambda z=z, a=a, e=e: plain_decode(model, z, a, e), n)
            ours = _timed(lambda z=z, a=a, e=e: model.decode(z, a, e), n)
        rows.append(
            {
                "what": "reference: the paper's modules built plainly (nn.LSTM steps in a Python loop)",
                "batch": batch,
                "ms": round(plain * 1e3, 2),
                "motions/s": round(batch / plain),
                "OdmoModel.decode vs plain": f"{plain / ours:.2f}x",
                "max joint difference mm": error,
            }
        )
    return rows


def int8_dynamic(model: OdmoModel) -> OdmoModel:
    """A copy of ``model`` with every nn.LSTM and nn.Linear int8 dynamically quantized (torch's quantized
    engine, x86 / fbgemm here). Only ``plain_decode`` runs it: OdmoModel.decode's fused loop reads the
    float weights of the nn.LSTM that quantize_dynamic replaces."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # torch.ao.quantization is deprecated in favour of torchao
        return torch.ao.quantization.quantize_dynamic(copy.deepcopy(model), {nn.LSTM, nn.Linear}, torch.qint8)


ROUNDINGS = ("int8", "bfloat16", "float16")  # weight formats whose rounding alone is measured


@torch.no_grad()
def rounded_weights(model: OdmoModel, fmt: str) -> OdmoModel:
    """A copy of ``model`` whose nn.LSTM and nn.Linear weights are rounded to ``fmt`` (one of ROUNDINGS;
    int8: one symmetric scale per output row) and kept in float32: that format's weights with exact
    arithmetic, the best accuracy the format allows."""
    rounded = copy.deepcopy(model)
    for module in rounded.modules():
        if isinstance(module, nn.LSTM | nn.Linear):
            for name, weight in module.named_parameters():
                if not name.startswith("weight"):
                    continue
                if fmt == "int8":
                    scale = weight.abs().amax(1, keepdim=True).clamp_min(1e-12) / 127
                    weight.copy_((weight / scale).round() * scale)
                else:
                    weight.copy_(weight.to(getattr(torch, fmt)).float())
    return rounded


def _precision_row(
    what: str, batch: int, seconds: float, reference: float, error: torch.Tensor
) -> dict[str, object]:
    """One reduced-precision row: time, rate, speed-up over the float32 ``reference`` seconds and the
    largest joint difference ``error`` (B, T, J, 3) in mm."""
    return {
        "what": what,
        "batch": batch,
        "ms": round(seconds * 1e3, 2),
        "motions/s": round(batch / seconds),
        "vs float32": f"{reference / seconds:.2f}x",
        "max joint difference mm": _largest_mm(error),
    }


def _largest_mm(error: torch.Tensor, digits: int = 1) -> float:
    """The largest joint distance of ``error`` (..., 3), metres, in millimetres rounded to ``digits``."""
    return round(float(torch.linalg.vector_norm(error, dim=-1).max()) * 1e3, digits)


def _reduced_precision(repeats: int) -> list[dict[str, object]]:
    """The bundled model's decode of its bank codes in reduced precision against float32 in the same run,
    at batch 1, 2, 64 and 1024, every joint on the skeleton's bone lengths: OdmoModel.decode under
    bfloat16 and float16 autocast; the paper's modules int8 dynamically quantized, against the same
    modules in float32; and weights rounded to each of ROUNDINGS in float32 arithmetic (accuracy only)."""
    loaded = load_model(BUNDLED.parent)
    model, bank = loaded.model, loaded.bank
    model.attach_skeleton(loaded.skeleton)
    quantized = int8_dynamic(model)
    rounded_models = {fmt: rounded_weights(model, fmt) for fmt in ROUNDINGS}
    native = "" if native_bfloat16("cpu") else " (no bfloat16 instructions)"
    half = "" if torch.ops.mkldnn._is_mkldnn_fp16_supported() else " (no float16 instructions)"
    autocasts = {
        f"bundled model decode, bfloat16 autocast{native}": lambda: bfloat16_autocast("cpu"),
        f"bundled model decode, float16 autocast{half}": lambda: torch.autocast("cpu", torch.float16),
    }
    engine = torch.backends.quantized.engine
    int8 = f"bundled model, the paper's modules int8 (quantize_dynamic, {engine}; vs them in float32)"
    rows: list[dict[str, object]] = []
    for batch in (1, 2, 64, 1024):
        rows_of = np.arange(batch) % len(bank.codes)
        z, a, e = (torch.from_numpy(x[rows_of]) for x in (bank.codes, bank.actions, bank.ends))
        n = max(3, repeats // max(1, batch // 16))
        with torch.inference_mode():
            exact = model.decode(z, a, e)[0]
            f32 = _timed(lambda z=z, a=a, e=e: model.decode(z, a, e), n)
            plain = _timed(lambda z=z, a=a, e=e: plain_decode(model, z, a, e), n)
            reduced = model.projection(plain_decode(quantized, z, a, e))
            i8 = _timed(lambda z=z, a=a, e=e: plain_decode(quantized, z, a, e), n)
            for what, autocast in autocasts.items():
                with autocast():
                    joints = model.decode(z, a, e)[0].float()
                    seconds = _timed(lambda z=z, a=a, e=e: model.decode(z, a, e), n)
                rows.append(_precision_row(what, batch, seconds, f32, joints - exact))
            rounded = {fmt: r.decode(z, a, e)[0] for fmt, r in rounded_models.items()}
        rows.append(_precision_row(int8, batch, i8, plain, reduced - exact))
        rows += [
            {
                "what": f"bundled model decode, {fmt}-rounded weights in float32 ({fmt}'s best accuracy)",
                "batch": batch,
                "max joint difference mm": _largest_mm(joints - exact),
            }
            for fmt, joints in rounded.items()
        ]
    return rows


def _kinematics(skeleton: Skeleton, config: OdmoConfig, rng: np.random.Generator) -> list[dict[str, object]]:
    """Time the bone projection, the foot clean-up and torch FK of 6D local rotations."""
    rows = []
    projection = BoneProjection(skeleton)
    offsets = torch.tensor(np.array(skeleton.offsets), dtype=torch.float32)
    feet = list(config.foot_joints)
    for batch in (1, 1024):
        joints = torch.as_tensor(
            rng.standard_normal((batch, config.window, N_JOINTS, 3)), dtype=torch.float32
        )
        d6 = torch.as_tensor(rng.standard_normal((batch, config.window, N_JOINTS, 6)), dtype=torch.float32)
        root = joints[..., 0, :]
        positions = projection(joints).numpy()
        contact = rng.random((batch, config.window, len(feet))) < 0.5
        repeats = 50 if batch == 1 else 5
        with torch.inference_mode():
            stages = {
                "bone projection (FK of bone directions, in the decoder)": lambda j=joints: projection(j),
                "torch FK of 6D local rotations, every frame at once": lambda d=d6, r=root: (
                    forward_kinematics(rotation_6d_to_matrix(d), offsets, skeleton.parents, r)
                ),
                "foot clean-up (plant_feet, half the foot frames planted)": lambda p=positions, c=contact: (
                    plant_feet(p, c, skeleton, feet, config.foot_heights, fps=config.fps)
                ),
            }
            for name, fn in stages.items():
                seconds = _timed(fn, repeats)
                rows.append({"what": f"stage: {name}", "batch": batch, "ms": round(seconds * 1e3, 2)})
    return rows


def _model_decodes(
    model: OdmoModel, what: str, batches: tuple[int, ...], rng: np.random.Generator, repeats: int
) -> list[dict[str, object]]:
    """Time ``model.decode`` of random codes, actions and ends under inference_mode at each batch size."""
    rows: list[dict[str, object]] = []
    for batch in batches:
        z = torch.as_tensor(rng.standard_normal((batch, model.config.latent_dim)), dtype=torch.float32)
        a = torch.as_tensor(rng.integers(0, N_ACTIONS, batch))
        e = torch.as_tensor(rng.standard_normal((batch, 3)), dtype=torch.float32)

        def run(z=z, a=a, e=e) -> None:
            with torch.inference_mode():
                model.decode(z, a, e)

        seconds = _timed(run, max(3, repeats // max(1, batch // 16)))
        rows.append(
            {"what": what, "batch": batch, "ms": round(seconds * 1e3, 2), "motions/s": round(batch / seconds)}
        )
    return rows


def _rotation_decodes(
    config: OdmoConfig, skeleton: Skeleton, rng: np.random.Generator, repeats: int
) -> list[dict]:
    """Time OdmoModel.decode of a rotation decoder (``pose_output`` "rotations": forward kinematics every
    frame of its free run) at batch 1 and 1024."""
    model = OdmoModel(dataclasses.replace(config, pose_output="rotations"), seed=0).eval()
    model.attach_skeleton(skeleton)
    what = "OdmoModel.decode, pose_output rotations (FK every frame; inference_mode)"
    return _model_decodes(model, what, (1, 1024), rng, repeats)


def main(argv: list[str] | None = None) -> int:
    """Measure and record the decode benchmark at one torch thread (the explorer's decode worker) and at
    ``--threads``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=50)
    args = parser.parse_args(argv)
    skeleton = bundled_skeleton()
    feet = tuple(foot_joints(skeleton))
    heights = tuple(0.04 if "Toe" in skeleton.names[j] else 0.11 for j in feet)
    config = OdmoConfig(n_actions=N_ACTIONS, n_joints=N_JOINTS, foot_joints=feet, foot_heights=heights)
    model = OdmoModel(config, seed=0).eval()
    loaded = _loaded(model, config, skeleton)
    rows = []
    for threads in sorted({1, args.threads}):
        torch.set_num_threads(threads)
        rng = np.random.default_rng(0)
        part = _decodes(loaded, rng, args.repeats) + _plain_modules(loaded, rng, args.repeats)
        part += _stages(model, rng, config)
        part += _kinematics(skeleton, config, rng) + _rotation_decodes(config, skeleton, rng, args.repeats)
        part += _reduced_precision(args.repeats)
        rows += [{"threads": threads} | row for row in part]
    for row in rows:
        print(row)
    record("decode", rows, f"python bench/decode.py --threads {args.threads} --repeats {args.repeats}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
