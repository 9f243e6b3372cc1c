"""Property tests: random BVH files round-trip; mutated files fail only with MotionFormatError, quickly."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from engine.errors import MotionFormatError
from engine.motion.bvh import format_bvh, parse_bvh_text, read_bvh

ORDERS = ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"]
POSITIONS = ["Xposition", "Yposition", "Zposition"]


@st.composite
def bvh_files(draw: st.DrawFn) -> tuple[str, np.ndarray]:
    """A random valid BVH text (metres) and its joint positions computed independently here."""
    n_joints = draw(st.integers(1, 6))
    n_frames = draw(st.integers(1, 4))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    parents = [-1] + [int(rng.integers(0, j)) for j in range(1, n_joints)]
    offsets = rng.uniform(-1, 1, (n_joints, 3))
    layouts = []
    for j in range(n_joints):
        order = ORDERS[int(rng.integers(6))]
        channels = [f"{a}rotation" for a in order]
        if j == 0 or rng.random() < 0.3:
            channels += POSITIONS
            rng.shuffle(channels)
        # The rotation channels' listed order is the intrinsic order.
        layouts.append(("".join(c[0] for c in channels if c.endswith("rotation")), channels))
    values = {
        j: np.stack(
            [rng.uniform(*((-2, 2) if c in POSITIONS else (-180, 180)), n_frames) for c in channels], 1
        )
        for j, (_, channels) in enumerate(layouts)
    }

    lines = ["HIERARCHY"]
    order_dfs: list[int] = []

    def emit(j: int, depth: int) -> None:
        pad = "\t" * depth
        order_dfs.append(j)
        lines.append(f"{pad}{'ROOT' if j == 0 else 'JOINT'} j{j}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(repr(float(v)) for v in offsets[j])}")
        lines.append(f"{pad}  CHANNELS {len(layouts[j][1])} {' '.join(layouts[j][1])}")
        kids = [c for c in range(n_joints) if parents[c] == j]
        for c in kids:
            emit(c, depth + 1)
        if not kids:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0.1 0", f"{pad}  }}"])
        lines.append(f"{pad}}}")

    emit(0, 0)
    lines += ["MOTION", f"Frames: {n_frames}", "Frame Time: 0.0333333"]
    data = np.concatenate([values[j] for j in order_dfs], axis=1)
    lines += [" ".join(repr(float(v)) for v in row) for row in data]

    # Independent forward kinematics, joint by joint, in file order.
    expected = np.zeros((n_frames, n_joints, 3))
    for t in range(n_frames):
        world: dict[int, Rotation] = {}
        for j in order_dfs:
            order, channels = layouts[j]
            row = dict(zip(channels, values[j][t], strict=True))
            local = Rotation.from_euler(order, [row[f"{a}rotation"] for a in order], degrees=True)
            trans = np.array([row[p] for p in POSITIONS]) if "Xposition" in row else offsets[j]
            if parents[j] < 0:
                expected[t, j], world[j] = trans, local
            else:
                p = parents[j]
                expected[t, j] = expected[t, p] + world[p].apply(trans)
                world[j] = world[p] * local
    return "\n".join(lines) + "\n", expected[:, order_dfs]


@settings(max_examples=40, deadline=2000)
@given(bvh_files())
def test_random_files_match_independent_fk_and_round_trip(case: tuple[str, np.ndarray]) -> None:
    text, expected = case
    motion = parse_bvh_text(text, units="m")
    assert np.allclose(motion.joints, expected, atol=1e-4)
    back = parse_bvh_text(format_bvh(motion)[0], units="m") if motion.local_rotations is not None else None
    if back is not None:
        assert np.max(np.abs(back.joints - motion.joints)) < 1e-5


MUTATIONS = ["truncate", "token", "drop_line", "dup_line", "insert", "brace"]
BAD_TOKENS = [
    "nan",
    "inf",
    "-inf",
    "{",
    "}",
    "abc",
    "1e999",
    "JOINT",
    "End",
    "ROOT",
    "MOTION",
    "0x1f",
    "",
    "7 7",
]


@settings(max_examples=120, deadline=1000)
@given(bvh_files(), st.sampled_from(MUTATIONS), st.integers(0, 10**6), st.sampled_from(BAD_TOKENS))
def test_mutated_files_raise_only_motion_format_error(
    case: tuple[str, np.ndarray], mutation: str, where: int, token: str
) -> None:
    text = case[0]
    lines = text.split("\n")
    k = where % len(lines)
    if mutation == "truncate":
        text = text[: where % len(text)]
    elif mutation == "token":
        words = lines[k].split(" ")
        words[where % len(words)] = token
        lines[k] = " ".join(words)
        text = "\n".join(lines)
    elif mutation == "drop_line":
        text = "\n".join(lines[:k] + lines[k + 1 :])
    elif mutation == "dup_line":
        text = "\n".join(lines[: k + 1] + lines[k:])
    elif mutation == "insert":
        text = "\n".join([*lines[:k], token, *lines[k:]])
    else:
        text = text.replace("}", "", 1) if where % 2 else text.replace("{", "{ {", 1)
    try:
        parse_bvh_text(text, units="m")
    except MotionFormatError as exc:
        assert exc.path == "<string>"


@settings(max_examples=40, deadline=1000)
@given(st.binary(max_size=400))
def test_binary_garbage_raises_motion_format_error(blob: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "junk.bvh"
        path.write_bytes(blob)
        try:
            read_bvh(path)
        except MotionFormatError as exc:
            assert exc.path == str(path)
        else:
            raise AssertionError("random bytes parsed as a BVH file")
