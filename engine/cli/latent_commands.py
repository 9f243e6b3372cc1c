"""``odmo edit | mix | crowd | invert``: operations in a model's latent space, each refused in one line by
a model that lacks the capability."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from engine.cli.model_commands import ENDPOINT_HELP, endpoint_code, motion_outputs, write_samples
from engine.cli.options import add_up_axis, positive_int
from engine.errors import ConfigError
from engine.limits import check_count

if TYPE_CHECKING:
    from engine.generators import Generator


def _open(args: argparse.Namespace, capability: str, needs_action: bool = True) -> Generator:
    from engine.generators import open_generator, require

    generator = open_generator(args.model)
    require(generator, capability)
    if needs_action and getattr(args, "action", None) is None and generator.action_names is not None:
        raise ConfigError(f"{args.model}: name an --action: {', '.join(generator.action_names)}")
    return generator


def _cmd_edit(args: argparse.Namespace) -> int:
    generator = _open(args, "edit", needs_action=not args.list)
    directions = generator.edit_directions
    if args.list:
        for name, d in directions.items():
            print(f"{name}\tscore {d.score:.3f}\tspread {d.scale:.4g}\tcodes {d.n_codes}")
        return 0
    if args.code is None or args.direction is None or args.out is None:
        raise ConfigError("give --code, --direction and --out (or --list to see the directions)")
    check_count("--steps", args.steps)
    code = endpoint_code(generator, args.code, args.action)
    amounts = np.linspace(0.0, args.amount, args.steps) if args.steps > 1 else [args.amount]
    with motion_outputs(args.out, len(amounts), f"edit_{args.direction.replace('=', '-')}") as paths:
        samples = [generator.edit(code, args.action, args.direction, float(a)) for a in amounts]
        write_samples(samples, paths)
    return 0


def _cmd_mix(args: argparse.Namespace) -> int:
    generator = _open(args, "mix")
    a, b = (endpoint_code(generator, text, None) for text in (args.coarse, args.fine))
    with motion_outputs(args.out, 1, "mix") as paths:
        write_samples([generator.mix(a, b, args.split)], paths)
    return 0


def _cmd_crowd(args: argparse.Namespace) -> int:
    check_count("--n", args.n)
    generator = _open(args, "crowd")
    code = endpoint_code(generator, args.code, None)
    with motion_outputs(args.out, args.n, "crowd") as paths:
        write_samples(generator.crowd(code, args.n, args.sigma, args.seed), paths)
    return 0


def _cmd_invert(args: argparse.Namespace) -> int:
    from engine.motion.formats import read_motion

    generator = _open(args, "invert")
    motion = read_motion(args.file, up_axis=args.up_axis)
    bar = tqdm(total=args.steps, desc="inverting", file=sys.stderr, disable=args.json)

    def report(step: int, steps: int, error: float) -> None:
        bar.update(1)
        bar.set_postfix_str(f"{100 * error:.1f} cm", refresh=False)

    try:
        code, error = generator.invert(motion, args.space, args.steps, progress=report)
    finally:
        bar.close()
    if args.out is not None:
        [shown] = generator.decode(code[None])
        with motion_outputs(args.out, 1, "inverted") as paths:
            from engine.generate import Sample

            write_samples([Sample(code, -1, -1, None, shown)], paths)
    result = {"file": str(args.file), "space": args.space, "steps": args.steps, "error_m": round(error, 5)}
    if args.json:
        print(json.dumps(result | {"code": [round(float(v), 6) for v in code]}))
    else:
        print(f"{args.file}: {args.space} code of {len(code)} values, mean joint error {100 * error:.2f} cm")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the latent-space sub-commands to ``odmo``."""
    out_help = "a .npz/.bvh/.npy file (numbered if several) or a folder"
    p = subparsers.add_parser(
        "edit", help="move a code along a semantic edit direction (style, speed, energy)"
    )
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--list", action="store_true", help="list the directions with their scores")
    p.add_argument("--action", help="the code's action (a conditional model needs one)")
    p.add_argument("--code", metavar="mN|iN", help=ENDPOINT_HELP)
    p.add_argument("--direction", help="e.g. style=elderly, speed, energy (see --list)")
    p.add_argument("--amount", type=float, default=2.0, help="spreads of the codes to move (2)")
    p.add_argument("--steps", type=positive_int, default=1, help="motions from 0 to --amount (1: just it)")
    p.add_argument("--out", type=Path, help=out_help)
    p.set_defaults(func=_cmd_edit)

    p = subparsers.add_parser("mix", help="style mixing: one code's coarse levels with another's fine ones")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--coarse", required=True, metavar="iN", help="bank code giving the coarse levels")
    p.add_argument("--fine", required=True, metavar="iN", help="bank code giving the fine levels")
    p.add_argument("--split", type=int, default=2, help="levels taken from --coarse (2)")
    p.add_argument("--out", type=Path, required=True, help=out_help)
    p.set_defaults(func=_cmd_mix)

    p = subparsers.add_parser("crowd", help="a crowd of variations: codes drawn from N(code, sigma²)")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--code", required=True, metavar="iN", help="bank code at the crowd's centre")
    p.add_argument("--n", type=int, default=8, help="how many motions (8)")
    p.add_argument("--sigma", type=float, default=0.3, help="spread of the codes (0.3)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, required=True, help=out_help)
    p.set_defaults(func=_cmd_crowd)

    p = subparsers.add_parser("invert", help="find the code of a motion file by optimisation")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("file", type=Path, help="motion file (BVH, NPZ, NPY)")
    add_up_axis(p)
    p.add_argument("--space", choices=("W", "W+"), default="W+", help="code space searched (W+)")
    p.add_argument("--steps", type=positive_int, default=300, help="optimisation steps (300)")
    p.add_argument("--out", type=Path, help="also write the inverted motion here")
    p.add_argument("--json", action="store_true", help="print one JSON object with the code")
    p.set_defaults(func=_cmd_invert)
