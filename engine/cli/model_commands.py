"""``odmo train | bank | sample | interpolate | encode | complete``: the model commands."""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from tqdm import tqdm

from engine.cli.options import add_up_axis, positive_int
from engine.errors import ConfigError, DataError
from engine.fileio import folder_lock
from engine.limits import check_count

if TYPE_CHECKING:
    from engine.generate import Sample
    from engine.generators import Generator
    from engine.motion.datasets import Dataset
    from engine.train.distributed import Ranks
    from engine.train.epochs import TrainProgress

# torch and the model code are imported inside the commands, so that `odmo --help` stays quick.

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


@contextlib.contextmanager
def motion_outputs(out: Path, n: int, stem: str) -> Iterator[list[Path]]:
    """Where ``n`` motions go; several files keep their folder locked for the whole command, so that a
    second writer into it fails at once instead of overwriting them."""
    paths = output_paths(out, n, stem)
    if len(paths) == 1:
        yield paths
        return
    with folder_lock(paths[0].parent, "writing motions"):
        yield paths


def write_samples(samples: list[Sample], paths: list[Path]) -> None:
    from engine.motion.formats import write_motion

    for s, path in zip(samples, paths, strict=True):
        write_motion(s.motion, path)
        mode = "" if s.mode < 0 else f" mode {s.mode}"
        print(f"{path}{mode}")


def endpoint_code(generator: Generator, text: str, action: str | None) -> np.ndarray:
    """The code named by ``text`` (see ENDPOINT_HELP) among the bank codes of ``action`` (any bank code,
    and no mode means, when ``action`` is None: an unconditional model)."""
    match = _ENDPOINT_RE.match(text.strip())
    if match is None:
        raise ConfigError(f"bad endpoint {text!r}: {ENDPOINT_HELP}")
    bank = generator.bank
    if bank is None:
        raise ConfigError(f"{generator.path}: the model has no latent bank (run `odmo bank`)")
    kind, number = match.group(1), int(match.group(2))
    if action is None:
        if kind == "m":
            raise ConfigError(f"endpoint {text!r}: a mode belongs to an action; name it with --action")
        if number >= len(bank.codes):
            raise ConfigError(f"the latent bank has codes i0..i{len(bank.codes) - 1}")
        return np.asarray(bank.codes[number], dtype=np.float32)
    names = bank.action_names
    if action not in names:
        raise ConfigError(f"unknown action {action!r}; the model knows: {', '.join(names)}")
    index = names.index(action)
    if kind == "m":
        if index not in bank.modes:
            raise ConfigError(f"action {action!r} has no modes in the latent bank")
        means = bank.modes[index].means_
        if number >= len(means):
            raise ConfigError(f"action {action!r} has modes m0..m{len(means) - 1}")
        return np.asarray(means[number], dtype=np.float32)
    if number >= len(bank.codes):
        raise ConfigError(f"the latent bank has codes i0..i{len(bank.codes) - 1}")
    if int(bank.actions[number]) != index:
        owner = bank.action_names[int(bank.actions[number])]
        raise ConfigError(f"bank code i{number} is a {owner!r} code, not {action!r}")
    return np.asarray(bank.codes[number], dtype=np.float32)


def _end(args: argparse.Namespace) -> np.ndarray | None:
    if args.end is None:
        return None
    if not np.all(np.isfinite(args.end)) or np.max(np.abs(args.end)) > 1e3:
        raise ConfigError(f"--end must be two finite numbers of metres (at most 1000), got {args.end}")
    return np.asarray(args.end, dtype=np.float32)


