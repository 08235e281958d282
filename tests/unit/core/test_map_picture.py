"""The dz map drawn without matplotlib (calidar.report.map_picture): its colours are matplotlib's
RdBu_r, each cell shows its value's colour, NaN white, and the axes carry round ticks."""

from __future__ import annotations

import io

import numpy as np
import pytest

from calidar.report.map_picture import LUT_SIZE, colours, diverging_lut, map_png, nice_ticks


def _image(png: bytes) -> np.ndarray:
    from PIL import Image

    with Image.open(io.BytesIO(png)) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB"))


def test_colour_table_is_matplotlibs_rdbu_r():
    from matplotlib import colormaps

    theirs = np.round(colormaps["RdBu_r"].resampled(LUT_SIZE)(np.arange(LUT_SIZE))[:, :3] * 255)
    assert np.abs(diverging_lut().astype(float) - theirs).max() <= 1


def test_values_take_their_step_as_imshow_does():
    lim = 2.0
    v = np.array([-5.0, -2.0, -1e-9, 0.0, 1.0, 2.0, 7.0, np.nan])
    rgb = colours(v, lim)
    lut = diverging_lut()
    expected = [0, 0, 127, 128, 192, 255, 255]
    assert np.array_equal(rgb[:-1], lut[expected])
    assert np.array_equal(rgb[-1], [255, 255, 255])


def test_picture_shows_each_cell_in_its_colour():
    lut = diverging_lut()
    grid = np.full((40, 60), np.nan)
    grid[:, :20] = 1.0  # +lim: the darkest red
    grid[:, 20:40] = -1.0  # −lim: the darkest blue
    img = _image(map_png(grid, (1000.0, 5000.0), 2.0, "strips 1 − 2", "dz [m]", lim=1.0))
    red = np.all(img == lut[-1], axis=2)
    blue = np.all(img == lut[0], axis=2)
    # the map is scaled to 600 × 400 px (10 px a cell): a third of it red, a third blue; the colour
    # bar's ends add at most a few rows of each
    assert red.sum() == pytest.approx(200 * 400, rel=0.05)
    assert blue.sum() == pytest.approx(200 * 400, rel=0.05)
    east_of_red = np.percentile(np.nonzero(red)[1], 95)
    assert east_of_red < np.percentile(np.nonzero(blue)[1], 5)  # red west of blue, as in the grid
    assert img.shape[0] > 400 and img.shape[1] > 600


def test_ticks_are_round_inside_and_apart():
    ticks, labels = nice_ticks(422528.0, 423076.0, 440, lambda s: 7.0 * len(s))
    steps = np.diff(ticks)
    assert ticks[0] >= 422528.0 and ticks[-1] <= 423076.0 and np.allclose(steps, steps[0])
    assert steps[0] in (100.0, 200.0, 250.0) and labels[0] == f"{ticks[0]:.0f}"
    assert 440 * steps[0] / (423076.0 - 422528.0) >= 7.0 * len(labels[0]) + 12
    ticks, labels = nice_ticks(-0.37, 0.37, 440, lambda s: 22.0)
    assert "0" in labels and all(s.startswith("−") for s in labels[: list(labels).index("0")])
    assert len(ticks) >= 3
