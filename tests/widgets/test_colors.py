"""Colour helpers: RGBA conversion and shared brushes."""

from __future__ import annotations

import numpy as np
import pytest

from widgets._colors import brushes_for, palette_rgb, qcolor, shades, to_rgba8


def test_to_rgba8_accepts_float_and_rgb() -> None:
    out = to_rgba8(np.array([[1.0, 0.5, 0.0], [0.0, 0.0, 1.0]]), 2)
    assert out.dtype == np.uint8
    assert out.tolist() == [[255, 128, 0, 255], [0, 0, 255, 255]]
    with pytest.raises(ValueError, match="colours"):
        to_rgba8(np.zeros((3, 4)), 2)


def test_brushes_shared_per_colour() -> None:
    rgba = np.array([[1, 2, 3, 255], [9, 8, 7, 100], [1, 2, 3, 255]], dtype=np.uint8)
    brushes = brushes_for(rgba)
    assert [b.color().getRgb() for b in brushes] == [(1, 2, 3, 255), (9, 8, 7, 100), (1, 2, 3, 255)]
    assert brushes[0] is brushes[2]


def test_palette_gives_every_category_its_own_colour_and_qcolor_forms() -> None:
    colors = palette_rgb(30)
    assert colors.shape == (30, 3)
    assert len({tuple(c) for c in colors.tolist()}) == 30
    assert palette_rgb(17)[:10].tolist() == palette_rgb(10).tolist()
    d = np.abs(colors[:, None].astype(int) - colors[None].astype(int)).sum(-1)
    np.fill_diagonal(d, 999)
    assert d[:17, :17].min() > 30, "the first 17 colours are told apart"
    ramp = shades(colors[0], 4)
    assert ramp.shape == (4, 3) and len({tuple(c) for c in ramp.tolist()}) == 4
    assert qcolor((1.0, 0.0, 0.0)).getRgb() == (255, 0, 0, 255)
    assert qcolor((0, 255, 0, 10)).getRgb() == (0, 255, 0, 10)
    assert qcolor("#0000ff").getRgb() == (0, 0, 255, 255)
