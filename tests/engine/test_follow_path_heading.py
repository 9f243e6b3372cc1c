"""follow_path faces where the path goes, whatever its direction, and refuses paths no code can reach."""

from __future__ import annotations

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.generate import decode, decode_array, follow_path
from engine.generate._path import path_heading, turn_floor
from engine.modelio import LoadedModel, load_model
from engine.train.windows import canonicalize


@pytest.fixture(scope="module")
def loaded(tiny_model_dir) -> LoadedModel:
    """The tiny model with its latent bank."""
    return load_model(tiny_model_dir)


def _walk(loaded: LoadedModel) -> tuple[int, np.ndarray]:
    """The farthest-travelling action and the floor path of one of its bank codes."""
    bank = loaded.bank
    reach = [np.linalg.norm(bank.ends[bank.indices_of(a)][:, [0, 2]], axis=1).mean() for a in range(3)]
    action = int(np.argmax(reach))
    i = int(bank.indices_of(action)[3])
    _, trajectory = decode_array(loaded, bank.codes[i : i + 1], np.array([action]), bank.ends[i : i + 1])
    return action, trajectory[0][:, [0, 2]].astype(np.float64)


def test_turn_floor_and_heading_agree() -> None:
    path = np.stack([np.zeros(10), np.linspace(0, 2, 10)], axis=1)
    assert path_heading(path) == pytest.approx(0.0, abs=1e-9)
    back = turn_floor(path, np.pi)
    assert path_heading(back) == pytest.approx(np.pi, abs=1e-6) or path_heading(back) == pytest.approx(-np.pi)
    np.testing.assert_allclose(turn_floor(turn_floor(path, 0.7), -0.7), path, atol=1e-12)


@pytest.mark.parametrize("turn", [np.pi, np.pi / 2])
def test_a_path_drawn_backwards_or_sideways_is_walked_facing_forward(loaded, turn: float) -> None:
    action, path = _walk(loaded)
    drawn = turn_floor(path - path[0], turn) + np.array([0.5, -1.0])
    length = np.linalg.norm(np.diff(drawn, axis=0), axis=1).sum()
    result = follow_path(loaded, drawn, action, steps=40, seed=0)
    assert result.path_error_m < max(0.1 * length, 0.05)
    # the body keeps to the path the way the code's own motion keeps to its own path (a walker faces
    # where it goes, a side-stepper stays side-on) instead of facing +z whatever the direction
    i = int(loaded.bank.indices_of(action)[3])
    own = decode(loaded, loaded.bank.codes[i], action, loaded.bank.ends[i : i + 1])
    own_offset = canonicalize(own.joints[:1], own.skeleton)[1] - path_heading(path)
    facing = canonicalize(result.motion.joints[:1], result.motion.skeleton)[1]
    offset = facing - path_heading(drawn)
    assert abs(np.angle(np.exp(1j * (offset - own_offset)))) < np.radians(35)
    np.testing.assert_allclose(np.asarray(result.end)[[0, 2]], drawn[-1] - drawn[0], atol=1e-5)


def test_a_path_far_beyond_the_actions_reach_is_refused(loaded) -> None:
    action, _ = _walk(loaded)
    longest = np.linalg.norm(loaded.bank.ends[loaded.bank.indices_of(action)][:, [0, 2]], axis=1).max()
    far = np.stack([np.zeros(20), np.linspace(0, 4 * longest + 1.0, 20)], axis=1)
    with pytest.raises(ConfigError, match="unreachable"):
        follow_path(loaded, far, action, steps=5)
