"""follow_path: arc-length resampling and code optimisation through the trajectory generator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from engine.errors import ConfigError
from engine.generate import decode_array, follow_path, resample_path
from engine.modelio import LoadedModel, load_model

BUNDLED = Path(__file__).resolve().parents[2] / "resources" / "models" / "bandai2-odmo"


@pytest.fixture(scope="module")
def loaded(tiny_model_dir) -> LoadedModel:
    """The tiny model with its latent bank."""
    return load_model(tiny_model_dir)


def test_resample_path_spaces_points_by_arc_length():
    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0]])
    points = resample_path(path, 5)
    np.testing.assert_allclose(points, [[0, 0], [1, 0], [2, 0], [3, 0], [3, 1]], atol=1e-12)
    with pytest.raises(ConfigError, match="non-zero length"):
        resample_path(np.zeros((3, 2)), 5)
    with pytest.raises(ConfigError):
        resample_path(np.zeros((1, 2)), 5)


def _walk_action(loaded: LoadedModel) -> int:
    """The action whose bank end locations travel farthest (the walk)."""
    reach = [
        np.linalg.norm(loaded.bank.ends[loaded.bank.indices_of(a)][:, [0, 2]], axis=1).mean()
        for a in range(len(loaded.action_names))
    ]
    return int(np.argmax(reach))


def test_a_path_the_model_made_is_followed_closely(loaded):
    action = _walk_action(loaded)
    i = int(loaded.bank.indices_of(action)[3])
    _, trajectory = decode_array(
        loaded, loaded.bank.codes[i : i + 1], np.array([action]), loaded.bank.ends[i : i + 1]
    )
    start = np.array([1.0, -2.0])
    path = trajectory[0][:, [0, 2]] + start
    length = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
    result = follow_path(loaded, path, action, steps=60, seed=0)
    assert result.path_error_m < max(0.1 * length, 0.05)
    assert result.path_error_m <= result.initial_error_m + 1e-6
    root = result.motion.joints[0, loaded.skeleton.root]
    np.testing.assert_allclose(root[[0, 2]], start, atol=0.25)
    assert result.motion.meta["path_error_m"] == pytest.approx(result.path_error_m)


def test_a_held_out_path_improves_with_optimisation() -> None:
    # The bundled model: the tiny test model's trajectory hardly depends on its code (every start fits
    # this arc to within 1e-8 m), so there would be nothing to optimise.
    loaded = load_model(BUNDLED)
    action = loaded.action_names.index("walk-turn-right")
    reach = np.linalg.norm(loaded.bank.ends[loaded.bank.indices_of(action)][:, [0, 2]], axis=1).mean()
    s = np.linspace(0.0, 1.0, 40)
    # A gentle arc to the right (the turns' ends lie at -x) that no training clip drew, for a turning walk
    # (the bundled models' straight walks' paths hardly depend on their codes within the prior: 0.2118 ->
    # 0.2117 m at stop 42, 0.2130 -> 0.2121 m at stop 44).
    path = np.stack([-0.4 * reach * s**2, reach * s], axis=1)
    # Any mode: the best-fitting start is optimised (a mode's index means nothing across retrainings).
    result = follow_path(loaded, path, action, steps=80, seed=1)
    # measured 0.0497 -> 0.0450 m (stop-46 model), 0.0478 -> 0.0417 m (stop 50)
    assert result.path_error_m < result.initial_error_m - 1e-3
    np.testing.assert_allclose(result.end[[0, 2]], path[-1], atol=1e-6)
    modes = loaded.bank.modes[action]
    d = result.code - modes.conventional_mean_
    maha = d @ np.linalg.solve(modes.conventional_cov_, d)
    assert maha < 4 * loaded.config.latent_dim


def test_bad_mode_is_rejected(loaded):
    with pytest.raises(ConfigError, match="modes"):
        follow_path(loaded, np.array([[0.0, 0.0], [0.0, 1.0]]), 0, mode=99)
