"""``odmo info`` and ``odmo convert``: inspect and convert motion files and dataset folders."""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path
from typing import Any

from engine.cli.options import add_up_axis
from engine.errors import ConfigError, MotionFormatError
from engine.motion.motion import Motion

_PICKLE_SUFFIXES = (".pkl", ".pickle")


def register(subparsers: Any) -> None:
    """Add the ``info`` and ``convert`` sub-commands."""
    info = subparsers.add_parser("info", help="describe a motion file or a dataset folder")
    info.add_argument("path", type=Path, help="a .bvh, .npz, .npy or .pkl file, or a dataset folder")
    info.add_argument("--pattern", help="for a folder: regex, named group 'action' labels file names")
    info.add_argument("--labels", type=Path, help="for a folder: CSV/JSON label sidecar (file,action[,...])")
    _add_reading_options(info)
    info.set_defaults(func=_info)

    convert = subparsers.add_parser("convert", help="convert between BVH, NPZ and .npy (with resampling)")
    convert.add_argument("input", type=Path, help="a .bvh, .npz or .npy file, or a HumanAct12 .pkl")
    convert.add_argument("output", type=Path, help="the output file (a folder for a .pkl input)")
    convert.add_argument("--fps", type=float, help="resample to this frame rate")
    convert.add_argument(
        "--to", choices=("npz", "bvh", "npy"), default="npz", help="output format of each clip of a .pkl"
    )
    convert.add_argument(
        "--drop-joints", nargs="+", default=(), metavar="NAME", help="remove these joints (e.g. joint_Root)"
    )
    _add_reading_options(convert)
    convert.set_defaults(func=_convert)


def _add_reading_options(parser: argparse.ArgumentParser) -> None:
    """Options that say how to read joints-only and pickled inputs."""
    parser.add_argument(
        "--skeleton",
        default="auto",
        help="skeleton of a .npy input: smpl24, smpl22, or auto (the one with as many joints; default)",
    )
    parser.add_argument("--input-fps", type=float, default=20.0, help="frame rate of a .npy or .pkl input")
    add_up_axis(parser)
    parser.add_argument(
        "--allow-pickle", action="store_true", help="allow reading a .pkl (data-only allow-list unpickler)"
    )


def _read_clips(path: Path, args: argparse.Namespace) -> list[Motion]:
    """The clip(s) in a motion file."""
    from engine.motion.axes import to_y_up
    from engine.motion.formats import read_motion
    from engine.motion.humanact12 import read_actor_pickle

    if not path.is_file():
        raise MotionFormatError("no such file", path)
    if path.suffix.lower() in _PICKLE_SUFFIXES:
        clips = read_actor_pickle(path, allow_pickle=args.allow_pickle, fps=args.input_fps)
        return [to_y_up(clip, args.up_axis) for clip in clips]
    if path.suffix.lower() == ".npy":
        return [read_motion(path, args.up_axis, skeleton=args.skeleton, fps=args.input_fps)]
    return [read_motion(path, args.up_axis)]


def _z_up_hint(motion: Motion) -> str | None:
    """A hint when ``motion`` stands along z once read (None otherwise)."""
    from engine.motion.axes import looks_z_up

    if not looks_z_up(motion):
        return None
    if "turned_from_up_axis" in motion.meta:
        return "the body stands along z after turning: if the file is Y-up, leave out --up-axis z"
    return "the body stands along z: if the file is Z-up, add --up-axis z"


def _up_axis_line(motion: Motion) -> str:
    """How ``motion`` was read: Y-up, turned from Z-up, or Y-up with a hint that it may be Z-up."""
    shown = (
        f"y (turned from {motion.meta['turned_from_up_axis']}-up)"
        if "turned_from_up_axis" in motion.meta
        else "y"
    )
    hint = _z_up_hint(motion)
    return shown if hint is None else f"{shown}; {hint}"


def _info(args: argparse.Namespace) -> int:
    """Print frames, fps, duration, joints, units and label of a file, or a folder's summary."""
    if args.path.is_dir():
        return _folder_info(args)
    clips = _read_clips(args.path, args)
    if len(clips) > 1:
        counts = Counter(c.action for c in clips)
        print(f"{args.path}: {len(clips)} clips, {sum(c.n_frames for c in clips)} frames")
        for action, n in sorted(counts.items()):
            print(f"  {action}: {n}")
        return 0
    m = clips[0]
    rotations = "yes" if m.local_rotations is not None else "no (joint positions only)"
    print(f"file:      {args.path}")
    print(f"frames:    {m.n_frames}")
    print(f"fps:       {m.fps:g}")
    print(f"duration:  {m.duration:.3f} s")
    print(f"joints:    {m.n_joints} (root {m.skeleton.names[m.skeleton.root]})")
    print(f"units:     {m.skeleton.units}")
    print(f"up axis:   {_up_axis_line(m)}")
    print(f"rotations: {rotations}")
    print(f"label:     {m.action or '-'}")
    return 0


def _folder_info(args: argparse.Namespace) -> int:
    """Print a dataset folder's clips per action, total frames and fingerprint."""
    from tqdm import tqdm

    from engine.motion.datasets import load_folder

    with tqdm(desc="loading", unit="clip", leave=False) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        data = load_folder(
            args.path, pattern=args.pattern, labels=args.labels, progress=progress, up_axis=args.up_axis
        )
    counts = Counter(c.action for c in data.clips)
    frames = sum(c.n_frames for c in data.clips)
    print(f"folder:      {data.root} ({data.layout} layout)")
    print(f"clips:       {len(data.clips)} ({frames} frames)")
    print(f"joints:      {data.skeleton.n_joints} (root {data.skeleton.names[data.skeleton.root]})")
    print(f"fingerprint: {data.fingerprint}")
    for action in data.action_names:
        print(f"  {action}: {counts.get(action, 0)}")
    return 0


def _convert(args: argparse.Namespace) -> int:
    """Convert one file (or each clip of a pickle into a folder), optionally resampled."""
    from engine.motion.formats import SUPPORTED, write_motion

    clips = _read_clips(args.input, args)
    from_pickle = args.input.suffix.lower() in _PICKLE_SUFFIXES
    if not from_pickle and args.output.suffix.lower() not in SUPPORTED:
        raise ConfigError(f"output must end in one of {', '.join(SUPPORTED)}: {args.output}")
    if args.fps is not None and not 0 < args.fps <= 10000:
        raise ConfigError(f"--fps must be in (0, 10000], got {args.fps}")
    for i, motion in enumerate(clips):
        if args.drop_joints:
            unknown = sorted(set(args.drop_joints) - set(motion.skeleton.names))
            if unknown:
                raise ConfigError(f"no joint named {', '.join(unknown)}")
            motion = motion.without_joints(args.drop_joints)
        if args.fps is not None and abs(args.fps - motion.fps) > 1e-6:
            motion = motion.resample(args.fps)
        out = args.output / f"{i:04d}_{motion.action}.{args.to}" if from_pickle else args.output
        report = write_motion(motion, out)
        joints = report.get("joints", motion.n_joints)
        print(f"wrote {out}: {motion.n_frames} frames at {motion.fps:g} fps, {joints} joints")
        if (hint := _z_up_hint(motion)) is not None:
            print(f"  note: {hint}")
        if report.get("rotations_from") == "ik":
            print(
                f"  joints converted to rotations by IK: mean FK error {report['fk_error_m'] * 1000:.2f} mm"
            )
        if report.get("dropped_root"):
            print(f"  root {report['dropped_root']!r} changes length to its child: written without it")
    return 0