class TqdmProgress:
    """A tqdm bar fed by ``engine.train.loop.TrainProgress`` reports (loss terms, steps/s, ETA)."""

    def __init__(self) -> None:
        self.bar: tqdm | None = None  # drawn at the first report: an error before it prints one line alone
        self.stage = ""

    def __call__(self, report: TrainProgress) -> None:
        """Show one report."""
        if self.bar is None:
            self.bar = tqdm(total=1.0, unit="run", bar_format=_BAR, file=sys.stderr)
        if report.stage != self.stage:
            self.stage = report.stage
            self.bar.reset(total=1.0)
        self.bar.n = report.fraction
        if report.stage == "train":
            losses = " ".join(f"{k}={v:.3g}" for k, v in report.losses.items())
            self.bar.set_description(f"epoch {report.epoch}/{report.epochs}", refresh=False)
            self.bar.set_postfix_str(f"{losses} | {report.steps_per_s:.1f} steps/s", refresh=False)
        else:
            self.bar.set_description(f"latent bank: {report.message}", refresh=False)
            self.bar.set_postfix_str("", refresh=False)
        self.bar.refresh()

    def close(self) -> None:
        """Close the bar, if it was drawn."""
        if self.bar is not None:
            self.bar.close()


_BAR = "{desc}: {percentage:3.0f}%|{bar}| [{elapsed}<{remaining}] {postfix}"


