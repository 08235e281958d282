"""The strip report's charts drawn without matplotlib (calidar.report.chart_picture): each
correlation cell in its value's colour with its value written, the histograms' bars as high as
their counts, and ``calidar boresight``'s report path importing no matplotlib."""

from __future__ import annotations

import io
import json
import subprocess
import sys

import numpy as np
import pytest

from calidar.report.chart_picture import (AFTER, ALPHA, BEFORE, BINS, CELL_PX, PLOT_H, PLOT_W,
                                          _bars, correlation_png, correlation_text,
                                          histogram_png)
from calidar.report.map_picture import BACKGROUND, colours


def _image(png: bytes) -> np.ndarray:
    from PIL import Image

    with Image.open(io.BytesIO(png)) as im:
        assert im.format == "PNG"
        return np.asarray(im.convert("RGB"))


def _count(img: np.ndarray, rgb) -> int:
    return int(np.all(img == np.asarray(rgb, np.uint8), axis=-1).sum())


def test_correlation_text_as_the_cells_show_it():
    assert [correlation_text(v) for v in (0.62, -0.104, -0.001, 0.0, 1.0, np.nan)] == \
        ["+0.62", "-0.10", "0.00", "0.00", "+1.00", "—"]


def test_each_correlation_cell_shows_its_colour():
    corr = np.array([[1.0, -0.83, 0.3], [-0.83, 1.0, 0.07], [0.3, 0.07, 1.0]])
    img = _image(correlation_png(corr, ["boresight_roll", "boresight_pitch", "lever_arm_z"]))
    for v, cells in ((1.0, 3), (-0.83, 2), (0.3, 2), (0.07, 2)):
        rgb = colours(np.array([v]), 1.0)[0]
        # each cell's colour fills most of its square (its text and the colour bar aside)
        n = _count(img, rgb)
        assert cells * 0.6 * CELL_PX**2 <= n <= cells * CELL_PX**2 + 20 * CELL_PX, (v, n)


def test_an_undefined_correlation_is_a_white_cell_with_a_dash():
    corr = np.array([[1.0, np.nan], [np.nan, 1.0]])
    img = _image(correlation_png(corr, ["a", "b"]))
    red = colours(np.array([1.0]), 1.0)[0]
    assert _count(img, red) >= 2 * 0.6 * CELL_PX**2
    assert correlation_text(np.nan) == "—"


def test_bars_are_as_high_as_their_counts_and_blend_where_both_are():
    before = np.zeros(BINS, int)
    after = np.zeros(BINS, int)
    before[10], after[10], after[60] = 100, 50, 25
    canvas = _bars([before, after], 200.0)  # 100 of 200: half the height
    assert canvas.shape == (PLOT_H, PLOT_W, 3)
    col10 = int((10.5 / BINS) * PLOT_W)
    col60 = int((60.5 / BINS) * PLOT_W)
    blue = np.round((1 - ALPHA) * np.array(BACKGROUND) + ALPHA * np.array(BEFORE))
    both = np.round((1 - ALPHA) * blue + ALPHA * np.array(AFTER))
    orange = np.round((1 - ALPHA) * np.array(BACKGROUND) + ALPHA * np.array(AFTER))
    column = canvas[:, col10].astype(float)
    h = PLOT_H
    assert np.array_equal(column[int(0.45 * h)], BACKGROUND)
    assert np.array_equal(column[int(0.55 * h)], blue)
    assert np.array_equal(column[int(0.70 * h)], blue)  # above the other's 50 (a quarter)
    assert np.array_equal(column[int(0.80 * h)], both)
    assert np.array_equal(canvas[h - 2, col60].astype(float), orange)  # 25: an eighth
    assert np.array_equal(canvas[int(0.85 * h), col60], BACKGROUND)
    assert np.array_equal(canvas[h - 1, 0], BACKGROUND)  # an empty bin


def test_histogram_picture_has_both_colours():
    rng = np.random.default_rng(3)
    img = _image(histogram_png(rng.normal(0, 40, 20_000), rng.normal(0, 8, 20_000), unit="mm"))
    blue = np.round((1 - ALPHA) * np.array(BACKGROUND) + ALPHA * np.array(BEFORE))
    assert _count(img, blue) > 1000 and _count(img, (np.round(
        (1 - ALPHA) * blue + ALPHA * np.array(AFTER)))) > 1000


@pytest.mark.parametrize("empty", [True, False])
def test_histogram_of_no_or_zero_residuals_is_drawn(empty):
    r = np.zeros(0 if empty else 5)
    assert _image(histogram_png(r, r)).shape[0] > PLOT_H


_PROBE = """
import json, sys
import calidar.cli.boresight, calidar.pipelines.boresight, calidar.pipelines.boresight_outputs
import calidar.strips.report
from calidar.report import Report
from calidar.report.chart_picture import correlation_png, histogram_png
from calidar.report.map_picture import map_png
import numpy as np
sec = Report("t").section("s")
sec.picture(correlation_png(np.eye(2), ["a", "b"]), "c")
sec.picture(histogram_png(np.ones(9), np.zeros(9)), "h")
sec.picture(map_png(np.ones((4, 5)), (0.0, 0.0), 1.0, "m", "dz"), "m")
print(json.dumps([len(sec.blocks), sorted(m for m in sys.modules if m.startswith("matplotlib"))]))
"""


def test_the_boresight_report_path_imports_no_matplotlib():
    out = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                         check=True).stdout
    blocks, modules = json.loads(out.strip().splitlines()[-1])
    assert blocks == 3 and modules == []
