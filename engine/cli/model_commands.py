"""``odmo train | bank | sample | interpolate | encode``: the model commands."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from engine.errors import ConfigError
from engine.generate import action_index, encode, interpolate, sample
from engine.generate import Sample as GeneratedSample
from engine.modelio import LoadedModel, load_model
from engine.motion.motion import Motion

MOTION_SUFFIXES = (".npz", ".bvh", ".npy")
ENDPOINT_HELP = (
    "an interpolation endpoint: 'mN' = mean of mode N of the action (m0, m1, ...), "
    "'iN' = code N of the latent bank (its index on the latent map; it must belong to the action)"
)
_ENDPOINT_RE = re.compile(r"^([mi])(\d+)$")


def output_paths(out: Path, n: int, stem: str) -> list[Path]:
    """Where ``n`` motions go: ``out`` itself, numbered siblings of a file name, or files in a folder."""
    if out.suffix.lower() in MOTION_SUFFIXES:
        if n == 1:
            return [out]
        return [out.with_name(f"{out.stem}_{i:03d}{out.suffix}") for i in range(n)]
    if out.suffix:
        raise ConfigError(f"{out}: unknown motion format {out.suffix!r}; use {', '.join(MOTION_SUFFIXES)}")
    return [out / f"{stem}_{i:03d}.npz" for i in range(n)]


def _write(samples: list[GeneratedSample], out: Path, stem: str) -> None:
    for s, path in zip(samples, output_paths(out, len(samples), stem), strict=True):
        s.motion.save(path)
        mode = "" if s.mode < 0 else f" mode {s.mode}"
        print(f"{path}{mode}")


def endpoint_code(loaded: LoadedModel, text: str, action: int) -> np.ndarray:
    """The (D,) code named by ``text`` (see ENDPOINT_HELP)."""
    match = _ENDPOINT_RE.match(text.strip())
    if match is None:
        raise ConfigError(f"bad endpoint {text!r}: {ENDPOINT_HELP}")
    bank = loaded.bank
    if bank is None:
        raise ConfigError(f"{loaded.path}: the model has no latent bank (run `odmo bank`)")
    kind, number = match.group(1), int(match.group(2))
    if kind == "m":
        means = bank.modes[action].means
        if number >= len(means):
            raise ConfigError(f"action {loaded.action_names[action]!r} has modes m0..m{len(means) - 1}")
        return np.asarray(means[number], dtype=np.float32)
    if number >= len(bank.codes):
        raise ConfigError(f"the latent bank has codes i0..i{len(bank.codes) - 1}")
    if int(bank.actions[number]) != action:
        owner = bank.action_names[int(bank.actions[number])]
        raise ConfigError(f"bank code i{number} is a {owner!r} code, not {loaded.action_names[action]!r}")
    return np.asarray(bank.codes[number], dtype=np.float32)


def _end(args: argparse.Namespace) -> np.ndarray | None:
    return None if args.end is None else np.asarray(args.end, dtype=np.float32)


def _cmd_train(args: argparse.Namespace) -> int:
    from engine.cli._train_progress import TqdmProgress
    from engine.model.config import OdmoConfig
    from engine.motion.datasets import load_folder
    from engine.train.loop import train

    dataset = load_folder(args.data)
    config = OdmoConfig(n_actions=len(dataset.action_names), n_joints=dataset.skeleton.n_joints, arch=args.arch)
    if args.epochs is not None:
        config = OdmoConfig.from_dict({**config.to_dict(), "epochs": args.epochs})
    with TqdmProgress(config.epochs) as progress:
        result = train(
            dataset.clips,
            dataset.action_names,
            args.out,
            config,
            seed=args.seed,
            device=args.device,
            resume=args.resume,
            progress=progress,
        )
    print(f"{args.out}: {result}")
    return 0


def _cmd_sample(args: argparse.Namespace) -> int:
    loaded = load_model(args.model)
    strategy = "mode" if args.mode is not None else args.strategy
    samples = sample(loaded, args.action, args.n, args.seed, strategy=strategy, mode=args.mode, end=_end(args))
    _write(samples, args.out, args.action)
    return 0


def _cmd_interpolate(args: argparse.Namespace) -> int:
    loaded = load_model(args.model)
    action = action_index(loaded, args.action)
    a, b = (endpoint_code(loaded, text, action) for text in (args.from_, args.to))
    samples = interpolate(loaded, a, b, action, args.steps, method=args.method)
    _write(samples, args.out, f"{args.action}_{args.from_}_{args.to}")
    return 0


def _cmd_encode(args: argparse.Namespace) -> int:
    loaded = load_model(args.model)
    motion = Motion.from_file(args.file)
    code, guess = encode(loaded, motion)
    mode = None
    if guess is not None and loaded.bank is not None and guess in loaded.bank.modes:
        mode = int(loaded.bank.modes[guess].predict(code[None])[0])
    report = {
        "file": str(args.file),
        "code": [round(float(v), 6) for v in code],
        "action": None if guess is None else loaded.action_names[guess],
        "mode": mode,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"code: {' '.join(f'{v:.4f}' for v in code)}")
        print(f"action guess: {report['action'] or 'unknown (no latent bank)'}")
        print(f"nearest mode: {'-' if mode is None else mode}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the model sub-commands to ``odmo``."""
    p = subparsers.add_parser("train", help="train an ODMO model on a folder of labelled clips")
    p.add_argument("--data", type=Path, required=True, help="dataset folder")
    p.add_argument("--out", type=Path, required=True, help="model folder to write")
    p.add_argument("--epochs", type=int, default=None, help="epochs of 2,048 windows (default: config's)")
    p.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resume", action="store_true", help="continue from the folder's last checkpoint")
    p.add_argument("--arch", default="odmo", choices=("odmo",))
    p.set_defaults(func=_cmd_train)

    p = subparsers.add_parser("sample", help="sample motions of one action from its discovered modes")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--action", required=True, help="action name")
    p.add_argument("--mode", type=int, default=None, help="sample only this mode (implies --strategy mode)")
    p.add_argument("--n", type=int, default=1, help="how many motions")
    p.add_argument("--end", type=float, nargs=2, metavar=("X", "Z"), help="end location on the floor, metres")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--strategy", default="mode_preserving", choices=("mode_preserving", "conventional"))
    p.add_argument("--out", type=Path, required=True, help="a .npz/.bvh/.npy file (numbered if N > 1) or a folder")
    p.set_defaults(func=_cmd_sample)

    p = subparsers.add_parser(
        "interpolate",
        help="decode the codes between two endpoints of one action",
        description=f"Endpoints: {ENDPOINT_HELP}.",
    )
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--action", required=True, help="action name")
    p.add_argument("--from", dest="from_", required=True, metavar="mN|iN", help=ENDPOINT_HELP)
    p.add_argument("--to", required=True, metavar="mN|iN", help=ENDPOINT_HELP)
    p.add_argument("--steps", type=int, default=8, help="motions, endpoints included")
    p.add_argument("--method", default="linear", choices=("linear", "slerp"))
    p.add_argument("--out", type=Path, required=True, help="a .npz/.bvh/.npy file (numbered) or a folder")
    p.set_defaults(func=_cmd_interpolate)

    p = subparsers.add_parser("encode", help="print the latent code of a motion file, its action and mode")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("file", type=Path, help="motion file (BVH, NPZ, NPY)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_encode)