def config_overrides(pairs: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` strings as config fields, values parsed as JSON when they can be (else strings)."""
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError(f"bad --set {pair!r}; expected KEY=VALUE")
        try:
            out[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            out[key.strip()] = value
    return out


def _dataset(args: argparse.Namespace) -> Dataset:
    from engine.motion.datasets import load_folder

    return load_folder(args.data, pattern=args.pattern, labels=args.labels, up_axis=args.up_axis)


def _trainer(arch: str) -> tuple[type, Callable[..., Any]]:
    """The config class and the ``train`` function of a kind (imported here: they bring in torch)."""
    if arch == "a2m":
        from engine.model.a2m import A2mConfig
        from engine.train.a2m_loop import train_a2m

        return A2mConfig, train_a2m
    if arch == "modi":
        from engine.model.modi import ModiConfig
        from engine.train.modi_loop import train_modi

        return ModiConfig, train_modi
    if arch == "dvgan":
        from engine.model.dvgan import DvganConfig
        from engine.train.dvgan_loop import train_dvgan

        return DvganConfig, train_dvgan
    from engine.model.config import OdmoConfig
    from engine.train.loop import train

    return OdmoConfig, train


def _cmd_train(args: argparse.Namespace) -> int:
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"{args.out}: exists and is not a folder; --out names the model folder to write")
    from engine.train.distributed import finish

    ranks = _ranks(args)
    dataset = _dataset(args)
    fields = {"n_actions": len(dataset.action_names), "n_joints": dataset.skeleton.n_joints}
    fields |= config_overrides(args.set)
    if args.epochs is not None:
        fields["epochs"] = args.epochs
    config_type, train = _trainer(args.arch)
    try:
        config = config_type(**fields)
    except TypeError as exc:
        raise ConfigError(f"bad {args.arch} setting: {exc}") from None
    started = {} if args.warm_start is None else {"warm_start": _warm_start(args.arch, args.warm_start)}
    progress = TqdmProgress() if ranks.is_main else None
    try:
        with folder_lock(args.out, "training a model") if ranks.is_main else contextlib.nullcontext():
            result = train(
                dataset.clips,
                dataset.action_names,
                args.out,
                config,
                seed=args.seed,
                device=args.device,
                resume=args.resume,
                progress=progress,
                bank_projections=args.projections,
                **started,
                **({"ranks": ranks} if ranks.distributed else {}),
            )
    finally:
        if progress is not None:
            progress.close()
        finish(ranks)
    if ranks.is_main:
        losses = " ".join(f"{k}={v:.4g}" for k, v in result.train_losses.items())
        print(f"{result.model_dir}: {result.epochs} epochs, {result.train_seconds:.1f} s, {losses}")
    return 0


def _warm_start(arch: str, folder: Path) -> Any:
    """The weights of the ``arch`` model folder ``folder`` to start training from; ConfigError for a kind
    that does not start from saved weights."""
    from engine.train.kind_run import WarmStart

    if arch == "a2m":
        from engine.generators.a2m import load_a2m as load
    elif arch == "odmo":
        from engine.modelio import load_model as load
    elif arch == "dvgan":
        from engine.generators.dvgan import load_dvgan as load
    else:
        raise ConfigError(
            f"--warm-start: --arch {arch} trains from its initialisation only "
            "(odmo, a2m and dvgan start from weights)"
        )
    return WarmStart.from_folder(folder, load)


def _ranks(args: argparse.Namespace) -> Ranks:
    """The processes torchrun started for this training (one without torchrun); ConfigError for a kind
    that trains in one process only."""
    from engine.modelio import resolve_device
    from engine.train.distributed import start

    ranks = start(resolve_device(args.device))
    if ranks.distributed and args.arch != "odmo":
        raise ConfigError(f"--arch {args.arch} trains in one process; torchrun trains --arch odmo only")
    return ranks


def _cmd_bank(args: argparse.Namespace) -> int:
    with folder_lock(args.model, "writing the model folder"):
        return _bank_locked(args)


def _bank_locked(args: argparse.Namespace) -> int:
    from engine.generators import open_generator, require
    from engine.latent.bank import build_bank
    from engine.latent.columns import MetaColumns
    from engine.modelio import save_bank
    from engine.motion.datasets import open_folder

    loaded = open_generator(args.model, with_bank=False)  # a damaged bank must not stop its rebuild
    require(loaded, "encode", "build a latent bank (it cannot encode clips into codes)")
    names = loaded.label_names
    clips = open_folder(args.data, pattern=args.pattern, labels=args.labels, up_axis=args.up_axis)
    labels = [clips.label(k) for k in range(len(clips))]
    unknown = sorted({action for action, _ in labels} - set(names))
    if unknown:
        raise DataError(f"{args.data}: actions {unknown} are not the model's {names}")
    with tqdm(total=0, unit="window", desc="encoding (reading clips one at a time)", file=sys.stderr) as bar:

        def encoded(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        codes, ends, owners, starts = loaded.encode_bank(clips, args.stride, progress=encoded)
    # One label per clip, indexed by each code's clip: no dict or name string per window.
    extra = {}
    if starts is not None:
        extra = {"window_stride": np.full(len(starts), args.stride), "window_start": starts}
    progress = tqdm(total=1.0, bar_format=_BAR, file=sys.stderr)
    try:

        def report(message: str, fraction: float) -> None:
            progress.n = fraction
            progress.set_description(message)

        bank = build_bank(
            codes,
            np.array([names.index(action) for action, _ in labels], dtype=np.int64)[owners],
            ends,
            np.asarray([meta["source"] for _, meta in labels], dtype=object)[owners],
            MetaColumns.from_table([meta for _, meta in labels], owners, extra),
            names,
            projections=args.projections,
            seed=args.seed,
            progress=report,
        )
    finally:
        progress.close()
    path = save_bank(loaded.path, bank)
    sizes = ", ".join(f"{names[a]}: {m.n_modes_}" for a, m in sorted(bank.modes.items()))
    print(f"{path}: {len(codes)} codes; modes {sizes}")
    return 0


def _cmd_sample(args: argparse.Namespace) -> int:
    from engine.generators import SampleRequest, open_generator, require

    check_count("--n", args.n)
    request = SampleRequest(
        args.action, args.n, args.seed, args.strategy, args.mode, _end(args), truncation=args.truncation
    )
    with motion_outputs(args.out, args.n, args.action or "sample") as paths:
        generator = open_generator(args.model)
        if args.truncation != 1.0:
            require(generator, "truncate")
        if args.action is None and generator.action_names is not None:
            raise ConfigError(f"{args.model}: name an --action: {', '.join(generator.action_names)}")
        if args.frames is None:
            write_samples(generator.sample(request), paths)
        else:
            require(generator, "extend", f"make {args.frames}-frame motions")
            write_samples(generator.sample(request, frames=args.frames), paths)
    return 0


def _cmd_complete(args: argparse.Namespace) -> int:
    from engine.generators import open_generator, require
    from engine.motion.formats import read_motion, write_motion

    check_count("--n", args.n)
    with motion_outputs(args.out, args.n, f"{args.prefix.stem}_completed") as paths:
        generator = open_generator(args.model)
        require(generator, "complete")
        prefix = read_motion(args.prefix, up_axis=args.up_axis)
        if args.prefix_frames is not None:
            prefix = prefix.with_joints(prefix.joints[: args.prefix_frames])
        for motion, path in zip(
            generator.complete(prefix, args.frames, args.n, args.seed, args.action), paths, strict=True
        ):
            write_motion(motion, path)
            print(f"{path} ({motion.meta['prefix_frames']} prefix + {args.frames} frames)")
    return 0


def _cmd_interpolate(args: argparse.Namespace) -> int:
    from engine.generators import open_generator, require

    check_count("--steps", args.steps)
    with motion_outputs(args.out, args.steps, f"{args.action or 'code'}_{args.from_}_{args.to}") as paths:
        generator = open_generator(args.model)
        require(generator, "interpolate")
        if args.action is None and generator.action_names is not None:
            raise ConfigError(f"{args.model}: name an --action: {', '.join(generator.action_names)}")
        a, b = (endpoint_code(generator, text, args.action) for text in (args.from_, args.to))
        write_samples(generator.interpolate(a, b, args.action, args.steps, method=args.method), paths)
    return 0


def _cmd_encode(args: argparse.Namespace) -> int:
    from engine.generators import open_generator, require
    from engine.motion.formats import read_motion

    generator = open_generator(args.model)
    require(generator, "encode")
    motion = read_motion(args.file, up_axis=args.up_axis)
    code, guess = generator.encode(motion)
    bank, mode = generator.bank, None
    if guess is not None and bank is not None and guess in bank.modes:
        mode = int(bank.modes[guess].predict(code[None])[0])
    report = {
        "file": str(args.file),
        "code": [round(float(v), 6) for v in code],
        "action": None if guess is None else generator.label_names[guess],
        "mode": mode,
    }
    if args.json:
        print(json.dumps(report))
    else:
        print(f"code: {' '.join(f'{v:.4f}' for v in code)}")
        print(f"action guess: {report['action'] or 'unknown (no latent bank)'}")
        print(f"nearest mode: {'-' if mode is None else mode}")
    return 0


def _data_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--data", type=Path, required=True, help="dataset folder")
    p.add_argument("--pattern", help="regex with a named group 'action' that labels file names")
    p.add_argument("--labels", type=Path, help="CSV/JSON label sidecar (file,action[,style])")
    add_up_axis(p)
    p.add_argument(
        "--projections",
        type=lambda text: tuple(x for x in text.split(",") if x),
        default=("pca", "tsne", "umap"),
        help="comma-separated latent maps to fit (default pca,tsne,umap)",
    )


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the model sub-commands to ``odmo``."""
    p = subparsers.add_parser("train", help="train a model (ODMO, Action2Motion, MoDi, DVGAN)")
    _data_arguments(p)
    p.add_argument("--out", type=Path, required=True, help="model folder to write")
    p.add_argument("--epochs", type=int, default=None, help="epochs of 2,048 windows (default: config's)")
    p.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"))
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resume", action="store_true", help="continue from the folder's last checkpoint")
    p.add_argument(
        "--warm-start",
        type=Path,
        metavar="FOLDER",
        help="start from this model folder's weights (a fine-tune; odmo, a2m and dvgan): the settings may "
        "change the loss weights and schedule, not the sizes",
    )
    p.add_argument(
        "--arch",
        default="odmo",
        choices=("odmo", "a2m", "modi", "dvgan"),
        help="odmo (default), a2m, modi or dvgan",
    )
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="any model setting")
    p.set_defaults(func=_cmd_train)

    p = subparsers.add_parser(
        "bank", help="rebuild a model's latent bank (codes, modes, maps) from a dataset"
    )
    p.add_argument("--model", type=Path, required=True, help="model folder")
    _data_arguments(p)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--stride",
        type=positive_int,
        default=None,
        metavar="FRAMES",
        help="a code for every window every FRAMES frames at the model's rate, so a long clip is a path "
        "on the map (default: one code per clip, its centre window)",
    )
    p.set_defaults(func=_cmd_bank)

    p = subparsers.add_parser("sample", help="sample motions (of one action, for a conditional model)")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument(
        "--action", help="action name (a conditional model needs one; MoDi: sample that label's modes)"
    )
    p.add_argument(
        "--truncation",
        type=float,
        default=1.0,
        metavar="PSI",
        help="pull each draw towards the mean it came from (MoDi's W, Action2Motion's prior; 1: none)",
    )
    p.add_argument("--mode", type=int, default=None, help="sample only this mode (overrides --strategy)")
    p.add_argument("--n", type=int, default=1, help="how many motions")
    p.add_argument(
        "--frames",
        type=positive_int,
        default=None,
        help="frames per motion (default: the model's window; "
        "longer ones from a model that extends motions, DVGAN's RNN)",
    )
    p.add_argument("--end", type=float, nargs=2, metavar=("X", "Z"), help="end location on the floor, metres")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--strategy",
        choices=("mode_preserving", "conventional", "prior"),
        help="ODMO: mode_preserving (default) or conventional; Action2Motion and MoDi: prior (default) or "
        "the bank's modes",
    )
    p.add_argument(
        "--out", type=Path, required=True, help="a .npz/.bvh/.npy file (numbered if N > 1) or a folder"
    )
    p.set_defaults(func=_cmd_sample)

    p = subparsers.add_parser(
        "interpolate",
        help="decode the codes between two endpoints of one action",
        description=f"Endpoints: {ENDPOINT_HELP}.",
    )
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--action", help="action name (a conditional model needs one)")
    p.add_argument("--from", dest="from_", required=True, metavar="mN|iN", help=ENDPOINT_HELP)
    p.add_argument("--to", required=True, metavar="mN|iN", help=ENDPOINT_HELP)
    p.add_argument("--steps", type=int, default=8, help="motions, endpoints included")
    p.add_argument("--method", default="linear", choices=("linear", "slerp"))
    p.add_argument("--out", type=Path, required=True, help="a .npz/.bvh/.npy file (numbered) or a folder")
    p.set_defaults(func=_cmd_interpolate)

    p = subparsers.add_parser("encode", help="print the latent code of a motion file, its action and mode")
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("file", type=Path, help="motion file (BVH, NPZ, NPY)")
    add_up_axis(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_encode)

    p = subparsers.add_parser(
        "complete", help="continue the frames of a motion file several ways (DVGAN's RNN)"
    )
    p.add_argument("--model", type=Path, required=True, help="model folder")
    p.add_argument("--prefix", type=Path, required=True, help="motion file (BVH, NPZ, NPY) to continue")
    p.add_argument(
        "--prefix-frames",
        type=positive_int,
        default=None,
        help="use only its first FRAMES frames (at the file's rate)",
    )
    p.add_argument("--frames", type=positive_int, required=True, help="frames to add, at the model's rate")
    p.add_argument("--n", type=int, default=1, help="how many continuations")
    p.add_argument("--action", help="action phrase (default: the file's label)")
    p.add_argument("--seed", type=int, default=0)
    add_up_axis(p)
    p.add_argument("--out", type=Path, required=True, help="a .npz/.bvh/.npy file (numbered) or a folder")
    p.set_defaults(func=_cmd_complete)
