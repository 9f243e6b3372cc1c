"""Arithmetic ceiling of decode and training speed: the model's matrix-product FLOPs at the default sizes
against the rate this CPU reaches on matrix products of the LSTMs' own shapes.

Run: ``python bench/ceiling.py [--threads 2]``. A multiply-add counts as 2 FLOP; only matrix products are
counted (gate nonlinearities, losses and the optimiser are left out), so the ceiling is an upper bound.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import torch

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._report import record
from engine.model.config import OdmoConfig
from engine.model.odmo import DECODE_SLICE

N_ACTIONS, N_JOINTS = 10, 21
AIMS = {"decode": 5000.0, "training": 300.0}


def linear_flops(rows: int, inputs: int, outputs: int) -> float:
    """FLOPs of a linear layer applied to ``rows`` vectors."""
    return 2.0 * rows * inputs * outputs


def lstm_flops(steps: int, inputs: int, hidden: int, layers: int) -> float:
    """FLOPs of the input and recurrent products of a stacked LSTM over ``steps`` frames of one sequence."""
    sizes = [inputs] + [hidden] * (layers - 1)
    return sum(2.0 * steps * 4 * hidden * (size + hidden) for size in sizes)


def decode_stages(c: OdmoConfig) -> dict[str, float]:
    """FLOPs per free-running decode of one motion, by stage."""
    t, h, cond, pose = c.window, c.traj_hidden, c.n_actions * c.latent_dim, c.n_joints * 3
    m = c.motion_hidden
    end = 3 if c.use_end_location else 0
    return {
        "trajectory generator": linear_flops(1, cond + end, h)
        + linear_flops(1, h, h)
        + lstm_flops(t - 1, h + 1, h, 2)
        + 3 * linear_flops(t - 1, h, h)
        + linear_flops(t - 1, h, 3),
        "trajectory encoder": linear_flops(t, 3, m) + lstm_flops(t, m, m, 2),
        "pose decoder": linear_flops(1, cond, m)
        + t * (linear_flops(1, m, m) + lstm_flops(1, m, m, 2))
        + linear_flops(t, m, pose),
    }


def training_window(c: OdmoConfig) -> float:
    """FLOPs per training window: forward and backward (twice the forward) of every part that carries a
    gradient, plus the no-grad teacher-forced pass that scheduled sampling mixes in."""
    t, m, pose = c.window, c.motion_hidden, c.n_joints * 3
    encoder = lstm_flops(t, pose, c.enc_hidden, 1) + linear_flops(1, c.enc_hidden, c.enc_fc)
    encoder += linear_flops(1, c.enc_fc, c.enc_fc) + linear_flops(1, c.enc_fc, 2 * c.latent_dim)
    stages = decode_stages(c)
    decoder = linear_flops(t, pose, m) + lstm_flops(t, m, m, 2) + linear_flops(t, m, pose)
    with_grad = encoder + stages["trajectory generator"] + stages["trajectory encoder"] + decoder
    return 3 * with_grad + decoder


def matmul_rate(rows: int, hidden: int, dtype: torch.dtype, seconds: float = 1.0) -> float:
    """GFLOP/s of (rows, H) @ (H, 4H), the shape of an LSTM's gate product, over ~``seconds``."""
    a = torch.randn(rows, hidden, dtype=dtype)
    b = torch.randn(hidden, 4 * hidden, dtype=dtype)
    for _ in range(5):
        a @ b
    count, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        a @ b
        count += 1
    return linear_flops(rows, hidden, 4 * hidden) * count / elapsed / 1e9


def best_rate(batch: int, config: OdmoConfig, dtype: torch.dtype) -> float:
    """The higher GFLOP/s of the recurrent product (batch rows) and the input product (batch·T rows)."""
    return max(matmul_rate(rows, config.motion_hidden, dtype) for rows in (batch, batch * config.window))


def main(argv: list[str] | None = None) -> int:
    """Measure the matrix-product rates and record the ceilings (decodes of 1,024 run in slices)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    config = OdmoConfig(n_actions=N_ACTIONS, n_joints=N_JOINTS)
    per_motion = sum(decode_stages(config).values())
    work = {
        "decode": (per_motion, min(DECODE_SLICE, 1024), "motions/s"),
        "training": (training_window(config), config.batch_size, "windows/s"),
    }
    rows = []
    for name, (flops, shape_rows, unit) in work.items():
        for dtype in (torch.float32, torch.bfloat16):
            rate = best_rate(shape_rows, config, dtype)
            ceiling = rate * 1e9 / flops
            rows.append(
                {
                    "what": name,
                    "MFLOP per item": round(flops / 1e6, 1),
                    "precision": str(dtype).removeprefix("torch."),
                    "batch": shape_rows,
                    "best matmul GFLOP/s": round(rate, 1),
                    "ceiling": f"{ceiling:,.0f} {unit}",
                    "aim": f"{AIMS[name]:,.0f}",
                }
            )
    for row in rows:
        print(row)
    record("Arithmetic ceiling", rows, f"python bench/ceiling.py --threads {args.threads}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
